#!/usr/bin/env bash
# What the scene's region bodies cost the physics: a bare C loop (two mj_step calls per
# environment step, pseudo-random controls, no Rust) on the shipped model, on the same model
# without its mocap bodies (the four balls: labels come from the environment's own region
# positions, never from MuJoCo), and without the world's decorative geoms as well; the three
# models interleaved REPS times, medians of steps/s and of the per-repetition speed ratio.
# Prints each model's joint angles after the loop, which are equal when the removed parts
# leave the arm's trajectory unchanged, and how many steps ended with joint1 at its limit. Needs gcc, python3 and libmujoco-dev.
#
#   experiments/env/mocap_cost.sh [STEPS] [REPS]
set -euo pipefail
cd "$(dirname "$0")/../.."
STEPS=${1:-20000}
REPS=${2:-7}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
python3 - assets/reacher_delivery.xml "$WORK" <<'PY'
import sys, xml.etree.ElementTree as ET
src, out = sys.argv[1], sys.argv[2]
tree = ET.parse(src)
world = tree.getroot().find("worldbody")
for body in [b for b in world.findall("body") if b.get("mocap") == "true"]:
    world.remove(body)
tree.write(f"{out}/no_mocap.xml")
for geom in world.findall("geom"):
    world.remove(geom)
tree.write(f"{out}/arm_only.xml")
PY
cat > "$WORK/loop.c" <<'C'
#include <mujoco/mujoco.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
static int cmp(const void *a, const void *b) { double x = *(const double *)a, y = *(const double *)b; return (x > y) - (x < y); }
int main(int argc, char **argv) {
    int steps = atoi(argv[1]), reps = atoi(argv[2]), n = argc - 3;
    mjModel *m[3]; mjData *d[3]; char err[1000];
    double secs[3][64], v[64];
    for (int i = 0; i < n; i++) {
        m[i] = mj_loadXML(argv[3 + i], 0, err, sizeof err);
        if (!m[i]) { fprintf(stderr, "%s: %s\n", argv[3 + i], err); return 1; }
        d[i] = mj_makeData(m[i]);
    }
    for (int r = 0; r < reps; r++)
        for (int i = 0; i < n; i++) {
            mj_resetData(m[i], d[i]);
            unsigned s = 12345;
            long limit_steps = 0;
            double t0 = now();
            for (int k = 0; k < steps; k++) {
                for (int a = 0; a < 2; a++) { s = s * 1103515245u + 12345u; d[i]->ctrl[a] = ((s >> 8) % 2001) / 1000.0 - 1.0; }
                mj_step(m[i], d[i]);
                mj_step(m[i], d[i]);
                limit_steps += d[i]->nefc > 0;
            }
            secs[i][r] = now() - t0;
            if (r == 0)
                printf("%-14s nbody %d ngeom %d; joint angles after the loop %.17g %.17g; %ld steps at joint1's limit\n",
                       argv[3 + i], m[i]->nbody, m[i]->ngeom, d[i]->qpos[0], d[i]->qpos[1], limit_steps);
        }
    for (int i = 0; i < n; i++) {
        for (int r = 0; r < reps; r++) v[r] = steps / secs[i][r];
        qsort(v, reps, sizeof v[0], cmp);
        printf("%-14s %8.0f steps/s (median of %d)\n", argv[3 + i], v[reps / 2], reps);
    }
    for (int i = 1; i < n; i++) {
        for (int r = 0; r < reps; r++) v[r] = secs[0][r] / secs[i][r];
        qsort(v, reps, sizeof v[0], cmp);
        printf("speed %s / %s: %.3f (median of per-repetition ratios)\n", argv[3 + i], argv[3], v[reps / 2]);
    }
    return 0;
}
C
gcc -O2 "$WORK/loop.c" -o "$WORK/loop" -lmujoco -lm
cp assets/reacher_delivery.xml "$WORK/shipped.xml"
echo "# $STEPS environment steps (2 mj_step each) x $REPS repetitions; $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg)"
cd "$WORK" && ./loop "$STEPS" "$REPS" shipped.xml no_mocap.xml arm_only.xml
