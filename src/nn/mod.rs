//! Small hand-written neural networks: dense layers, MLPs, Gaussian heads, Adam.
