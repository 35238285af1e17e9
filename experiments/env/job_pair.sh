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
# OWN_CONFIG=1 is for a BEFORE binary whose configuration or run directory differ from AFTER's
# (an older commit): each binary prints its own standard configuration (cut to ITERS the same
# way), prepares its own run and runs it; the script then checks that the two binaries give the
# same bytes of expert demonstrations on every paper task (`expert_data.bin` of an fkl run:
# format version, observations, lengths; binaries that write different versions of the file
# differ there whatever their demonstrations) and that each binary's jobs match its own first job, and
# prints the median wall seconds of each side with their ratio too.
#
#   [ALGO=smirl] [OWN_CONFIG=1] nice -n 10 experiments/env/job_pair.sh BEFORE_BIN AFTER_BIN [REPS] [ITERS]
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
OWN_CONFIG=${OWN_CONFIG:-0}
# job_config BIN OUT: BIN's standard configuration for Composite, cut to ITERS.
job_config() {
    if [ "$ITERS" = full ]; then
        "$1" --task composite --print-config > "$2"
    else
        "$1" --task composite --print-config \
            | sed -e "s/^irl_iterations = 800$/irl_iterations = $ITERS/" \
                -e 's/^sac_steps = 20000$/sac_steps = 0/' \
                -e 's/^checkpoints = 4$/checkpoints = 0/' > "$2"
    fi
}
schedule="the standard configuration"
[ "$ITERS" = full ] || schedule="standard schedule with $ITERS IRL iterations, no final phase"
rm -rf "$WORK/prepared" "$WORK/prepared_before" "$WORK/user_before" "$WORK/user_after" \
    "$WORK/wall_before" "$WORK/wall_after"
job_config "$AFTER" "$WORK/job.toml"
"$AFTER" prepare --task composite --config "$WORK/job.toml" --algo "$ALGO" --quiet \
    --out "$WORK/prepared" > /dev/null
if [ "$OWN_CONFIG" = 1 ]; then
    job_config "$BEFORE" "$WORK/job_before.toml"
    "$BEFORE" prepare --task composite --config "$WORK/job_before.toml" --algo "$ALGO" --quiet \
        --out "$WORK/prepared_before" > /dev/null
    # The experts' demonstrations of every paper task, prepared for fkl (observations and
    # lengths; no learned machine), by each binary with its own standard configuration.
    demos=""
    for task in or sequential if composite; do
        for side in before after; do
            side_bin=$BEFORE
            [ "$side" = after ] && side_bin=$AFTER
            rm -rf "$WORK/demos_${side}_$task"
            "$side_bin" --task "$task" --print-config > "$WORK/demos_$side.toml"
            "$side_bin" prepare --task "$task" --config "$WORK/demos_$side.toml" --algo fkl \
                --quiet --out "$WORK/demos_${side}_$task" > /dev/null
        done
        same=identical
        cmp -s "$WORK/demos_before_$task/expert_data.bin" "$WORK/demos_after_$task/expert_data.bin" \
            || same=DIFFER
        demos="$demos $task $same,"
    done
    echo "# each binary's own configuration and prepared run; expert demonstrations:${demos%,}"
fi
echo "# $ALGO, composite, $schedule; $(nproc) cores"
stem="${ALGO}_seed0"
for rep in $(seq 1 "$REPS"); do
    for which in before after; do
        bin=$BEFORE
        [ "$which" = after ] && bin=$AFTER
        run="$WORK/${which}_$rep"
        rm -rf "$run"
        prepared="$WORK/prepared"
        [ "$OWN_CONFIG" = 1 ] && [ "$which" = before ] && prepared="$WORK/prepared_before"
        cp -r "$prepared" "$run"
        /usr/bin/time -o "$WORK/time" -f "%e s wall, %U s user, %S s sys" \
            "$bin" job --run "$run" --algo "$ALGO" --seed 0 --quiet > /dev/null
        sed 's/"wall_secs":[0-9.e+-]*//' "$run/jobs/$stem.json" > "$run/record.txt"
        replayer=$AFTER
        [ "$OWN_CONFIG" = 1 ] && replayer=$bin
        "$replayer" replay "$run/logs/$stem.mcap" | grep -v 'steps replayed in' > "$run/replay.txt"
        # The outputs are compared with the first before job's, or with the binary's own first
        # job's when each binary has its own configuration.
        first="$WORK/before_1"
        [ "$OWN_CONFIG" = 1 ] && first="$WORK/${which}_1"
        same=identical
        for f in record.txt replay.txt $(cd "$first" && find rewards -type f | sort); do
            cmp -s "$run/$f" "$first/$f" || same="DIFFERS ($f)"
        done
        echo "$which rep $rep: $(cat "$WORK/time"); load $(cut -d' ' -f1 /proc/loadavg); $same"
        cut -d' ' -f1 "$WORK/time" >> "$WORK/wall_$which"
        cut -d' ' -f4 "$WORK/time" >> "$WORK/user_$which"
    done
done
median() { sort -g "$1" | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
b=$(median "$WORK/user_before")
a=$(median "$WORK/user_after")
echo "# median user CPU: before $b s, after $a s: after/before $(awk -v a="$a" -v b="$b" 'BEGIN {printf "%.3f", a / b}')"
if [ "$OWN_CONFIG" = 1 ]; then
    b=$(median "$WORK/wall_before")
    a=$(median "$WORK/wall_after")
    echo "# median wall: before $b s, after $a s: after/before $(awk -v a="$a" -v b="$b" 'BEGIN {printf "%.3f", a / b}')"
fi
