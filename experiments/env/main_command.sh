#!/usr/bin/env bash
# Times the README's main command (`reacher --task composite`, seed 0, default configuration) and
# prints what it measured: the commit, the load before it, wall and user time, each job's wall
# time (run.json) and log size (logs/<algo>_seed0.mcap), and the run's summary.md. Append the
# output to experiments/env/main_command.txt. An idle timing needs an idle machine: the load
# average printed first says whether it was.
#
#   experiments/env/main_command.sh target/release/reacher WORKDIR
#
# WORKDIR must not exist; the run directory is WORKDIR/main-composite (kept, for replay).
set -euo pipefail
if [ $# -ne 2 ]; then
    echo "usage: $0 REACHER_BIN WORKDIR (a directory that does not exist yet)" >&2
    exit 2
fi
bin=$(realpath "$1")
work=$2
if [ -e "$work" ]; then
    echo "$work exists: give a new directory (this script writes only into its own)" >&2
    exit 2
fi
mkdir -p "$work"
cd "$work"
echo "# The README's main command: /usr/bin/time -f '%e s wall, %U s user' reacher --task composite --out main-composite --quiet"
echo "# binary: $("$bin" --version); $(nproc) cores; load average at the start: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "# started $(date -u '+%Y-%m-%d %H:%M UTC')"
/usr/bin/time -o time.txt -f '%e s wall, %U s user' "$bin" --task composite --out main-composite --quiet > stdout.txt
echo "# ended $(date -u '+%Y-%m-%d %H:%M UTC'); total: $(cat time.txt)"
python3 - main-composite <<'EOF'
import json, os, sys
run = sys.argv[1]
with open(os.path.join(run, "run.json")) as fh:
    info = json.load(fh)
rows = []
for job in info["jobs"]:
    log = os.path.join(run, "logs", f"{job['algo']}_seed{job['seed']}.mcap")
    rows.append(f"{job['algo']} {job['wall_secs']:.0f} s, log {os.path.getsize(log) / 1e6:.1f} MB")
print(f"# prepare {info['prepare_secs']:.0f} s; per job (run.json wall_secs; logs/<algo>_seed0.mcap): " + "; ".join(rows))
EOF
echo "# summary.md:"
sed 's/^/# /' main-composite/summary.md
