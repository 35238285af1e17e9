//! Counterfactual experiences for reward machines (CRM; Toro Icarte, Klassen, Valenzano &
//! McIlraith, "Reward Machines: Exploiting Reward Function Structure in Reinforcement
//! Learning", JAIR 2022), applied to sampled replay batches of a product environment.
//!
//! A transition (o, u, a, o') of the product MDP says what the *environment* does after action
//! a in o; the machine's part is a known function of the labels L(o'). So the same
//! environment step is also a valid experience from every other machine state ũ:
//! (o, ũ, a, o', δ_u(ũ, L(o'))). CRM trains on all of them. Here it is done at sample time:
//! a share of each sampled batch gets its machine state replaced by one drawn uniformly from
//! the non-absorbing states, with the next state, the termination flag and the machine's reward
//! recomputed — in expectation the batch is drawn from the buffer CRM would have filled with
//! all |U| copies, without storing them.
//!
//! Why it matters for SMIRL's inner SAC: the value of a later machine state (e.g. "touch blue
//! after red and green") is otherwise learned only from the steps the agent happens to spend
//! in that state; with CRM every touch of blue anywhere in the buffer teaches what touching
//! blue is worth there.
//!
//! Observations are the product's layout: the inner observation (`inner_dim` columns) then a
//! one-hot block of the machine state (`rm::product::one_hot`).

use super::replay::ReplayBatch;
use crate::rm::product::one_hot;
use crate::rm::RewardMachine;
use rand::{Rng, RngCore};

/// Bad CRM settings.
#[derive(Debug, thiserror::Error)]
pub enum CrmError {
    #[error("counterfactual share must be in [0, 1], got {0}")]
    Fraction(f64),
    #[error("the reward machine has no non-absorbing state to relabel from")]
    NoStartState,
}

/// Sample-time counterfactual relabelling with one reward machine.
#[derive(Clone, Debug)]
pub struct CounterfactualRm {
    rm: RewardMachine,
    inner_dim: usize,
    fraction: f64,
    /// States a transition can start from (an episode ends on entering an absorbing state).
    starts: Vec<usize>,
}

impl CounterfactualRm {
    /// Relabels a share `fraction` ∈ [0, 1] of every batch, for observations made of
    /// `inner_dim` inner columns and the machine's one-hot block.
    pub fn new(
        rm: RewardMachine,
        inner_dim: usize,
        fraction: f64,
    ) -> Result<CounterfactualRm, CrmError> {
        if !(0.0..=1.0).contains(&fraction) {
            return Err(CrmError::Fraction(fraction));
        }
        let starts: Vec<usize> = (0..rm.n_states())
            .filter(|&u| !rm.is_absorbing(u))
            .collect();
        if starts.is_empty() {
            return Err(CrmError::NoStartState);
        }
        Ok(CounterfactualRm {
            rm,
            inner_dim,
            fraction,
            starts,
        })
    }

    pub fn fraction(&self) -> f64 {
        self.fraction
    }

    /// Rewrites about `fraction` of the batch's transitions in place: machine state ũ drawn
    /// uniformly from the non-absorbing states, next state δ_u(ũ, L(o')), `env_rewards` the
    /// machine's reward δ_r(ũ, L(o')) (as the unshaped product reports it), `terminated` set
    /// when the environment itself ended the episode or ũ's successor is absorbing. The
    /// environment's own termination is read back as "terminated although the logged successor
    /// state is not absorbing" — so an environment that ends an episode on the very step its
    /// machine reaches a goal is taken as not ending it (ReacherDelivery never ends one
    /// itself: only the time limit, which is not a termination).
    ///
    /// # Panics
    /// If the batch's observations are not `inner_dim` + machine-states rows (a programming
    /// error: the batch comes from the product environment this relabeller was built for).
    pub fn relabel(&self, batch: &mut ReplayBatch, rng: &mut dyn RngCore) {
        if self.fraction == 0.0 {
            return;
        }
        let n = self.rm.n_states();
        let d = batch.obs.nrows();
        assert_eq!(
            d,
            self.inner_dim + n,
            "product observation width (inner + one-hot machine state)"
        );
        let block = self.inner_dim..self.inner_dim + n;
        for i in 0..batch.len() {
            if self.fraction < 1.0 && rng.gen::<f64>() >= self.fraction {
                continue;
            }
            let logged_next = hot_index(&batch.next_obs.column(i).as_slice()[block.clone()]);
            let env_terminated = batch.terminated[i] > 0.5 && !self.rm.is_absorbing(logged_next);
            let u = self.starts[rng.gen_range(0..self.starts.len())];
            let (u_next, reward) = self.rm.step(u, batch.labels[i]);
            one_hot(
                u,
                &mut batch.obs.column_mut(i).as_mut_slice()[block.clone()],
            );
            one_hot(
                u_next,
                &mut batch.next_obs.column_mut(i).as_mut_slice()[block.clone()],
            );
            batch.env_rewards[i] = reward as f32;
            batch.terminated[i] =
                f32::from(u8::from(env_terminated || self.rm.is_absorbing(u_next)));
        }
    }
}

/// Index of the hot entry of a one-hot block (0 if none is hot).
pub fn hot_index(block: &[f32]) -> usize {
    block.iter().position(|&x| x > 0.5).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rm::format::parse_rm;
    use crate::rm::LabelSet;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// r then b → goal (state 2, reward 1); c in state 1 → failure (state 3).
    fn machine() -> RewardMachine {
        parse_rm(
            "vocabulary: rgbyc\nstates: 4\ninitial: 0\nterminal: 2\nfailure: 3\n\
             (0, 1, 'r', 0)\n(1, 2, 'b', 1)\n(1, 3, 'c&!b', 0)\n",
            "test machine",
        )
        .expect("valid machine")
    }

    const INNER: usize = 3;

    /// A batch of `labels.len()` transitions, all logged in machine state 0 → 0.
    fn batch(labels: &[LabelSet]) -> ReplayBatch {
        let mut b = ReplayBatch::new(INNER + 4, 2, labels.len());
        for (i, &l) in labels.iter().enumerate() {
            for r in 0..INNER {
                b.obs[(r, i)] = (10 * i + r) as f32;
                b.next_obs[(r, i)] = (10 * i + r) as f32 + 0.5;
            }
            b.obs[(INNER, i)] = 1.0;
            b.next_obs[(INNER, i)] = 1.0;
            b.labels[i] = l;
            b.env_rewards[i] = -7.0;
            b.indices[i] = i;
        }
        b
    }

    fn state(col: &[f32]) -> usize {
        hot_index(&col[INNER..])
    }

    #[test]
    fn every_relabelled_transition_follows_the_machine() {
        let rm = machine();
        let crm = CounterfactualRm::new(rm.clone(), INNER, 1.0).unwrap();
        let labels = [
            LabelSet::EMPTY,
            LabelSet::EMPTY.with(0),
            LabelSet::EMPTY.with(2),
        ]
        .repeat(100);
        let mut b = batch(&labels);
        let before = b.clone();
        crm.relabel(&mut b, &mut ChaCha8Rng::seed_from_u64(1));
        let mut seen = [0usize; 4];
        for (i, &label) in labels.iter().enumerate() {
            let u = state(b.obs.column(i).as_slice());
            let u_next = state(b.next_obs.column(i).as_slice());
            seen[u] += 1;
            let (expected_next, reward) = rm.step(u, label);
            assert!(
                !rm.is_absorbing(u),
                "transition {i} starts in absorbing state {u}"
            );
            assert_eq!(u_next, expected_next, "transition {i}");
            assert_eq!(b.env_rewards[i], reward as f32);
            assert_eq!(b.terminated[i] > 0.5, rm.is_absorbing(u_next));
            // One-hot blocks are exactly one-hot; the inner observation is untouched.
            assert_eq!(b.obs.column(i).as_slice()[INNER..].iter().sum::<f32>(), 1.0);
            assert_eq!(
                b.obs.column(i).as_slice()[..INNER],
                before.obs.column(i).as_slice()[..INNER]
            );
            assert_eq!(
                b.next_obs.column(i).as_slice()[..INNER],
                before.next_obs.column(i).as_slice()[..INNER]
            );
        }
        // Both non-absorbing states are drawn, about equally often (300 draws).
        assert_eq!(seen[2] + seen[3], 0);
        assert!(seen[0] > 110 && seen[1] > 110, "{seen:?}");
        // The goal is reached by the counterfactual "b in state 1" transitions only.
        assert!((0..b.len()).any(|i| b.terminated[i] > 0.5 && b.env_rewards[i] == 1.0));
    }

    #[test]
    fn a_share_of_the_batch_is_relabelled_and_zero_draws_nothing() {
        let crm = CounterfactualRm::new(machine(), INNER, 0.5).unwrap();
        let labels = vec![LabelSet::EMPTY; 400];
        let mut b = batch(&labels);
        crm.relabel(&mut b, &mut ChaCha8Rng::seed_from_u64(2));
        // Relabelled transitions keep env_rewards = machine reward (0 here), the rest −7.
        let relabelled = b.env_rewards.iter().filter(|&&r| r == 0.0).count();
        assert!((150..250).contains(&relabelled), "{relabelled} of 400");

        let off = CounterfactualRm::new(machine(), INNER, 0.0).unwrap();
        let mut b = batch(&labels);
        let before = b.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        off.relabel(&mut b, &mut rng);
        assert_eq!(b.obs, before.obs);
        assert_eq!(b.env_rewards, before.env_rewards);
        assert_eq!(rng, ChaCha8Rng::seed_from_u64(3), "no draw when off");
    }

    #[test]
    fn the_environments_own_termination_is_kept() {
        let crm = CounterfactualRm::new(machine(), INNER, 1.0).unwrap();
        let mut b = batch(&[LabelSet::EMPTY; 20]);
        b.terminated.fill(1.0); // logged 0 → 0, not absorbing: the environment ended it
        crm.relabel(&mut b, &mut ChaCha8Rng::seed_from_u64(4));
        assert!(b.terminated.iter().all(|&t| t == 1.0));
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(matches!(
            CounterfactualRm::new(machine(), INNER, 1.5),
            Err(CrmError::Fraction(_))
        ));
        assert!(matches!(
            CounterfactualRm::new(machine(), INNER, f64::NAN),
            Err(CrmError::Fraction(_))
        ));
        let all_absorbing = parse_rm(
            "vocabulary: rgbyc\nstates: 1\ninitial: 0\nterminal: 0\nfailure: \n",
            "absorbing",
        )
        .unwrap();
        assert!(matches!(
            CounterfactualRm::new(all_absorbing, INNER, 1.0),
            Err(CrmError::NoStartState)
        ));
    }
}
