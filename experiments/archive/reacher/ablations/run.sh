#!/usr/bin/env bash
# SMIRL ablations on ReacherDelivery, 3 seeds, expert demonstrations. Usage:
#   experiments/reacher/ablations/run.sh
# paper_sac.toml is experiments/reacher/config_uniform.toml with the paper's IRL SAC ([sac] lr 3e-3,
# replay_capacity 10000; the default before this session's change; all six algorithms, so its
# run directories are the whole figure 7 of that default; held-out seeds:
# experiments/reacher/heldout.sh experiments/reacher/ablations/paper_sac.toml paper_sac-).
# no_crm.toml is paper_sac.toml without counterfactual learned-machine states
# (smirl_counterfactual = 0, the default before CRM; all six algorithms); crm_lr_decay adds
# reward_lr_decay = 0.5 and replay_100k a 10x replay buffer to paper_sac (held-out seeds of the
# latter: experiments/reacher/heldout.sh experiments/reacher/ablations/replay_100k.toml
# replay_100k-); shaping, lr_decay and no_l2 each change one more setting of no_crm.toml
# (they were run against that default).
# Run directories go to experiments/reacher/ablations/runs/<ablation>-<task>; the table:
#   python3 experiments/reacher/ablations/results.py
set -euo pipefail
cd "$(dirname "$0")/../../.."
cargo build --release --bin reacher
out=experiments/reacher/ablations/runs
mkdir -p "$out"
run() { # ablation task algos
  ./target/release/reacher --task "$2" --algo "$3" --seeds 3 \
    --config "experiments/reacher/ablations/$1.toml" --out "$out/$1-$2" --force --quiet > "$out/$1-$2.log"
}
for task in or sequential if composite; do
  run paper_sac "$task" all                 # [sac] lr = 3e-3, replay_capacity = 10000
  run no_crm "$task" all                    # paper_sac + smirl_counterfactual = 0
done
run demos_32 composite smirl                # default + demo_episodes = 32 (held-out seeds:
# heldout.sh experiments/reacher/ablations/demos_32.toml demos_32- [and demos_32-seeds6- 6])
run crm_lr_decay or smirl                   # paper_sac + reward_lr_decay = 0.5
run crm_lr_decay sequential smirl
run crm_lr_decay if smirl
run replay_100k or smirl                    # paper_sac + [sac] replay_capacity = 100000
run replay_100k sequential smirl
run replay_100k if smirl
run shaping sequential smirl,smirl-smooth   # smirl_shaping = 1.0
run lr_decay or smirl                       # reward_lr_decay = 0.5
run lr_decay if smirl
run lr_decay composite smirl
run no_l2 or smirl                          # smirl_reward_l2 = 0
run no_l2 composite smirl
# Issue 13: against config_unshaped.toml (the standard profile before SMIRL's shaping) ...
run shaping_crm or smirl                    # smirl_shaping = 1.0 (with CRM)
run shaping_crm sequential smirl
run shaping_crm if smirl
run shaping_crm composite smirl
run shaping_2 sequential smirl              # smirl_shaping = 2.0
run label_entries composite smirl           # smirl_label_features = "entries"
# ... and against config.toml (30 iterations with shaping)
for task in or sequential if composite; do
  run shaped_lr_decay "$task" smirl         # reward_lr_decay = 0.5
done
