#!/usr/bin/env bash
# The run behind the "reward was not what was lost" diagnosis in results.md: Composite, smirl,
# seeds 0-2, without counterfactual states (ablations/no_crm.toml), with the per-iteration
# reward trace (rewards/smirl_seed<S>.trace.csv; read it with experiments/reacher/trace.py).
# Usage: experiments/reacher/diagnose.sh   -> experiments/reacher/diagnostics/no_crm-composite
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin reacher
mkdir -p experiments/reacher/diagnostics
./target/release/reacher --task composite --algo smirl --seeds 3 \
  --config experiments/reacher/ablations/no_crm.toml \
  --out experiments/reacher/diagnostics/no_crm-composite --force --quiet \
  > experiments/reacher/diagnostics/no_crm-composite.log
