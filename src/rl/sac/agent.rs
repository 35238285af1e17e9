//! The SAC learner: networks, optimisers, temperature, and one gradient update.

use super::episode::{EpisodeSummary, RolloutStep};
use super::{SacConfig, SacError};
use crate::env::{episode, ContinuousEnv};
use crate::nn::codec::{ByteReader, ByteWriter, CodecError};
use crate::nn::{gaussian, Adam, AdamConfig, BackwardMode, Mlp, MlpArch, MlpWorkspace};
use crate::rl::replay::ReplayBatch;
use nalgebra::DMatrix;
use rand::Rng;
use rand_distr::StandardNormal;

/// How [`SacAgent::act`] picks an action.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ActMode {
    /// Sample from the squashed Gaussian (training, stochastic evaluation).
    Sample,
    /// tanh of the mean (deterministic evaluation).
    Mean,
}

/// Losses and temperature of one update.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UpdateStats {
    pub q1_loss: f32,
    pub q2_loss: f32,
    pub actor_loss: f32,
    pub alpha: f32,
    /// Mean log π of the batch's fresh actions (−entropy estimate).
    pub mean_log_prob: f32,
}

/// Buffers of one update, sized for the batch once so updates do not allocate.
#[derive(Clone, Debug)]
struct UpdateWorkspace {
    actor: MlpWorkspace,
    q1: MlpWorkspace,
    q2: MlpWorkspace,
    /// Critic input: observation rows then action rows.
    q_in: DMatrix<f32>,
    draw: PolicyDraw,
    targets: Vec<f32>,
    dq: DMatrix<f32>,
    dq_in: DMatrix<f32>,
    d_actions: DMatrix<f32>,
    d_log_prob: Vec<f32>,
    d_head: DMatrix<f32>,
}

/// Actions drawn from the actor's squashed Gaussian for a batch: the noise ε, pre-squash
/// values, actions and log π, sized once so drawing does not allocate.
#[derive(Clone, Debug)]
struct PolicyDraw {
    eps: DMatrix<f32>,
    pre: DMatrix<f32>,
    actions: DMatrix<f32>,
    log_prob: Vec<f32>,
}

impl PolicyDraw {
    fn new(act_dim: usize, batch: usize) -> Self {
        Self {
            eps: DMatrix::zeros(act_dim, batch),
            pre: DMatrix::zeros(act_dim, batch),
            actions: DMatrix::zeros(act_dim, batch),
            log_prob: vec![0.0; batch],
        }
    }

    /// Draws ε ~ N(0, I) from `rng` (column by column) and samples reparameterised actions
    /// from the actor output `head`.
    fn sample(&mut self, head: &DMatrix<f32>, rng: &mut impl Rng) {
        draw_noise(rng, self.eps.as_mut_slice());
        self.apply(head);
    }

    /// Samples reparameterised actions from `head` with the noise already in `eps`.
    fn apply(&mut self, head: &DMatrix<f32>) {
        gaussian::sample(
            head,
            &self.eps,
            &mut self.pre,
            &mut self.actions,
            &mut self.log_prob,
        );
    }
}

/// Fills `eps` with standard-normal noise from `rng`, in order: the draws sampling makes for
/// `eps.len() / act_dim` actions one after the other, so noise drawn ahead for a whole episode
/// (lockstep rollouts) is the noise one-at-a-time acting would have drawn.
pub fn draw_noise(rng: &mut impl Rng, eps: &mut [f32]) {
    for e in eps {
        *e = rng.sample(StandardNormal);
    }
}

/// Buffers for choosing one action at a time with an actor: what [`SacAgent::act`] uses, and
/// what lets a saved actor act exactly as the agent that trained it (same noise draws).
#[derive(Clone, Debug)]
pub struct ActWorkspace {
    actor: MlpWorkspace,
    obs: DMatrix<f32>,
    draw: PolicyDraw,
}

impl ActWorkspace {
    /// Buffers for `actor`, whose output is a mean and a log-std per action.
    pub fn new(actor: &Mlp) -> Self {
        Self::with_batch(actor, 1)
    }

    /// Buffers for choosing actions for `batch` observations at once (environments stepped
    /// in lockstep): one matrix product per layer instead of `batch`.
    pub fn with_batch(actor: &Mlp, batch: usize) -> Self {
        Self {
            actor: actor.workspace(batch),
            obs: DMatrix::zeros(actor.inputs(), batch),
            draw: PolicyDraw::new(actor.outputs() / 2, batch),
        }
    }

    /// Observations per call of [`ActWorkspace::act`].
    pub fn batch(&self) -> usize {
        self.obs.ncols()
    }

    /// Chooses `actor`'s actions for [`ActWorkspace::batch`] observations: `obs` holds them
    /// one after the other (`batch × obs_dim`), `action` receives theirs the same way
    /// (`batch × act_dim`). Sampling draws the noise observation by observation, so a batch of
    /// one draws what one call per observation draws.
    pub fn act(
        &mut self,
        actor: &Mlp,
        obs: &[f32],
        mode: ActMode,
        rng: &mut impl Rng,
        action: &mut [f32],
    ) {
        self.obs.as_mut_slice().copy_from_slice(obs);
        let head = actor.forward(&self.obs, &mut self.actor);
        match mode {
            ActMode::Mean => gaussian::mean_action(head, &mut self.draw.actions),
            ActMode::Sample => self.draw.sample(head, rng),
        }
        action.copy_from_slice(self.draw.actions.as_slice());
    }

    /// [`ActWorkspace::act`] with the sampling noise given instead of drawn: `noise` holds
    /// ε for every observation (`batch × act_dim`, what [`draw_noise`] writes); `None` takes
    /// the mean action. The actions are those `act` chooses when its generator would draw
    /// `noise`.
    pub fn act_with_noise(
        &mut self,
        actor: &Mlp,
        obs: &[f32],
        noise: Option<&[f32]>,
        action: &mut [f32],
    ) {
        self.obs.as_mut_slice().copy_from_slice(obs);
        let head = actor.forward(&self.obs, &mut self.actor);
        match noise {
            None => gaussian::mean_action(head, &mut self.draw.actions),
            Some(eps) => {
                self.draw.eps.as_mut_slice().copy_from_slice(eps);
                self.draw.apply(head);
            }
        }
        action.copy_from_slice(self.draw.actions.as_slice());
    }
}

/// Soft Actor-Critic with a tanh-squashed Gaussian actor and twin critics with Polyak targets.
#[derive(Clone, Debug)]
pub struct SacAgent {
    config: SacConfig,
    obs_dim: usize,
    act_dim: usize,
    pub actor: Mlp,
    pub q1: Mlp,
    pub q2: Mlp,
    pub q1_target: Mlp,
    pub q2_target: Mlp,
    actor_opt: Adam,
    q1_opt: Adam,
    q2_opt: Adam,
    alpha_opt: Adam,
    log_alpha: f32,
    target_entropy: f32,
    updates: u64,
    ws: UpdateWorkspace,
    act_ws: ActWorkspace,
}

fn check_finite(
    ok: bool,
    network: &'static str,
    what: &'static str,
    update: u64,
) -> Result<(), SacError> {
    if ok {
        Ok(())
    } else {
        Err(SacError::NonFinite {
            network,
            what,
            update,
        })
    }
}

impl SacAgent {
    /// Fresh networks initialised from `rng`. The config must be valid.
    pub fn new(config: &SacConfig, obs_dim: usize, act_dim: usize, rng: &mut impl Rng) -> Self {
        let actor_arch = MlpArch::new(obs_dim, &config.hidden, 2 * act_dim);
        let q_arch = MlpArch::new(obs_dim + act_dim, &config.hidden, 1);
        let actor = Mlp::new(&actor_arch, rng);
        let q1 = Mlp::new(&q_arch, rng);
        let q2 = Mlp::new(&q_arch, rng);
        let adam = AdamConfig::with_lr(config.lr);
        let b = config.batch_size;
        let ws = UpdateWorkspace {
            actor: actor.workspace(b),
            q1: q1.workspace(b),
            q2: q2.workspace(b),
            q_in: DMatrix::zeros(obs_dim + act_dim, b),
            draw: PolicyDraw::new(act_dim, b),
            targets: vec![0.0; b],
            dq: DMatrix::zeros(1, b),
            dq_in: DMatrix::zeros(obs_dim + act_dim, b),
            d_actions: DMatrix::zeros(act_dim, b),
            d_log_prob: vec![0.0; b],
            d_head: DMatrix::zeros(2 * act_dim, b),
        };
        let act_ws = ActWorkspace::new(&actor);
        Self {
            config: config.clone(),
            obs_dim,
            act_dim,
            actor_opt: Adam::for_mlp(adam, &actor),
            q1_opt: Adam::for_mlp(adam, &q1),
            q2_opt: Adam::for_mlp(adam, &q2),
            alpha_opt: Adam::new(adam, &[1]),
            q1_target: q1.clone(),
            q2_target: q2.clone(),
            actor,
            q1,
            q2,
            log_alpha: config.alpha.ln(),
            target_entropy: config.target_entropy_for(act_dim),
            updates: 0,
            ws,
            act_ws,
        }
    }

    pub fn config(&self) -> &SacConfig {
        &self.config
    }
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }
    pub fn act_dim(&self) -> usize {
        self.act_dim
    }
    /// Current entropy temperature α.
    pub fn alpha(&self) -> f32 {
        self.log_alpha.exp()
    }
    /// Gradient updates done so far.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// Chooses an action for one observation.
    pub fn act(&mut self, obs: &[f32], mode: ActMode, rng: &mut impl Rng, action: &mut [f32]) {
        self.act_ws.act(&self.actor, obs, mode, rng, action);
    }

    /// Plays one episode from `env.reset(reset_seed)` for at most `max_steps` steps, calling
    /// `on_step` after every step (for recording trajectories, state densities, labels).
    /// The returned summary has index 0.
    pub fn rollout<E: ContinuousEnv + ?Sized>(
        &mut self,
        env: &mut E,
        mode: ActMode,
        reset_seed: u64,
        max_steps: u64,
        rng: &mut impl Rng,
        mut on_step: impl FnMut(&RolloutStep),
    ) -> Result<EpisodeSummary, SacError> {
        for (what, expected, got) in [
            ("observation size", self.obs_dim, env.obs_dim()),
            ("action size", self.act_dim, env.act_dim()),
        ] {
            if expected != got {
                return Err(SacError::Dimension {
                    what,
                    expected,
                    got,
                });
            }
        }
        let summary = EpisodeSummary {
            index: 0,
            env_return: 0.0,
            final_reward: 0.0,
            length: 0,
            terminated: false,
        };
        episode::play(
            env,
            reset_seed,
            max_steps,
            |_, _| Ok(summary),
            |_, obs, action| self.act(obs, mode, rng, action),
            |summary, env, s| {
                let step = env
                    .step(s.action, s.next_obs)
                    .map_err(|source| SacError::Env { step: s.t, source })?;
                on_step(&RolloutStep {
                    t: s.t,
                    obs: s.obs,
                    action: s.action,
                    next_obs: s.next_obs,
                    env_step: step,
                });
                summary.env_return += step.reward;
                summary.final_reward = step.reward;
                summary.length += 1;
                summary.terminated = step.terminated;
                Ok(step.terminated || step.truncated)
            },
        )
    }

    /// Writes observations into the critic input's observation rows.
    fn fill_q_obs(q_in: &mut DMatrix<f32>, obs: &DMatrix<f32>, obs_dim: usize) {
        let rows = q_in.nrows();
        for (dst, src) in q_in
            .as_mut_slice()
            .chunks_exact_mut(rows)
            .zip(obs.as_slice().chunks_exact(obs_dim))
        {
            dst[..obs_dim].copy_from_slice(src);
        }
    }

    /// Writes actions into the critic input's action rows.
    fn fill_q_actions(q_in: &mut DMatrix<f32>, actions: &DMatrix<f32>, obs_dim: usize) {
        let rows = q_in.nrows();
        let a = rows - obs_dim;
        for (dst, src) in q_in
            .as_mut_slice()
            .chunks_exact_mut(rows)
            .zip(actions.as_slice().chunks_exact(a))
        {
            dst[obs_dim..].copy_from_slice(src);
        }
    }

    /// One SAC update on `batch` with per-transition `rewards` (from whatever reward function
    /// the caller uses). Bootstraps unless the transition's `terminated` flag is set.
    ///
    /// Order: critics (targets from the current actor and target critics), then the actor
    /// against the updated critics, then α (when tuned), then Polyak averaging of the targets.
    /// Stops with [`SacError::NonFinite`] naming the network if a loss or parameter is NaN/inf.
    pub fn update(
        &mut self,
        batch: &ReplayBatch,
        rewards: &[f32],
        rng: &mut impl Rng,
    ) -> Result<UpdateStats, SacError> {
        let b = self.config.batch_size;
        assert_eq!(batch.len(), b, "batch size differs from the config's");
        assert_eq!(rewards.len(), b, "one reward per transition");
        let update = self.updates + 1;
        let inv_b = 1.0 / b as f32;
        let alpha = self.log_alpha.exp();
        let gamma = self.config.gamma;
        let obs_dim = self.obs_dim;
        let ws = &mut self.ws;

        // Critic targets: y = r + γ (1 − terminated) (min Q_targ(s', a') − α log π(a'|s')).
        let head = self.actor.forward(&batch.next_obs, &mut ws.actor);
        ws.draw.sample(head, rng);
        Self::fill_q_obs(&mut ws.q_in, &batch.next_obs, obs_dim);
        Self::fill_q_actions(&mut ws.q_in, &ws.draw.actions, obs_dim);
        let qt1 = self.q1_target.forward(&ws.q_in, &mut ws.q1);
        let qt2 = self.q2_target.forward(&ws.q_in, &mut ws.q2);
        for j in 0..b {
            let soft_v = qt1[j].min(qt2[j]) - alpha * ws.draw.log_prob[j];
            ws.targets[j] = rewards[j] + gamma * (1.0 - batch.terminated[j]) * soft_v;
        }

        // Critics: L = ½ mean (Q − y)².
        Self::fill_q_obs(&mut ws.q_in, &batch.obs, obs_dim);
        Self::fill_q_actions(&mut ws.q_in, &batch.actions, obs_dim);
        let mut q_losses = [0.0f32; 2];
        for (i, (q, opt, qws)) in [
            (&mut self.q1, &mut self.q1_opt, &mut ws.q1),
            (&mut self.q2, &mut self.q2_opt, &mut ws.q2),
        ]
        .into_iter()
        .enumerate()
        {
            let values = q.forward(&ws.q_in, qws);
            let mut loss = 0.0;
            for ((d, &v), &y) in ws
                .dq
                .as_mut_slice()
                .iter_mut()
                .zip(values.as_slice())
                .zip(&ws.targets)
            {
                let err = v - y;
                loss += err * err;
                *d = err * inv_b;
            }
            q_losses[i] = 0.5 * loss * inv_b;
            let name = ["critic q1", "critic q2"][i];
            check_finite(q_losses[i].is_finite(), name, "loss", update)?;
            q.backward(&ws.q_in, qws, &ws.dq, None, BackwardMode::Params);
            opt.step_mlp(q);
            check_finite(q.params_finite(), name, "parameter", update)?;
        }

        // Actor: L = mean(α log π(a|s) − min Q(s, a)), a reparameterised.
        let head = self.actor.forward(&batch.obs, &mut ws.actor);
        ws.draw.sample(head, rng);
        Self::fill_q_actions(&mut ws.q_in, &ws.draw.actions, obs_dim);
        self.q1.forward(&ws.q_in, &mut ws.q1);
        self.q2.forward(&ws.q_in, &mut ws.q2);
        let mut actor_loss = 0.0;
        let mut sum_log_prob = 0.0;
        {
            let (v1, v2) = (ws.q1.output().as_slice(), ws.q2.output().as_slice());
            for j in 0..b {
                actor_loss += alpha * ws.draw.log_prob[j] - v1[j].min(v2[j]);
                sum_log_prob += ws.draw.log_prob[j];
                ws.d_log_prob[j] = alpha * inv_b;
            }
        }
        actor_loss *= inv_b;
        check_finite(actor_loss.is_finite(), "actor", "loss", update)?;
        // ∂L/∂a through whichever critic is the minimum for each sample.
        for first in [true, false] {
            let (v1, v2) = (ws.q1.output(), ws.q2.output());
            for j in 0..b {
                let q1_is_min = v1[j] <= v2[j];
                ws.dq[j] = if q1_is_min == first { -inv_b } else { 0.0 };
            }
            let (q, qws) = if first {
                (&mut self.q1, &mut ws.q1)
            } else {
                (&mut self.q2, &mut ws.q2)
            };
            q.backward(
                &ws.q_in,
                qws,
                &ws.dq,
                Some(&mut ws.dq_in),
                BackwardMode::InputOnly,
            );
            let rows = ws.dq_in.nrows();
            for (da, dqi) in ws
                .d_actions
                .as_mut_slice()
                .chunks_exact_mut(self.act_dim)
                .zip(ws.dq_in.as_slice().chunks_exact(rows))
            {
                for (d, g) in da.iter_mut().zip(&dqi[obs_dim..]) {
                    *d = if first { *g } else { *d + g };
                }
            }
        }
        gaussian::backward(
            ws.actor.output(),
            &ws.draw.eps,
            &ws.draw.actions,
            &ws.d_actions,
            &ws.d_log_prob,
            &mut ws.d_head,
        );
        self.actor.backward(
            &batch.obs,
            &mut ws.actor,
            &ws.d_head,
            None,
            BackwardMode::Params,
        );
        self.actor_opt.step_mlp(&mut self.actor);
        check_finite(self.actor.params_finite(), "actor", "parameter", update)?;

        // Temperature: L(log α) = −log α · mean(log π + H_target).
        let mean_log_prob = sum_log_prob * inv_b;
        if self.config.auto_alpha {
            let grad = -(mean_log_prob + self.target_entropy);
            let mut p = [self.log_alpha];
            self.alpha_opt
                .step_tensors(&mut [(&mut p[..], &[grad][..])]);
            self.log_alpha = p[0];
            check_finite(
                self.log_alpha.is_finite(),
                "temperature",
                "parameter",
                update,
            )?;
        }

        self.q1_target.polyak_from(&self.q1, self.config.tau);
        self.q2_target.polyak_from(&self.q2, self.config.tau);
        self.updates = update;
        Ok(UpdateStats {
            q1_loss: q_losses[0],
            q2_loss: q_losses[1],
            actor_loss,
            alpha,
            mean_log_prob,
        })
    }

    /// The five networks in checkpoint order, with names for messages.
    fn networks(&self) -> [(&'static str, &Mlp); 5] {
        [
            ("actor", &self.actor),
            ("critic q1", &self.q1),
            ("critic q2", &self.q2),
            ("target critic q1", &self.q1_target),
            ("target critic q2", &self.q2_target),
        ]
    }

    /// Appends networks, optimiser states, temperature and the update counter.
    pub fn write(&self, w: &mut ByteWriter) {
        for (_, net) in self.networks() {
            net.write(w);
        }
        for opt in [&self.actor_opt, &self.q1_opt, &self.q2_opt, &self.alpha_opt] {
            opt.write(w);
        }
        w.f32(self.log_alpha);
        w.u64(self.updates);
    }

    /// Reads state written by [`SacAgent::write`]. A network of another architecture gives
    /// `Ok(Err((name, found, expected)))`.
    #[allow(clippy::type_complexity)]
    pub fn read_into(
        &mut self,
        r: &mut ByteReader,
    ) -> Result<Result<(), (&'static str, MlpArch, MlpArch)>, CodecError> {
        let names = self.networks().map(|(n, _)| n);
        let nets = [
            &mut self.actor,
            &mut self.q1,
            &mut self.q2,
            &mut self.q1_target,
            &mut self.q2_target,
        ];
        for (name, net) in names.into_iter().zip(nets) {
            if let Err(found) = net.read_into(r)? {
                return Ok(Err((name, found, net.arch())));
            }
        }
        for opt in [
            &mut self.actor_opt,
            &mut self.q1_opt,
            &mut self.q2_opt,
            &mut self.alpha_opt,
        ] {
            opt.read_into(r)?;
        }
        self.log_alpha = r.f32("log alpha")?;
        self.updates = r.u64("update count")?;
        Ok(Ok(()))
    }
}
