//! `sac_bench`: SAC environment steps + gradient updates per second on one thread, against
//! the time of just the matrix products one step + update performs, measured in the same run.
//!
//! Each measured iteration is one environment step (policy action) followed by one gradient
//! update (the paper's (64, 64) / batch-256 configuration by default). The reference replays,
//! in a loop, the matrix products recorded while running one iteration (shapes and transposes
//! from `smirl::nn::gemm::trace`) through `smirl::nn::gemm::gemm`, the kernel training uses,
//! as bare products (a dense layer's bias and ReLU left out). Reported: median over
//! repetitions.

#![deny(unsafe_code)]

use anyhow::{bail, Context, Result};
use clap::Parser;
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smirl::env::reacher::{ReacherConfig, ReacherDelivery};
use smirl::env::{check_action, ContinuousEnv, EnvError, EnvStep};
use smirl::nn::gemm::{self, Epilogue, GemmShape};
use smirl::rl::sac::{EnvReward, SacConfig, SacTrainer};
use smirl::rm::LabelSet;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

mod common;
use common::median;

#[derive(Parser, Debug)]
#[command(about = "SAC steps+updates per second vs the matrix-multiply bound")]
struct Args {
    /// Environments, comma-separated: `synthetic` (cheap stand-in with the product env's sizes, obs
    /// `--obs-dim`), `reacher` (ReacherDelivery, obs 17) or `reacher-onehot` (ReacherDelivery
    /// with a 7-wide one-hot block appended, obs 24: the product environment's size).
    #[arg(long, default_value = "synthetic")]
    env: String,
    /// SAC config TOML (defaults: the paper's IRL config, (64, 64), batch 256).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Measured step+update iterations per repetition.
    #[arg(long, default_value_t = 2000)]
    iters: u64,
    /// Repetitions (the median is reported).
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// Observation size of the synthetic env (17 Reacher features + RM one-hot).
    #[arg(long, default_value_t = 24)]
    obs_dim: usize,
    #[arg(long, default_value_t = 2)]
    act_dim: usize,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also write the report here (atomically; an existing file only with --force).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
    /// Also time the traced products through matrixmultiply's `sgemm` against the unpacked
    /// kernel and against `gemm`'s choice between them, interleaved, whole update and shape by
    /// shape; and the dense layers' forwards with the bias (and ReLU) in the kernel against a
    /// bias copy, the product with β = 1 and a ReLU pass.
    #[arg(long)]
    compare_kernels: bool,
}

/// Cheap stand-in environment with the product environment's sizes: a damped linear system
/// driven by the action, plus a one-hot block that advances on a fixed schedule; 50-step
/// episodes like Reacher.
struct SyntheticEnv {
    obs_dim: usize,
    act_dim: usize,
    onehot: usize,
    state: Vec<f32>,
    t: usize,
}

impl SyntheticEnv {
    fn new(obs_dim: usize, act_dim: usize) -> Self {
        let onehot = (obs_dim / 3).min(7);
        Self {
            obs_dim,
            act_dim,
            onehot,
            state: vec![0.0; obs_dim - onehot],
            t: 0,
        }
    }
    fn write_obs(&self, obs: &mut [f32]) {
        let n = self.state.len();
        obs[..n].copy_from_slice(&self.state);
        obs[n..].fill(0.0);
        obs[n + (self.t / 10) % self.onehot] = 1.0;
    }
}

impl ContinuousEnv for SyntheticEnv {
    fn obs_dim(&self) -> usize {
        self.obs_dim
    }
    fn act_dim(&self) -> usize {
        self.act_dim
    }
    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for s in &mut self.state {
            *s = rng.gen_range(-0.1..0.1);
        }
        self.t = 0;
        self.write_obs(obs);
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        check_action(action, self.act_dim)?;
        let n = self.state.len();
        for i in 0..n {
            let a = action[i % self.act_dim].clamp(-1.0, 1.0);
            self.state[i] = 0.95 * self.state[i] + 0.05 * a + 0.01 * self.state[(i + 1) % n];
        }
        self.t += 1;
        self.write_obs(obs);
        let reward = -self.state[..2].iter().map(|x| x.abs()).sum::<f32>();
        Ok(EnvStep {
            reward: f64::from(reward),
            labels: LabelSet::EMPTY,
            terminated: false,
            truncated: self.t >= 50,
        })
    }
}

/// Appends a one-hot block to an environment's observation (slot chosen by the labels seen
/// so far, advancing on each new label): the size and cost profile of the product with a
/// reward machine (its one-hot state) without the machine, for benchmarking the network sizes.
struct OneHotAppended<E> {
    inner: E,
    width: usize,
    slot: usize,
}

impl<E: ContinuousEnv> OneHotAppended<E> {
    fn write_onehot(&self, obs: &mut [f32]) {
        let n = self.inner.obs_dim();
        obs[n..].fill(0.0);
        obs[n + self.slot] = 1.0;
    }
}

impl<E: ContinuousEnv> ContinuousEnv for OneHotAppended<E> {
    fn obs_dim(&self) -> usize {
        self.inner.obs_dim() + self.width
    }
    fn act_dim(&self) -> usize {
        self.inner.act_dim()
    }
    fn reset(&mut self, seed: u64, obs: &mut [f32]) {
        let n = self.inner.obs_dim();
        self.inner.reset(seed, &mut obs[..n]);
        self.slot = 0;
        self.write_onehot(obs);
    }
    fn step(&mut self, action: &[f32], obs: &mut [f32]) -> Result<EnvStep, EnvError> {
        let n = self.inner.obs_dim();
        let s = self.inner.step(action, &mut obs[..n])?;
        if !s.labels.is_empty() {
            self.slot = (self.slot + 1) % self.width;
        }
        self.write_onehot(obs);
        Ok(s)
    }
}

struct Measurement {
    iters_per_s: Vec<f64>,
    gemm_bound_per_s: Vec<f64>,
    env_only_per_s: Vec<f64>,
    shapes: Vec<GemmShape>,
}

fn measure<E: ContinuousEnv>(env: &mut E, config: &SacConfig, args: &Args) -> Result<Measurement> {
    let mut trainer = SacTrainer::new(config, env.obs_dim(), env.act_dim(), args.seed)?;
    // Fill the replay buffer and get past the random warm-up before measuring.
    let warm = config.warmup_steps.max(config.update_after) + 500;
    trainer.train(env, &mut EnvReward, warm, |_| {})?;
    let (outcome, shapes) = gemm::trace(|| trainer.step(env, &mut EnvReward));
    if outcome?.update.is_none() {
        bail!("the traced step did no update");
    }
    let mut operands: Vec<_> = shapes.iter().map(gemm::operands_for).collect();
    let mut env_obs = vec![0.0f32; env.obs_dim()];
    let mut env_act = vec![0.0f32; env.act_dim()];
    let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
    let mut m = Measurement {
        iters_per_s: vec![],
        gemm_bound_per_s: vec![],
        env_only_per_s: vec![],
        shapes: shapes.clone(),
    };
    // Training and the matmul reference alternate in short chunks so both see the same
    // machine load (the cores are shared); the ratio is taken per repetition.
    const CHUNKS: u64 = 10;
    let chunk = args.iters.div_ceil(CHUNKS);
    for _ in 0..args.reps {
        let (mut train_s, mut gemm_s) = (0.0, 0.0);
        for _ in 0..CHUNKS {
            let t = Instant::now();
            trainer.train(env, &mut EnvReward, chunk, |_| {})?;
            train_s += t.elapsed().as_secs_f64();
            let t = Instant::now();
            for _ in 0..chunk {
                for (s, (a, b, c)) in shapes.iter().zip(operands.iter_mut()) {
                    gemm::gemm(1.0, a, s.trans_a, b, s.trans_b, 0.0, c);
                }
            }
            gemm_s += t.elapsed().as_secs_f64();
        }
        let n = (chunk * CHUNKS) as f64;
        m.iters_per_s.push(n / train_s);
        m.gemm_bound_per_s.push(n / gemm_s);

        let t = Instant::now();
        env.reset(args.seed, &mut env_obs);
        for _ in 0..args.iters {
            for a in &mut env_act {
                *a = rng.gen_range(-1.0..1.0);
            }
            let s = env.step(&env_act, &mut env_obs)?;
            if s.terminated || s.truncated {
                env.reset(args.seed, &mut env_obs);
            }
        }
        m.env_only_per_s
            .push(args.iters as f64 / t.elapsed().as_secs_f64());
    }
    std::hint::black_box(&operands);
    Ok(m)
}

/// How a product of the trace is computed in [`compare_kernels`].
#[derive(Clone, Copy)]
enum Kernel {
    Sgemm,
    Unpacked,
    Chosen,
}

/// Runs every product of `shapes` once through `kernel`, with β = 1 for the dense forwards
/// (`W x` onto a copy of the bias on `sgemm`'s path) and 0 for the backward products.
fn replay(
    kernel: Kernel,
    shapes: &[GemmShape],
    operands: &mut [(DMatrix<f32>, DMatrix<f32>, DMatrix<f32>)],
) {
    for (s, (a, b, c)) in shapes.iter().zip(operands.iter_mut()) {
        let beta = if s.epilogue == Epilogue::Beta {
            0.0
        } else {
            1.0
        };
        match kernel {
            Kernel::Sgemm => gemm::gemm_matrixmultiply(1.0, a, s.trans_a, b, s.trans_b, beta, c),
            Kernel::Unpacked => {
                if !gemm::gemm_unpacked(a, s.trans_a, b, s.trans_b, beta, c) {
                    gemm::gemm_matrixmultiply(1.0, a, s.trans_a, b, s.trans_b, beta, c)
                }
            }
            Kernel::Chosen => gemm::gemm(1.0, a, s.trans_a, b, s.trans_b, beta, c),
        }
    }
}

/// Seconds per replay of `shapes` through each kernel: repetitions of `iters` replays, the
/// kernels taking turns in short chunks so that all see the same machine load.
fn time_kernels(
    shapes: &[GemmShape],
    kernels: &[Kernel],
    iters: u64,
    reps: usize,
) -> Vec<Vec<f64>> {
    let mut operands: Vec<_> = shapes.iter().map(gemm::operands_for).collect();
    let mut secs = vec![vec![]; kernels.len()];
    const CHUNKS: u64 = 10;
    let chunk = iters.div_ceil(CHUNKS);
    for _ in 0..reps {
        let mut total = vec![0.0; kernels.len()];
        for _ in 0..CHUNKS {
            for (t, &kernel) in total.iter_mut().zip(kernels) {
                let start = Instant::now();
                for _ in 0..chunk {
                    replay(kernel, shapes, &mut operands);
                }
                *t += start.elapsed().as_secs_f64();
            }
        }
        for (s, t) in secs.iter_mut().zip(total) {
            s.push(t / (chunk * CHUNKS) as f64);
        }
    }
    std::hint::black_box(&operands);
    secs
}

/// Seconds per pass over the dense forwards of `shapes` (the products with a bias), first as
/// a bias copy into every column, `gemm` with β = 1 and a ReLU pass for hidden layers, then
/// through `gemm_bias` (bias and ReLU in the kernel's epilogue where it runs): repetitions of
/// `iters` passes, the two taking turns in short chunks.
fn time_dense_forwards(shapes: &[GemmShape], iters: u64, reps: usize) -> [Vec<f64>; 2] {
    let dense: Vec<GemmShape> = shapes
        .iter()
        .filter(|s| s.epilogue != Epilogue::Beta)
        .copied()
        .collect();
    let mut operands: Vec<_> = dense.iter().map(gemm::operands_for).collect();
    let biases: Vec<Vec<f32>> = dense.iter().map(|s| vec![-0.125; s.m]).collect();
    let mut secs = [vec![], vec![]];
    const CHUNKS: u64 = 10;
    let chunk = iters.div_ceil(CHUNKS);
    for _ in 0..reps {
        let mut total = [0.0; 2];
        for _ in 0..CHUNKS {
            for (fused, t) in total.iter_mut().enumerate() {
                let start = Instant::now();
                for _ in 0..chunk {
                    for ((s, (a, b, c)), bias) in dense.iter().zip(&mut operands).zip(&biases) {
                        let relu = s.epilogue == Epilogue::BiasRelu;
                        if fused == 1 {
                            gemm::gemm_bias(a, b, bias, relu, c);
                        } else {
                            for col in c.as_mut_slice().chunks_exact_mut(s.m) {
                                col.copy_from_slice(bias);
                            }
                            gemm::gemm(1.0, a, false, b, false, 1.0, c);
                            if relu {
                                gemm::relu(c.as_mut_slice());
                            }
                        }
                    }
                }
                *t += start.elapsed().as_secs_f64();
            }
        }
        for (s, t) in secs.iter_mut().zip(total) {
            s.push(t / (chunk * CHUNKS) as f64);
        }
    }
    std::hint::black_box(&operands);
    secs
}

/// The traced products timed through `sgemm`, the unpacked kernel and `gemm`'s choice, for
/// the whole update and for each distinct shape.
fn compare_kernels(shapes: &[GemmShape], args: &Args) -> String {
    let mut s = String::new();
    let kernels = [Kernel::Sgemm, Kernel::Unpacked, Kernel::Chosen];
    let _ = writeln!(
        s,
        "kernels (unpacked kernel available, so used by gemm: {}):",
        smirl::nn::gemm_unpacked::supported()
    );
    let secs = time_kernels(shapes, &kernels, args.iters, args.reps);
    let us = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{:.1}", x * 1e6))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let _ = writeln!(
        s,
        "  one update's products, µs per rep: sgemm {} | unpacked {} | gemm {}",
        us(&secs[0]),
        us(&secs[1]),
        us(&secs[2])
    );
    let ratio = |i: usize| {
        let r: Vec<f64> = secs[i].iter().zip(&secs[0]).map(|(x, m)| x / m).collect();
        (median(&r), r)
    };
    let (unpacked, per_rep) = ratio(1);
    let _ = writeln!(
        s,
        "  time ratio unpacked/sgemm per rep: {} (median {unpacked:.3})",
        fmt2(&per_rep)
    );
    let (chosen, per_rep) = ratio(2);
    let _ = writeln!(
        s,
        "  time ratio gemm/sgemm per rep:     {} (median {chosen:.3})",
        fmt2(&per_rep)
    );
    let dense = shapes
        .iter()
        .filter(|s| s.epilogue != Epilogue::Beta)
        .count();
    let relu = shapes
        .iter()
        .filter(|s| s.epilogue == Epilogue::BiasRelu)
        .count();
    let [copy, fused] = time_dense_forwards(shapes, args.iters, args.reps);
    let _ = writeln!(
        s,
        "  dense forwards ({dense} products, {relu} with ReLU), µs per rep: bias copy + gemm β = 1 \
         + ReLU pass {} | gemm_bias {}",
        us(&copy),
        us(&fused)
    );
    let per_rep: Vec<f64> = fused.iter().zip(&copy).map(|(f, c)| f / c).collect();
    let _ = writeln!(
        s,
        "  time ratio gemm_bias/copy per rep: {} (median {:.3})",
        fmt2(&per_rep),
        median(&per_rep)
    );
    let mut distinct: Vec<GemmShape> = vec![];
    for sh in shapes {
        if !distinct.contains(sh) {
            distinct.push(*sh);
        }
    }
    let _ = writeln!(
        s,
        "  per shape (calls per update; median µs per call sgemm -> unpacked):"
    );
    for sh in distinct {
        let calls = shapes.iter().filter(|x| **x == sh).count();
        let one = [sh];
        let secs = time_kernels(&one, &kernels[..2], 10 * args.iters, args.reps);
        let (g, u) = (median(&secs[0]), median(&secs[1]));
        let _ = writeln!(
            s,
            "    m {:>3} k {:>3} n {:>3} trans ({}, {}){} x{calls}: {:.2} -> {:.2} ({:.2}x)",
            sh.m,
            sh.k,
            sh.n,
            u8::from(sh.trans_a),
            u8::from(sh.trans_b),
            match sh.epilogue {
                Epilogue::Beta => "",
                Epilogue::Bias => " bias",
                Epilogue::BiasRelu => " bias+relu",
            },
            g * 1e6,
            u * 1e6,
            u / g
        );
    }
    s
}

fn report(
    name: &str,
    config: &SacConfig,
    obs_dim: usize,
    act_dim: usize,
    m: &Measurement,
) -> String {
    let mut s = String::new();
    let flops: usize = m.shapes.iter().map(|s| 2 * s.m * s.k * s.n).sum();
    let it = median(&m.iters_per_s);
    let gb = median(&m.gemm_bound_per_s);
    let _ = writeln!(s, "env: {name} (obs {obs_dim}, act {act_dim})");
    let _ = writeln!(
        s,
        "config: hidden {:?}, batch {}, updates/step {}",
        config.hidden, config.batch_size, config.updates_per_step
    );
    let _ = writeln!(
        s,
        "matrix products per step+update: {} ({:.1} MFLOP)",
        m.shapes.len(),
        flops as f64 / 1e6
    );
    let fmt = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.0}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let _ = writeln!(s, "steps+updates/s per rep: {}", fmt(&m.iters_per_s));
    let _ = writeln!(s, "matmul-only/s per rep:   {}", fmt(&m.gemm_bound_per_s));
    let _ = writeln!(s, "env-only steps/s per rep: {}", fmt(&m.env_only_per_s));
    let _ = writeln!(
        s,
        "median steps+updates/s: {it:.0} ({:.0} µs each; target >= 1000)",
        1e6 / it
    );
    let _ = writeln!(
        s,
        "median matmul bound:    {gb:.0}/s ({:.0} µs, {:.1} GFLOP/s)",
        1e6 / gb,
        flops as f64 * gb / 1e9
    );
    let ratios: Vec<f64> = m
        .gemm_bound_per_s
        .iter()
        .zip(&m.iters_per_s)
        .map(|(g, i)| g / i)
        .collect();
    let _ = writeln!(
        s,
        "ratio per rep (time per step+update / matmul time): {}",
        fmt2(&ratios)
    );
    let _ = writeln!(s, "median ratio: {:.2} (target <= 2.5)", median(&ratios));
    s
}

fn fmt2(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x:.2}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The environment of the paper's tasks (Composite's layout).
fn composite_config() -> Result<ReacherConfig> {
    let task = smirl::env::reacher_task::ReacherTask::shipped("composite")?;
    Ok(task.env_config(&ReacherConfig::default())?)
}

fn main() -> Result<()> {
    let args = Args::parse();
    if let Some(path) = &args.out {
        smirl::output::check_file(path, args.force)?;
        if let Some(config) = &args.config {
            smirl::output::check_not_input(path, &[config])?;
        }
    }
    let config = match &args.config {
        Some(p) => SacConfig::load(p)?,
        None => SacConfig::default(),
    };
    if args.reps == 0 || args.iters == 0 {
        bail!("--reps and --iters must be positive");
    }
    let command: Vec<String> = std::env::args().collect();
    let mut out = format!(
        "$ cargo run --release --bin sac_bench -- {}\n",
        command[1..].join(" ")
    );
    let _ = writeln!(out, "commit: {}", smirl::GIT_COMMIT);
    // Other processes share the cores: record how busy the machine was.
    if let Ok(load) = std::fs::read_to_string("/proc/loadavg") {
        let _ = writeln!(
            out,
            "load average at start (1/5/15 min): {}",
            load.split_whitespace()
                .take(3)
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    for env_name in args.env.split(',') {
        let (name, obs_dim, act_dim, m) = match env_name {
            "synthetic" => {
                let mut env = SyntheticEnv::new(args.obs_dim, args.act_dim);
                let m = measure(&mut env, &config, &args)?;
                ("synthetic", args.obs_dim, args.act_dim, m)
            }
            "reacher" => {
                let mut env = ReacherDelivery::new(composite_config()?)?;
                let (o, a) = (env.obs_dim(), env.act_dim());
                ("ReacherDelivery", o, a, measure(&mut env, &config, &args)?)
            }
            "reacher-onehot" => {
                let mut env = OneHotAppended {
                    inner: ReacherDelivery::new(composite_config()?)?,
                    width: 7,
                    slot: 0,
                };
                let (o, a) = (env.obs_dim(), env.act_dim());
                let m = measure(&mut env, &config, &args)?;
                ("ReacherDelivery + 7-wide one-hot", o, a, m)
            }
            other => bail!(
            "unknown --env {other:?} (expected \"synthetic\", \"reacher\" or \"reacher-onehot\")"
        ),
        };
        out.push_str(&report(name, &config, obs_dim, act_dim, &m));
        if args.compare_kernels {
            out.push_str(&compare_kernels(&m.shapes, &args));
        }
    }
    print!("{out}");
    if let Some(path) = &args.out {
        smirl::output::create_parent(path)?;
        smirl::atomic_file::write_atomic(path, out.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
