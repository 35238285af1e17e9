//! The demonstrations as every IRL job of a task reads them ([`ExpertData`]), and their file
//! in a run directory.

use crate::nn::codec::{ByteReader, ByteWriter, CodecError};
use crate::rm::RewardMachine;

/// What every job of a task shares: the demonstrations as the IRL algorithms see them.
#[derive(Clone, Debug)]
pub struct ExpertData {
    /// Observations o_1..o_T of every demonstration step (row-major, one task observation
    /// wide): the states visited, as the agent's rollouts record them.
    pub obs: Vec<f32>,
    /// Demonstration lengths, in order.
    pub lengths: Vec<usize>,
    /// The learned machine's state each observation's labels are read in (u_{t−1}); empty
    /// when no machine was learned.
    pub learned_states: Vec<u32>,
}

impl ExpertData {
    pub fn n_states(&self) -> usize {
        self.lengths.iter().sum()
    }

    /// Width of an observation row (0 without any).
    pub fn obs_dim(&self) -> usize {
        self.obs.len() / self.n_states().max(1)
    }

    /// The binary file `reacher prepare` writes for the jobs (`expert_data.bin`): exact
    /// values, so a job that reads it computes what the one-process run computes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.raw(EXPERT_DATA_MAGIC);
        w.u32(EXPERT_DATA_VERSION);
        w.f32s(&self.obs);
        w.usize(self.lengths.len());
        for &len in &self.lengths {
            w.usize(len);
        }
        w.u32s(&self.learned_states);
        w.bytes
    }

    /// Reads [`ExpertData::to_bytes`] of a task whose observations are `obs_dim` wide; every
    /// count is checked against the bytes present and the arrays against each other.
    pub fn from_bytes(bytes: &[u8], obs_dim: usize) -> Result<ExpertData, CodecError> {
        let mut r = ByteReader::new(bytes);
        r.header(EXPERT_DATA_MAGIC, "smirl expert data", EXPERT_DATA_VERSION)?;
        let obs = r.f32s("observations")?;
        let n = r.usize("demonstration count")?;
        if n > bytes.len() / 8 {
            return Err(CodecError::Invalid {
                what: "demonstration count",
                problem: format!("{n} is more than the file can hold"),
            });
        }
        let lengths = (0..n)
            .map(|_| r.usize("demonstration length"))
            .collect::<Result<Vec<_>, _>>()?;
        let learned_states = r.u32s("learned machine states")?;
        r.finish()?;
        let steps = lengths
            .iter()
            .try_fold(0usize, |a, &l| a.checked_add(l))
            .filter(|&t| t.checked_mul(obs_dim) == Some(obs.len()))
            .ok_or_else(|| CodecError::Invalid {
                what: "observations",
                problem: format!(
                    "{} values do not fill the demonstrations' {n} lengths × {obs_dim}",
                    obs.len()
                ),
            })?;
        if !learned_states.is_empty() && learned_states.len() != steps {
            return Err(CodecError::Invalid {
                what: "learned machine states",
                problem: format!("{} states for {steps} steps", learned_states.len()),
            });
        }
        Ok(ExpertData {
            obs,
            lengths,
            learned_states,
        })
    }

    /// Checks the learned-machine states against `machine`, the one they were read in (the
    /// run's `rm/learned.txt`): one per step and each a state of it, so that no index read
    /// from the file reaches past the machine's arrays.
    pub fn check_machine(&self, machine: Option<&RewardMachine>) -> Result<(), CodecError> {
        let Some(machine) = machine else {
            return Ok(());
        };
        let invalid = |problem: String| CodecError::Invalid {
            what: "learned machine states",
            problem,
        };
        if self.learned_states.len() != self.n_states() {
            return Err(invalid(format!(
                "{} states for {} steps of a run with a learned machine",
                self.learned_states.len(),
                self.n_states()
            )));
        }
        let n = machine.n_states();
        if let Some(&u) = self.learned_states.iter().find(|&&u| u as usize >= n) {
            return Err(invalid(format!(
                "state {u} is not a state of the learned machine ({n} states)"
            )));
        }
        Ok(())
    }
}

const EXPERT_DATA_MAGIC: &[u8] = b"SMIRLXD\0";
/// The layout [`ExpertData::to_bytes`] writes after the magic bytes and this version: the
/// observations, the demonstration lengths, the learned-machine states. A file of another
/// version is refused ([`CodecError::Version`]).
const EXPERT_DATA_VERSION: u32 = 3;
