#!/usr/bin/env bash
# Diagnostic for IF smirl seed 1 (figure 7, cancel branch 0.75): the learned machine has no
# transition for the label set {r, c} (the cancel firing while the fingertip is on red), which
# no demonstration shows, so on it the machine stays where it is and the agent goes on to
# blue — a failure once the cancel has fired. This script prepares the figure-7 IF run again
# (same demonstrations and learned machine, base seed 0), adds the two transitions the
# perfect machine implies for {r, c} (start -> cancelled, red-touched -> go-to-red), runs
# smirl seed 1 and prints its per-iteration success per branch. A diagnosis of the cause,
# not a setting: the figure's machine is the one LRM learned.
# Usage: experiments/reacher/diagnose_unseen_label_set.sh [OUT]   (default /tmp/diagnose-if-rc)
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${1:-/tmp/diagnose-if-rc}
BIN=${REACHER_BIN:-target/release/reacher}
[ -n "${REACHER_BIN:-}" ] || cargo build --release --bin reacher
# The machine of the exact-guard run (LRM's reading of unseen label sets: stay), which
# runs/if-exact_guards used; the default config now says lrm_guards = "tree".
CONFIG=$(mktemp --suffix=.toml)
sed 's/^lrm_guards = .*/lrm_guards = "exact"/' experiments/reacher/config_uniform.toml > "$CONFIG"
"$BIN" prepare --task if --algo smirl --seeds 3 --config "$CONFIG" --out "$OUT"
rm -f "$CONFIG"
cmp "$OUT/rm/learned.txt" experiments/reacher/runs/if-exact_guards/rm/learned.txt
printf "(0, 3, 'r&!g&!b&!y&c', 0)\n(1, 2, 'r&!g&!b&!y&c', 0)\n" >> "$OUT/rm/learned.txt"
"$BIN" job --run "$OUT" --algo smirl --seed 1 --quiet
python3 - "$OUT/jobs/smirl_seed1.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print("iteration success normal cancel")
for row in r["rows"]:
    b = row["branches"]
    rate = lambda i: b["successes"][i] / max(b["episodes"][i], 1)
    print(row["iteration"], row["success_rate"], "%.2f" % rate(0), "%.2f" % rate(1))
PY
