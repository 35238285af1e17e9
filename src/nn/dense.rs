//! A fully connected layer `y = W x + b` on batches (one column per sample).

use super::gemm::{gemm, gemm_bias};
use nalgebra::DMatrix;
use rand::Rng;

/// Dense layer with its gradient buffers.
#[derive(Clone, Debug)]
pub struct Dense {
    /// Weights, `out × in`.
    pub w: DMatrix<f32>,
    /// Bias, `out × 1`.
    pub b: DMatrix<f32>,
    /// ∂L/∂W from the last backward pass.
    pub grad_w: DMatrix<f32>,
    /// ∂L/∂b from the last backward pass.
    pub grad_b: DMatrix<f32>,
}

impl Dense {
    /// PyTorch's default `nn.Linear` initialisation: W and b uniform in ±1/√in.
    pub fn new(inputs: usize, outputs: usize, rng: &mut impl Rng) -> Self {
        let bound = 1.0 / (inputs.max(1) as f32).sqrt();
        let w = DMatrix::from_fn(outputs, inputs, |_, _| rng.gen_range(-bound..bound));
        let b = DMatrix::from_fn(outputs, 1, |_, _| rng.gen_range(-bound..bound));
        Self {
            grad_w: DMatrix::zeros(outputs, inputs),
            grad_b: DMatrix::zeros(outputs, 1),
            w,
            b,
        }
    }

    pub fn inputs(&self) -> usize {
        self.w.ncols()
    }

    pub fn outputs(&self) -> usize {
        self.w.nrows()
    }

    /// `y = W x + b` for a batch `x` (`in × B`) into `y` (`out × B`).
    pub fn forward(&self, x: &DMatrix<f32>, y: &mut DMatrix<f32>) {
        gemm_bias(&self.w, x, self.b.as_slice(), false, y);
    }

    /// `y = max(0, W x + b)` element by element (a hidden layer and its ReLU), with the bits
    /// of [`Dense::forward`] followed by `v.max(0.0)` on every element.
    pub fn forward_relu(&self, x: &DMatrix<f32>, y: &mut DMatrix<f32>) {
        gemm_bias(&self.w, x, self.b.as_slice(), true, y);
    }

    /// Given `dy = ∂L/∂y`, writes ∂L/∂W and ∂L/∂b (when `param_grads`) and ∂L/∂x into `dx`
    /// (when given).
    pub fn backward(
        &mut self,
        x: &DMatrix<f32>,
        dy: &DMatrix<f32>,
        dx: Option<&mut DMatrix<f32>>,
        param_grads: bool,
    ) {
        if param_grads {
            gemm(1.0, dy, false, x, true, 0.0, &mut self.grad_w);
            let gb = self.grad_b.as_mut_slice();
            gb.fill(0.0);
            for col in dy.as_slice().chunks_exact(gb.len()) {
                for (g, d) in gb.iter_mut().zip(col) {
                    *g += d;
                }
            }
        }
        if let Some(dx) = dx {
            gemm(1.0, &self.w, true, dy, false, 0.0, dx);
        }
    }
}
