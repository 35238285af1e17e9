#!/usr/bin/env bash
# A short f-IRL job before/after, interleaved: fkl on Composite with the standard schedule cut to
# 10 IRL iterations (300 SAC steps, 300 rollouts of 100 steps each), run by two `reacher`
# binaries in turn, REPS times; prints each run's wall and CPU seconds and the job's wall_secs
# from run.json, and the machine's load. Run directories go to $WORK (default
# target/fkl_short_job_pair).
#
#   nice -n 10 experiments/env/fkl_short_job_pair.sh BEFORE_BIN AFTER_BIN [REPS]
set -euo pipefail
cd "$(dirname "$0")/../.."
BEFORE=$(realpath "$1")
AFTER=$(realpath "$2")
REPS=${3:-2}
WORK=${WORK:-target/fkl_short_job_pair}
mkdir -p "$WORK"
"$AFTER" --task composite --print-config | sed 's/^irl_iterations = 800/irl_iterations = 10/' \
    > "$WORK/fkl10.toml"
echo "# fkl, composite, standard schedule with 10 IRL iterations; $(nproc) cores"
for rep in $(seq 1 "$REPS"); do
    for which in before after; do
        bin=$BEFORE
        [ "$which" = after ] && bin=$AFTER
        out="$WORK/${which}_$rep"
        /usr/bin/time -o "$WORK/time" -f "%e s wall, %U s user, %S s sys" \
            "$bin" --task composite --config "$WORK/fkl10.toml" --algo fkl --quiet \
            --out "$out" --force > /dev/null
        job=$(grep -A2 '"fkl"' "$out/run.json" | sed -n 's/.*"wall_secs": \([0-9.]*\).*/\1/p')
        echo "$which rep $rep: $(cat "$WORK/time"); job wall $job s; load $(cut -d' ' -f1 /proc/loadavg)"
    done
done
