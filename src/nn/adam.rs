//! Adam (Kingma & Ba 2015) with PyTorch's update formula, except that a moment estimate below
//! f32's normal range is stored as zero (`zero_if_subnormal` says why).

use super::codec::{ByteReader, ByteWriter, CodecError};
use super::mlp::Mlp;

/// Adam hyper-parameters (PyTorch defaults except the learning rate).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdamConfig {
    pub lr: f32,
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
}

impl AdamConfig {
    pub fn with_lr(lr: f32) -> Self {
        Self {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }
}

/// Adam state for a list of parameter tensors.
#[derive(Clone, Debug)]
pub struct Adam {
    pub config: AdamConfig,
    /// Number of steps taken.
    pub t: u64,
    m: Vec<Vec<f32>>,
    v: Vec<Vec<f32>>,
}

impl Adam {
    /// Zero moments for tensors of the given lengths.
    pub fn new(config: AdamConfig, tensor_lens: &[usize]) -> Self {
        Self {
            config,
            t: 0,
            m: tensor_lens.iter().map(|&n| vec![0.0; n]).collect(),
            v: tensor_lens.iter().map(|&n| vec![0.0; n]).collect(),
        }
    }

    pub fn for_mlp(config: AdamConfig, mlp: &Mlp) -> Self {
        Self::new(config, &mlp.tensor_lens())
    }

    /// One step on every tensor of `mlp` using the gradients of its last backward pass.
    pub fn step_mlp(&mut self, mlp: &mut Mlp) {
        let (step_size, bc2_sqrt) = self.begin_step();
        for (i, (p, g)) in mlp.tensors_mut().enumerate() {
            self.update(i, p, g, step_size, bc2_sqrt);
        }
    }

    /// One step on a list of (parameter, gradient) tensors in the construction order.
    pub fn step_tensors(&mut self, tensors: &mut [(&mut [f32], &[f32])]) {
        let (step_size, bc2_sqrt) = self.begin_step();
        for (i, (p, g)) in tensors.iter_mut().enumerate() {
            self.update(i, p, g, step_size, bc2_sqrt);
        }
    }

    fn begin_step(&mut self) -> (f32, f32) {
        self.t += 1;
        let t = self.t.min(i32::MAX as u64) as i32;
        let c = &self.config;
        let bc1 = 1.0 - c.beta1.powi(t);
        let bc2 = 1.0 - c.beta2.powi(t);
        (c.lr / bc1, bc2.sqrt())
    }

    fn update(&mut self, i: usize, p: &mut [f32], g: &[f32], step_size: f32, bc2_sqrt: f32) {
        let AdamConfig {
            beta1, beta2, eps, ..
        } = self.config;
        let (m, v) = (&mut self.m[i], &mut self.v[i]);
        assert_eq!(m.len(), p.len(), "Adam: tensor {i} changed length");
        for (((p, &g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
            *m = zero_if_subnormal(beta1 * *m + (1.0 - beta1) * g);
            *v = zero_if_subnormal(beta2 * *v + (1.0 - beta2) * g * g);
            let denom = v.sqrt() / bc2_sqrt + eps;
            *p -= step_size * *m / denom;
        }
    }

    /// Appends the optimiser state (step count and moments).
    pub fn write(&self, w: &mut ByteWriter) {
        w.u64(self.t);
        w.usize(self.m.len());
        for (m, v) in self.m.iter().zip(&self.v) {
            w.f32s(m);
            w.f32s(v);
        }
    }

    /// Reads state written by [`Adam::write`] for tensors of the same lengths.
    pub fn read_into(&mut self, r: &mut ByteReader) -> Result<(), CodecError> {
        self.t = r.u64("Adam step count")?;
        let n = r.usize("Adam tensor count")?;
        if n != self.m.len() {
            return Err(CodecError::Invalid {
                what: "Adam tensor count",
                problem: format!("{n} stored, {} expected", self.m.len()),
            });
        }
        for (m, v) in self.m.iter_mut().zip(&mut self.v) {
            r.f32s_into(m, "Adam first moment")?;
            r.f32s_into(v, "Adam second moment")?;
        }
        Ok(())
    }
}

/// `x`, or zero when it lies below f32's normal range.
///
/// A parameter whose gradient stays zero (a ReLU unit dead on every sample) has moments that
/// decay geometrically into the subnormal range and stay there: β₁ = 0.9 times a few ulps
/// rounds back to the same ulps, and β₂ = 0.999 times up to 500 ulps does too. On x86 every
/// vector instruction with a subnormal operand takes a microcode assist of about a hundred
/// cycles, and a few such parameters make Adam a fifth of a SAC job's time. A moment this small
/// makes a step m / (√v + ε) below 10⁻³⁰ (ε = 10⁻⁸), which changes no parameter larger than
/// 10⁻²³ in size.
#[inline]
fn zero_if_subnormal(x: f32) -> f32 {
    if x.abs() < f32::MIN_POSITIVE {
        0.0
    } else {
        x
    }
}
