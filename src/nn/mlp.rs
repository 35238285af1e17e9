//! Multi-layer perceptrons: dense layers with ReLU between them and a linear output.

use super::codec::{read_file, save_file, ByteReader, ByteWriter, CodecError, FileError};
use super::dense::Dense;
use super::NnError;
use nalgebra::DMatrix;
use rand::Rng;
use std::fmt;
use std::path::Path;

const MLP_MAGIC: &[u8; 8] = b"SMIRLMLP";
const MLP_VERSION: u32 = 1;

/// Layer sizes of an MLP: input, hidden..., output. Hidden layers use ReLU, the output is
/// linear.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MlpArch {
    pub sizes: Vec<usize>,
}

impl fmt::Display for MlpArch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s: Vec<String> = self.sizes.iter().map(|s| s.to_string()).collect();
        write!(f, "{} (relu)", s.join("-"))
    }
}

impl MlpArch {
    pub fn new(input: usize, hidden: &[usize], output: usize) -> Self {
        let mut sizes = vec![input];
        sizes.extend_from_slice(hidden);
        sizes.push(output);
        Self { sizes }
    }

    pub(crate) fn write(&self, w: &mut ByteWriter) {
        w.str("relu");
        w.usize(self.sizes.len());
        for &s in &self.sizes {
            w.usize(s);
        }
    }

    pub(crate) fn read(r: &mut ByteReader) -> Result<Self, CodecError> {
        let act = r.string("activation")?;
        if act != "relu" {
            return Err(CodecError::Invalid {
                what: "activation",
                problem: format!("unknown activation {act:?}"),
            });
        }
        let n = r.usize("layer count")?;
        if !(2..=64).contains(&n) {
            return Err(CodecError::Invalid {
                what: "layer count",
                problem: format!("{n} sizes"),
            });
        }
        let sizes = (0..n)
            .map(|_| r.usize("layer size"))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { sizes })
    }
}

/// Which gradients a backward pass computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackwardMode {
    /// Parameter gradients (and the input gradient when asked for).
    Params,
    /// Only the gradient with respect to the input (e.g. ∂Q/∂a for the actor update); the
    /// network's parameter gradients are left untouched.
    InputOnly,
}

/// A ReLU MLP.
#[derive(Clone, Debug)]
pub struct Mlp {
    pub layers: Vec<Dense>,
}

/// Activations and back-propagated gradients of one batch size, reused across calls so the
/// hot path does not allocate.
#[derive(Clone, Debug)]
pub struct MlpWorkspace {
    batch: usize,
    /// Output of each layer (after ReLU for hidden layers).
    acts: Vec<DMatrix<f32>>,
    /// ∂L/∂(output of layer l) for hidden layers, after masking by the ReLU derivative.
    grads: Vec<DMatrix<f32>>,
}

impl MlpWorkspace {
    pub fn batch(&self) -> usize {
        self.batch
    }
    /// The network output of the last forward pass (`out × B`).
    pub fn output(&self) -> &DMatrix<f32> {
        self.acts.last().expect("an MLP has at least one layer")
    }
}

impl Mlp {
    pub fn new(arch: &MlpArch, rng: &mut impl Rng) -> Self {
        assert!(arch.sizes.len() >= 2, "an MLP needs input and output sizes");
        let layers = arch
            .sizes
            .windows(2)
            .map(|w| Dense::new(w[0], w[1], rng))
            .collect();
        Self { layers }
    }

    pub fn arch(&self) -> MlpArch {
        let mut sizes = vec![self.layers[0].inputs()];
        sizes.extend(self.layers.iter().map(|l| l.outputs()));
        MlpArch { sizes }
    }

    pub fn inputs(&self) -> usize {
        self.layers[0].inputs()
    }

    pub fn outputs(&self) -> usize {
        self.layers.last().unwrap().outputs()
    }

    pub fn num_params(&self) -> usize {
        self.layers.iter().map(|l| l.w.len() + l.b.len()).sum()
    }

    pub fn workspace(&self, batch: usize) -> MlpWorkspace {
        let acts = self
            .layers
            .iter()
            .map(|l| DMatrix::zeros(l.outputs(), batch))
            .collect();
        let grads = self.layers[..self.layers.len() - 1]
            .iter()
            .map(|l| DMatrix::zeros(l.outputs(), batch))
            .collect();
        MlpWorkspace { batch, acts, grads }
    }

    /// Forward pass of a batch `x` (`in × B`); the output is `ws.output()`.
    pub fn forward<'w>(&self, x: &DMatrix<f32>, ws: &'w mut MlpWorkspace) -> &'w DMatrix<f32> {
        assert_eq!(
            x.ncols(),
            ws.batch,
            "batch size differs from the workspace's"
        );
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate() {
            let (done, rest) = ws.acts.split_at_mut(l);
            let input = if l == 0 { x } else { &done[l - 1] };
            let y = &mut rest[0];
            if l < last {
                layer.forward_relu(input, y);
            } else {
                layer.forward(input, y);
            }
        }
        ws.output()
    }

    /// Backward pass after [`Mlp::forward`] on the same `x` and `ws`: given
    /// `d_out = ∂L/∂output`, computes parameter gradients (per `mode`) and, when `d_input` is
    /// given, ∂L/∂x.
    pub fn backward(
        &mut self,
        x: &DMatrix<f32>,
        ws: &mut MlpWorkspace,
        d_out: &DMatrix<f32>,
        d_input: Option<&mut DMatrix<f32>>,
        mode: BackwardMode,
    ) {
        assert_eq!(d_out.shape(), ws.output().shape(), "d_out shape");
        let params = mode == BackwardMode::Params;
        let n = self.layers.len();
        let mut d_input = d_input;
        for l in (0..n).rev() {
            let layer = &mut self.layers[l];
            if l == 0 {
                let dy = if n == 1 { d_out } else { &ws.grads[0] };
                layer.backward(x, dy, d_input.take(), params);
            } else {
                let input = &ws.acts[l - 1];
                let (lower, upper) = ws.grads.split_at_mut(l);
                let dy = if l == n - 1 { d_out } else { &upper[0] };
                let dx = &mut lower[l - 1];
                layer.backward(input, dy, Some(dx), params);
                // Branch-free ReLU derivative: keep the gradient where the unit was active.
                for (g, a) in dx.as_mut_slice().iter_mut().zip(input.as_slice()) {
                    *g *= f32::from(u8::from(*a > 0.0));
                }
            }
        }
    }

    /// Every (parameter, gradient) tensor pair in a fixed order: W then b of each layer.
    pub fn tensors_mut(&mut self) -> impl Iterator<Item = (&mut [f32], &[f32])> {
        self.layers.iter_mut().flat_map(|l| {
            let Dense {
                w,
                b,
                grad_w,
                grad_b,
            } = l;
            [
                (w.as_mut_slice(), grad_w.as_slice()),
                (b.as_mut_slice(), grad_b.as_slice()),
            ]
        })
    }

    /// Every parameter tensor in the order of [`Mlp::tensors_mut`].
    pub fn params(&self) -> impl Iterator<Item = &[f32]> {
        self.layers
            .iter()
            .flat_map(|l| [l.w.as_slice(), l.b.as_slice()])
    }

    /// Lengths of the parameter tensors, in order.
    pub fn tensor_lens(&self) -> Vec<usize> {
        self.params().map(|p| p.len()).collect()
    }

    /// Polyak averaging toward `source`: θ ← (1 − τ) θ + τ θ_source.
    pub fn polyak_from(&mut self, source: &Mlp, tau: f32) {
        for (t, s) in self.layers.iter_mut().zip(&source.layers) {
            for (a, b) in t.w.as_mut_slice().iter_mut().zip(s.w.as_slice()) {
                *a += tau * (b - *a);
            }
            for (a, b) in t.b.as_mut_slice().iter_mut().zip(s.b.as_slice()) {
                *a += tau * (b - *a);
            }
        }
    }

    /// Copies the parameters of a network of the same architecture.
    pub fn copy_from(&mut self, source: &Mlp) {
        for (t, s) in self.layers.iter_mut().zip(&source.layers) {
            t.w.copy_from(&s.w);
            t.b.copy_from(&s.b);
        }
    }

    /// True when every parameter is finite. Uses an integer max over the exponent bits so it
    /// vectorises (a NaN or ±inf has all exponent bits set).
    pub fn params_finite(&self) -> bool {
        self.params().all(all_finite)
    }

    /// Appends architecture and parameters to `w` (the body of a parameter file).
    pub fn write(&self, w: &mut ByteWriter) {
        self.arch().write(w);
        for p in self.params() {
            w.f32s(p);
        }
    }

    /// Reads parameters written by [`Mlp::write`] into this network, refusing another
    /// architecture. Returns the found architecture on mismatch.
    pub fn read_into(&mut self, r: &mut ByteReader) -> Result<Result<(), MlpArch>, CodecError> {
        let arch = MlpArch::read(r)?;
        if arch != self.arch() {
            return Ok(Err(arch));
        }
        for l in &mut self.layers {
            r.f32s_into(l.w.as_mut_slice(), "weights")?;
            r.f32s_into(l.b.as_mut_slice(), "bias")?;
        }
        Ok(Ok(()))
    }

    /// Saves the parameters to a versioned binary file (written atomically).
    pub fn save(&self, path: &Path) -> Result<(), NnError> {
        let mut w = ByteWriter::new();
        w.raw(MLP_MAGIC);
        w.u32(MLP_VERSION);
        self.write(&mut w);
        Ok(save_file(path, &w.bytes)?)
    }

    /// Loads parameters saved by [`Mlp::save`] into this network; a file of another
    /// architecture or format version is refused.
    pub fn load(&mut self, path: &Path) -> Result<(), NnError> {
        let p = path.display().to_string();
        let bytes = read_file(path)?;
        let codec = FileError::codec_at(&p);
        let mut r = ByteReader::new(&bytes);
        r.header(MLP_MAGIC, "smirl MLP parameter", MLP_VERSION)
            .map_err(codec)?;
        let mut staged = self.clone();
        match staged.read_into(&mut r).map_err(codec)? {
            Err(found) => Err(NnError::ArchitectureMismatch {
                path: p.clone(),
                found: found.to_string(),
                expected: self.arch().to_string(),
            }),
            Ok(()) => {
                r.finish().map_err(codec)?;
                *self = staged;
                Ok(())
            }
        }
    }
}

/// True when no element is NaN or ±inf (vectorisable integer reduction).
pub fn all_finite(xs: &[f32]) -> bool {
    let max = xs
        .iter()
        .map(|x| x.to_bits() & 0x7fff_ffff)
        .fold(0u32, u32::max);
    max < 0x7f80_0000
}
