#!/usr/bin/env bash
# A product-control job before/after, interleaved: fkl-product on Composite with the standard
# schedule cut to ITERS IRL iterations (300 SAC steps, 300 rollouts of 100 steps each) and no
# final phase, prepared once (demonstrations, learned machine) by AFTER_BIN, then run as
# `reacher job` by the two binaries in turn, REPS times. Prints each job's wall and CPU seconds
# and the machine's load, and checks every job's record (but wall_secs), reward and log
# against the first job's (the log by the listing of `reacher replay`, timing line aside: the
# log's header names the commit the binary was built from). Run directories go to $WORK
# (default target/product_job_pair).
#
#   nice -n 10 experiments/env/product_job_pair.sh BEFORE_BIN AFTER_BIN [REPS] [ITERS]
set -euo pipefail
cd "$(dirname "$0")/../.."
BEFORE=$(realpath "$1")
AFTER=$(realpath "$2")
REPS=${3:-3}
ITERS=${4:-40}
WORK=${WORK:-target/product_job_pair}
ALGO=fkl-product
mkdir -p "$WORK"
"$AFTER" --task composite --print-config \
    | sed -e "s/^irl_iterations = 800$/irl_iterations = $ITERS/" \
        -e 's/^sac_steps = 20000$/sac_steps = 0/' -e 's/^reset_steps = 20000$/reset_steps = 0/' \
        -e 's/^checkpoints = 4$/checkpoints = 0/' > "$WORK/product.toml"
rm -rf "$WORK/prepared"
"$AFTER" prepare --task composite --config "$WORK/product.toml" --algo "$ALGO" --quiet \
    --out "$WORK/prepared" > /dev/null
echo "# $ALGO, composite, standard schedule with $ITERS IRL iterations, no final phase; $(nproc) cores"
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
        for f in record.txt "rewards/$stem.bin" replay.txt; do
            cmp -s "$run/$f" "$WORK/before_1/$f" || same="DIFFERS ($f)"
        done
        echo "$which rep $rep: $(cat "$WORK/time"); load $(cut -d' ' -f1 /proc/loadavg); $same"
    done
done
