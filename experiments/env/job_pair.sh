#!/usr/bin/env bash
# One IRL job before/after, interleaved: ALGO (default fkl-product) on Composite, prepared once
# (demonstrations, learned machine) by AFTER_BIN, then run as `reacher job` by the two binaries
# in turn, REPS times. ITERS (default 40) cuts the baselines' standard schedule to that many IRL
# iterations (300 SAC steps, 300 rollouts of 100 steps each) with no final phase; ITERS=full
# runs the standard configuration as it is (SMIRL's whole job, final phase included). Prints
# each job's wall and CPU seconds and the machine's load, the median CPU (user) seconds of each
# side with their ratio after/before, and checks every job's record (but
# wall_secs), reward files and log against the first job's (the log by the listing of `reacher
# replay`, timing line aside: the log's header names the commit the binary was built from).
# Run directories go to $WORK (default target/job_pair).
#
#   [ALGO=smirl] nice -n 10 experiments/env/job_pair.sh BEFORE_BIN AFTER_BIN [REPS] [ITERS]
set -euo pipefail
cd "$(dirname "$0")/../.."
BEFORE=$(realpath "$1")
AFTER=$(realpath "$2")
REPS=${3:-3}
ITERS=${4:-40}
WORK=${WORK:-target/job_pair}
ALGO=${ALGO:-fkl-product}
# WORK is this script's own: it deletes run directories inside it, so it refuses a directory
# it did not make (the marker file says it did).
if [ -e "$WORK" ] && [ ! -e "$WORK/.made_by_job_pair.sh" ]; then
    echo "job_pair.sh: $WORK exists and was not made by this script; set WORK to a new directory" >&2
    exit 2
fi
mkdir -p "$WORK"
touch "$WORK/.made_by_job_pair.sh"
if [ "$ITERS" = full ]; then
    "$AFTER" --task composite --print-config > "$WORK/job.toml"
    schedule="the standard configuration"
else
    "$AFTER" --task composite --print-config \
        | sed -e "s/^irl_iterations = 800$/irl_iterations = $ITERS/" \
            -e 's/^sac_steps = 20000$/sac_steps = 0/' -e 's/^reset_steps = 20000$/reset_steps = 0/' \
            -e 's/^checkpoints = 4$/checkpoints = 0/' > "$WORK/job.toml"
    schedule="standard schedule with $ITERS IRL iterations, no final phase"
fi
rm -rf "$WORK/prepared" "$WORK/user_before" "$WORK/user_after"
"$AFTER" prepare --task composite --config "$WORK/job.toml" --algo "$ALGO" --quiet \
    --out "$WORK/prepared" > /dev/null
echo "# $ALGO, composite, $schedule; $(nproc) cores"
stem="${ALGO}_seed0"
for rep in $(seq 1 "$REPS"); do
    for which in before after; do
        bin=$BEFORE
        [ "$which" = after ] && bin=$AFTER
        run="$WORK/${which}_$rep"
        rm -rf "$run"
        cp -r "$WORK/prepared" "$run"
        /usr/bin/time -o "$WORK/time" -f "%e s wall, %U s user, %S s sys" \
            "$bin" job --run "$run" --algo "$ALGO" --seed 0 --quiet > /dev/null
        sed 's/"wall_secs":[0-9.e+-]*//' "$run/jobs/$stem.json" > "$run/record.txt"
        "$AFTER" replay "$run/logs/$stem.mcap" | grep -v 'steps replayed in' > "$run/replay.txt"
        same=identical
        for f in record.txt replay.txt $(cd "$WORK/before_1" && find rewards -type f | sort); do
            cmp -s "$run/$f" "$WORK/before_1/$f" || same="DIFFERS ($f)"
        done
        echo "$which rep $rep: $(cat "$WORK/time"); load $(cut -d' ' -f1 /proc/loadavg); $same"
        cut -d' ' -f4 "$WORK/time" >> "$WORK/user_$which"
    done
done
median() { sort -g "$1" | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
b=$(median "$WORK/user_before")
a=$(median "$WORK/user_after")
echo "# median user CPU: before $b s, after $a s: after/before $(awk -v a="$a" -v b="$b" 'BEGIN {printf "%.3f", a / b}')"
