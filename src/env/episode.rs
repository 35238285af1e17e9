//! The crate's one episode loop ([`play`]): reset, then act and step until the episode ends.
//! What differs between its users (which step they take: the environment's own, the product's
//! with its machine report, the IRL jobs' with the ground truth tracked; what they record) is
//! theirs, in the closures they hand it.

use super::ContinuousEnv;

/// One step of an episode being played: the action chosen for `obs`, to be taken, with the
/// next observation written into `next_obs`.
pub struct Step<'a> {
    /// 0-based index of the step within the episode.
    pub t: u64,
    pub obs: &'a [f32],
    pub action: &'a [f32],
    pub next_obs: &'a mut [f32],
}

/// Plays one episode of `env`: resets it with `reset_seed`, hands the first observation to
/// `begin` (which makes the episode's state: a summary, a recording, a log in progress), then,
/// for at most `max_steps` steps, `act` writes the action for the current observation and `step`
/// takes it and says whether the episode ended there. Returns the episode's state.
///
/// `act` runs before every step and `step` after it, in that order, so a policy drawing from a
/// random stream draws exactly once per step, as a hand-written loop would.
pub fn play<E, S, Err>(
    env: &mut E,
    reset_seed: u64,
    max_steps: u64,
    begin: impl FnOnce(&E, &[f32]) -> Result<S, Err>,
    mut act: impl FnMut(&E, &[f32], &mut [f32]),
    mut step: impl FnMut(&mut S, &mut E, Step<'_>) -> Result<bool, Err>,
) -> Result<S, Err>
where
    E: ContinuousEnv + ?Sized,
{
    let mut obs = vec![0.0f32; env.obs_dim()];
    let mut next_obs = vec![0.0f32; env.obs_dim()];
    let mut action = vec![0.0f32; env.act_dim()];
    env.reset(reset_seed, &mut obs);
    let mut state = begin(&*env, &obs)?;
    for t in 0..max_steps {
        act(&*env, &obs, &mut action);
        let s = Step {
            t,
            obs: &obs,
            action: &action,
            next_obs: &mut next_obs,
        };
        let ended = step(&mut state, env, s)?;
        std::mem::swap(&mut obs, &mut next_obs);
        if ended {
            break;
        }
    }
    Ok(state)
}
