#!/usr/bin/env bash
# Does a longer LRM search change SMIRL's learned machines? For each task and base seed, the
# machine learned by `reacher prepare` (demonstrations and LRM only, no IRL) with the standard
# config and with a stronger search (lrm_steps = 1000, lrm_starts = 32, lrm_patience = 50;
# the standard: 100 steps, the learner's 4 starts and patience 5). Prints a markdown table:
# learned states, LRM cost (and the perfect machine's on the same traces), whether the machine
# refines the perfect one along the demonstrations (ambiguous steps), whether the stronger
# search's machine is the standard's, and which perfect states each learned state was seen
# with (`rm/report.txt`). Nothing here reads an IRL result.
# Usage: experiments/reacher/lrm_search.sh ["TASKS"] ["BASES"]
#   defaults: all four tasks, base seeds 0 3 6 9 (figure 7's and the held-out ones)
#   STANDARD=<config> (default experiments/reacher/config.toml): the search it is compared with
#   STRONG_STEPS, STRONG_STARTS, STRONG_PATIENCE (default 1000, 32, 50): the stronger search,
#   or STRONG_CONFIG=<config>: a config of its own (rows "strong" are then that config's)
#   CHANGED_ONLY=1: print only the bases whose two machines differ (the count of every base
#   and of those is printed last either way)
#   REACHER_BIN=<binary>; the prepared directories go to a temporary directory this script
#   creates and removes.
set -euo pipefail
cd "$(dirname "$0")/../.."
TASKS=${1:-or sequential if composite}
BASES=${2:-0 3 6 9}
if [ -z "${REACHER_BIN:-}" ]; then cargo build --release --bin reacher >&2; fi
BIN=${REACHER_BIN:-./target/release/reacher}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
STANDARD=${STANDARD:-experiments/reacher/config.toml}
STRONG=$TMP/strong.toml
if [ -n "${STRONG_CONFIG:-}" ]; then
  cp "$STRONG_CONFIG" "$STRONG"
  strong_name="\`$STRONG_CONFIG\`"
else
  STRONG_STEPS=${STRONG_STEPS:-1000}
  STRONG_STARTS=${STRONG_STARTS:-32}
  STRONG_PATIENCE=${STRONG_PATIENCE:-50}
  grep -q '^lrm_steps = 100$' "$STANDARD"
  sed "s/^lrm_steps = 100\$/lrm_steps = $STRONG_STEPS\nlrm_starts = $STRONG_STARTS\nlrm_patience = $STRONG_PATIENCE/" "$STANDARD" > "$STRONG"
  strong_name="a stronger search ($STRONG_STEPS steps, $STRONG_STARTS starts, patience $STRONG_PATIENCE)"
fi
echo "LRM's search, \`$STANDARD\` against $strong_name (\`experiments/reacher/lrm_search.sh\`, tasks \"$TASKS\", bases \"$BASES\")."
echo
echo "| task | base seed | search | learned states | LRM cost (perfect machine's) | refines (ambiguous steps) | same machine | perfect states per learned state |"
echo "|---|---|---|---|---|---|---|---|"
declare -A bases_of changed_of
for task in $TASKS; do
  for base in $BASES; do
    rows=""
    for search in standard strong; do
      cfg=$STANDARD
      [ "$search" = strong ] && cfg=$STRONG
      out=$TMP/$task-$base-$search
      "$BIN" prepare --task "$task" --algo smirl --seed "$base" --seeds 1 --config "$cfg" \
        --out "$out" > /dev/null
      report=$out/rm/report.txt
      states=$(sed -n 's/^learned machine: \([0-9]*\) states.*/\1/p' "$report")
      cost=$(sed -n 's/^LRM cost \([0-9.]*\) (the perfect machine.s on the same traces: \([0-9.]*\)).*/\1 (\2)/p' "$report")
      refines=$(sed -n 's/^refines the perfect machine along the [0-9]* demonstrations: \([a-z]*\) (\([0-9]*\) of.*/\1 (\2)/p' "$report")
      same=-
      if [ "$search" = strong ]; then
        if cmp -s "$out/rm/learned.txt" "$TMP/$task-$base-standard/rm/learned.txt"; then same=yes; else same=no; fi
      fi
      seen=$(sed -n 's/^learned state \([0-9]*\) seen with perfect states \(.*\)/\1: \2/p' "$report" | paste -sd ';' - | sed 's/;/; /g')
      rows+="| $task | $base | $search | $states | $cost | $refines | $same | $seen |"$'\n'
    done
    bases_of[$task]=$(( ${bases_of[$task]:-0} + 1 ))
    [ "$same" = no ] && changed_of[$task]=$(( ${changed_of[$task]:-0} + 1 ))
    if [ -z "${CHANGED_ONLY:-}" ] || [ "$same" = no ]; then printf '%s' "$rows"; fi
  done
done
echo
summary=""
for task in $TASKS; do
  summary+="${summary:+; }$task ${changed_of[$task]:-0} of ${bases_of[$task]}"
done
echo "Bases whose machine differs: $summary."
