#!/usr/bin/env python3
"""SMIRL's settings (issue 13): `smirl` per task under each setting tried, and the standard
profile on held-out demonstrations. Per run: the final ground-truth success of each SAC seed
(IF and Composite: the lower branch; the branches as normal/cancel), the mean success over the
last quarter of the IRL iterations per seed, and how many seeds end at >= 0.9; for the runs with
a final-policy phase (final_policy.csv) the reported policy's success per seed instead, with
the candidate reported (0 = the co-trained policy). Numbers from the runs' metrics and
final-policy tables (rundata.py: the run directory on disk, else the committed consolidated
rows). Markdown on standard output.

Usage: python3 experiments/reacher/smirl_settings.py"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import rundata  # noqa: E402

TASKS = ["or", "sequential", "if", "composite"]
# (setting, what it is, run directory pattern relative to experiments/reacher)
TUNING = [
    ("before", "config_unshaped.toml: 20 IRL iterations, no shaping", "runs/{task}-schedules"),
    ("shaping_crm", "+ smirl_shaping = 1.0", "ablations/runs/shaping_crm-{task}"),
    ("shaping_2", "+ smirl_shaping = 2.0", "ablations/runs/shaping_2-{task}"),
    ("label_entries", "+ smirl_label_features = \"entries\"", "ablations/runs/label_entries-{task}"),
    ("standard", "config.toml: 30 IRL iterations, smirl_shaping = 1.0", "runs/{task}-shaped"),
    ("shaped_lr_decay", "+ reward_lr_decay = 0.5", "ablations/runs/shaped_lr_decay-{task}"),
    ("remember_events", "+ lrm_remember_events = true (its IRL loop; the final policy below)",
     "ablations/runs/remember_events-{task}"),
    ("standard, SAC seeds 3-5", "config.toml, SAC seeds 3, 4, 5 (its IRL loop; the final policy below)",
     "ablations/runs/standard-seeds3to5-{task}"),
    ("remember + borrow_events, SAC seeds 3-5",
     "ablations/borrow_events.toml, SAC seeds 3, 4, 5 (its IRL loop; the final policy below)",
     "ablations/runs/borrow_events-seeds3to5-{task}"),
]
# The standard profile with its final-policy phase (smirl_final_sac_steps = 20 000 in 4
# checkpoints): the same IRL loops as "standard", then the reported policy.
FINAL_TUNING = [
    ("final policy", "config.toml + smirl_final_sac_steps = 20000, 4 checkpoints",
     "runs/{task}-final"),
    ("remember_events, final policy", "final policy + lrm_remember_events = true",
     "ablations/runs/remember_events-{task}"),
    # More tuning seeds (SAC seeds 3-5 on base 0's demonstrations and machines), for the
    # decision between the standard and memory + borrowing fixed before these runs (README,
    # "Borrowing the cancel").
    ("final policy, SAC seeds 3-5", "config.toml, SAC seeds 3, 4, 5",
     "ablations/runs/standard-seeds3to5-{task}"),
    ("remember + borrow_events, final policy, SAC seeds 3-5",
     "ablations/borrow_events.toml, SAC seeds 3, 4, 5",
     "ablations/runs/borrow_events-seeds3to5-{task}"),
    # Stratified demonstrations (ablations/stratified_demos.toml), SAC seeds 0-5 on base 0 under
    # the rule fixed in commit 496ffef before the runs (README, "Stratified demonstrations");
    # IF and Composite only.
    ("stratified demonstrations, final policy, SAC seeds 0-5",
     "ablations/stratified_demos.toml, SAC seeds 0-5",
     "ablations/runs/stratified-seeds0to5-{task}"),
    # Event stutter (ablations/event_stutter.toml, the standard since), SAC seeds 0-5 on base 0
    # under the rule in that file, fixed in commit 0e183fa before the runs (README, "Event
    # stutter"); Composite only (no other task's machine changes).
    ("event stutter, final policy, SAC seeds 0-5",
     "ablations/event_stutter.toml, SAC seeds 0-5",
     "ablations/runs/event_stutter-seeds0to5-{task}"),
    # Shared visits and event-gated visits (ablations/shared_visits.toml, event_gated_visits.toml),
    # SAC seeds 0-5 on base 0 under the rules in those files, fixed in commits 05af371 and
    # a3f9f04 before their runs (README, "Shared visits"); shared visits stopped after IF and
    # Composite had vetoed it.
    ("shared visits, final policy, SAC seeds 0-5",
     "ablations/shared_visits.toml, SAC seeds 0-5",
     "ablations/runs/shared_visits-seeds0to5-{task}"),
    ("event-gated visits, final policy, SAC seeds 0-5",
     "ablations/event_gated_visits.toml, SAC seeds 0-5",
     "ablations/runs/event_gated_visits-seeds0to5-{task}"),
    # Unpredicted events (ablations/unpredicted_events.toml: LRM not asked to predict the
    # cancel), SAC seeds 0-5 on base 0 under the rule in that file, fixed in commit d6fce19
    # before the runs (README, "Not predicting the cancel").
    ("unpredicted events, final policy, SAC seeds 0-5",
     "ablations/unpredicted_events.toml, SAC seeds 0-5",
     "ablations/runs/unpredicted_events-seeds0to5-{task}"),
    # Commuted events (ablations/commute_events.toml), SAC seeds 0-5 on base 0 under the rule in
    # that file, fixed in commit c0efbd2 before the runs (README, "Commuted events"); Composite
    # only (no other task's base-0 machine changes).
    ("commuted events, final policy, SAC seeds 0-5",
     "ablations/commute_events.toml, SAC seeds 0-5",
     "ablations/runs/commute_events-seeds0to5-{task}"),
    # Replay 200 000 (ablations/replay_all.toml), SAC seeds 0-5 on base 0 under the rule in that
    # file, fixed in commit 9f96a09 before the runs (README, "Why agents forget").
    ("replay 200 000, final policy, SAC seeds 0-5",
     "ablations/replay_all.toml, SAC seeds 0-5",
     "ablations/runs/replay_all-seeds0to5-{task}"),
    # The sink of unseen touches (ablations/unseen_touch_sink.toml), SAC seeds 0-5 on base 0 under
    # the rule in that file, fixed in commit e6b4f49 before the runs (README, "A sink for touches
    # the demonstrations never make").
    ("sink of unseen touches, final policy, SAC seeds 0-5",
     "ablations/unseen_touch_sink.toml, SAC seeds 0-5",
     "ablations/runs/unseen_touch_sink-seeds0to5-{task}"),
    # Entered only after the cancel (ablations/sink_after_events.toml), rule fixed in commit
    # 5f6ea58 before the runs; Composite only (no other task's base-0 machine changes).
    ("sink after events, final policy, SAC seeds 0-5",
     "ablations/sink_after_events.toml, SAC seeds 0-5",
     "ablations/runs/sink_after_events-seeds0to5-{task}"),
    # LRM's fallback starts (ablations/fallback_starts.toml, the standard since), rule fixed in
    # commit 1a8d645 before the runs; Sequential only (no other task's base-0 machine changes).
    ("fallback starts, final policy, SAC seeds 0-5",
     "ablations/fallback_starts.toml, SAC seeds 0-5",
     "ablations/runs/fallback_starts-seeds0to5-{task}"),
    # Initial events (ablations/initial_events.toml), rule fixed in commit 06902f7 before the
    # runs; Sequential only (no other task's base-0 machine changes).
    ("initial events, final policy, SAC seeds 0-5",
     "ablations/initial_events.toml, SAC seeds 0-5",
     "ablations/runs/initial_events-seeds0to5-{task}"),
]
HELDOUT = [
    ("base 3", "heldout/shaped-{task}"),
    ("base 6", "heldout/shaped-seeds6-{task}"),
    ("base 9", "heldout/shaped-seeds9-{task}"),
    # Base 12 was run only with the final-policy phase; its IRL loops give the co-trained row.
    ("base 12", "heldout/final-seeds12-{task}"),
    # Base 15: run after borrow_events was built, on seeds no setting had seen.
    ("base 15", "heldout/final-seeds15-{task}"),
    # Bases 18 and 21: run after the standard was confirmed on tuning seeds 0-5.
    ("base 18", "heldout/final-seeds18-{task}"),
    ("base 21", "heldout/final-seeds21-{task}"),
    # Bases 24 and 27: run after the cancel probe's prediction for them was committed (16473b8).
    ("base 24", "heldout/final-seeds24-{task}"),
    ("base 27", "heldout/final-seeds27-{task}"),
    # Bases 30 and 33, run after event stutter's rule was fixed: the previous standard (config.toml
    # without lrm_event_stutter), every task; event stutter changes only Composite's machines and
    # IF 33's there (its rows below), so the others are the new standard's jobs too.
    ("base 30, previous standard", "heldout/final-seeds30-{task}"),
    ("base 33, previous standard", "heldout/final-seeds33-{task}"),
    ("base 3, remember_events", "heldout/remember-{task}"),
    ("base 6, remember_events", "heldout/remember-seeds6-{task}"),
    ("base 9, remember_events", "heldout/remember-seeds9-{task}"),
    ("base 12, remember_events", "heldout/remember-seeds12-{task}"),
]
FINAL_HELDOUT = [
    ("base 3, final policy", "heldout/final-{task}"),
    ("base 6, final policy", "heldout/final-seeds6-{task}"),
    ("base 9, final policy", "heldout/final-seeds9-{task}"),
    ("base 12, final policy", "heldout/final-seeds12-{task}"),
    ("base 15, final policy", "heldout/final-seeds15-{task}"),
    ("base 18, final policy", "heldout/final-seeds18-{task}"),
    ("base 21, final policy", "heldout/final-seeds21-{task}"),
    ("base 24, final policy", "heldout/final-seeds24-{task}"),
    ("base 27, final policy", "heldout/final-seeds27-{task}"),
    ("base 30, previous standard, final policy", "heldout/final-seeds30-{task}"),
    ("base 33, previous standard, final policy", "heldout/final-seeds33-{task}"),
    ("base 3, remember_events, final policy", "heldout/remember-{task}"),
    ("base 6, remember_events, final policy", "heldout/remember-seeds6-{task}"),
    ("base 9, remember_events, final policy", "heldout/remember-seeds9-{task}"),
    ("base 12, remember_events, final policy", "heldout/remember-seeds12-{task}"),
    # remember_events + borrow_events (ablations/borrow_events.toml). At bases 3-12 only the
    # machines that borrowing changes were rerun (IF at bases 9 and 12); elsewhere the machine,
    # and so every job, is remember_events' (README). Base 15: every task; base 18: IF.
    ("base 3, remember + borrow_events, final policy", "heldout/borrow-{task}"),
    ("base 6, remember + borrow_events, final policy", "heldout/borrow-seeds6-{task}"),
    ("base 9, remember + borrow_events, final policy", "heldout/borrow-seeds9-{task}"),
    ("base 12, remember + borrow_events, final policy", "heldout/borrow-seeds12-{task}"),
    ("base 15, remember + borrow_events, final policy", "heldout/borrow-seeds15-{task}"),
    ("base 18, remember + borrow_events, final policy", "heldout/borrow-seeds18-{task}"),
    # borrow_events alone (ablations/borrow_only.toml): only where it changes the standard
    # machine (IF at bases 9, 12 and 18, Sequential at 12; of base 15's none); elsewhere the jobs
    # are the standard's.
    ("base 9, borrow_events alone, final policy", "heldout/borrow-only-seeds9-{task}"),
    ("base 12, borrow_events alone, final policy", "heldout/borrow-only-seeds12-{task}"),
    ("base 18, borrow_events alone, final policy", "heldout/borrow-only-seeds18-{task}"),
    # Stratified demonstrations (ablations/stratified_demos.toml): IF and Composite at every base.
] + [(f"base {b}, stratified demonstrations, final policy", f"heldout/stratified-seeds{b}-{{task}}")
     for b in (3, 6, 9, 12, 15, 18, 21)] + [
    # Event stutter (ablations/event_stutter.toml, the standard since): Composite at every base
    # where it changes the machine (all but 18, whose jobs are the previous standard's), and IF
    # at 33 (the only other machine it changes at bases 0-33).
    (f"base {b}, event stutter, final policy", f"heldout/event-stutter-seeds{b}-{{task}}")
    for b in (3, 6, 9, 12, 15, 21, 24, 27, 30, 33)] + [
    # Shared visits (ablations/shared_visits.toml): Composite at bases 3 and 6 only (stopped
    # once its tuning rule had failed). Event-gated visits (ablations/event_gated_visits.toml,
    # the standard since): every task at every base 3-33; IF and Composite at 36-45 and OR and
    # Sequential at 36-42 were run after the whole study (bases never looked at before).
    (f"base {b}, shared visits, final policy", f"heldout/shared-visits-seeds{b}-{{task}}")
    for b in (3, 6)] + [
    (f"base {b}, event-gated visits, final policy", f"heldout/event-gated-seeds{b}-{{task}}")
    for b in range(3, 46, 3)] + [
    # The task's own machine (smirl_machine = "task", smirl_sweep.sh MACHINE=task): an oracle
    # for diagnosis, not a setting to choose — OR at its half-plateau bases, IF and Composite
    # at their cancel-hole bases, Sequential at its unrefined-machine bases.
    (f"base {b}, task machine (oracle), final policy", f"heldout/task-machine-seeds{b}-{{task}}")
    for b in (6, 9, 12, 18, 21, 30, 33)] + [
    # Unpredicted events (ablations/unpredicted_events.toml, the standard since) at the bases
    # run last, 36-45, every task; then Composite at 3 and 6, the old hole bases (IF 12,
    # Composite 18), the fresh bases whose machines have cancel holes (IF 69, 72, Composite 69,
    # 93: probed before any job ran there; IF 93, the same kind, run after them) and Composite 54
    # (no hole; commuted events change its machine).
    (f"base {b}, unpredicted events, final policy", f"heldout/unpredicted-seeds{b}-{{task}}")
    for b in (3, 6, 12, 18, 36, 39, 42, 45, 54, 69, 72, 93)] + [
    # Commuted events (ablations/commute_events.toml, the standard since): the hole bases, old
    # (IF 12, Composite 18 and 36) and fresh (IF 69, 72, 93, Composite 69, 93), and Composite 54;
    # then the held-out bases whose machines it changes (Composite 9, 12, 21, 30, 33, 45;
    # Sequential 42, OR 45), Composite's other bases without a job of the standard (15, 24, 27)
    # and IF 3 (standard_heldout.py).
    (f"base {b}, commuted events, final policy", f"heldout/commute-seeds{b}-{{task}}")
    for b in (3, 9, 12, 15, 18, 21, 24, 27, 30, 33, 36, 42, 45, 54, 69, 72, 93)] + [
    # The fresh agent (ablations/fresh_agent.toml): Composite 30, a held-out miss of the standard.
    (f"base {b}, fresh agent, final policy", f"heldout/fresh-agent-seeds{b}-{{task}}")
    for b in (30,)] + [
    # Replay 200 000 (ablations/replay_all.toml, the standard since): Composite at the held-out
    # bases with misses under the previous standard (3, 27, 30, 36, 39), then bases it solved
    # (Composite 9, 12, 15 and 33, IF 36 and 39) and Sequential 42 (1 of 3 under it); then
    # (stop 40) every other held-out base of the previous standard, every task run there; then
    # (stop 41) fresh bases no run had used, IF and Composite: every third from 75 to 105 but 93.
    (f"base {b}, replay 200 000, final policy", f"heldout/replay-all-seeds{b}-{{task}}")
    for b in (3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 33, 36, 39, 42, 45, 54, 69, 72, 75, 78, 81,
              84, 87, 90, 93, 96, 99, 102, 105, 153, 219, 246, 282, 372, 546, 549)] + [
    # LRM's fallback starts (ablations/fallback_starts.toml, the standard since): the previous
    # standard's held-out bases whose machine it changes, then fresh bases where it changes it
    # (lrm_fallback.md, lrm_fallback_303to600.md), the replay-all jobs beside them.
    (f"base {b}, fallback starts, final policy", f"heldout/fallback-starts-seeds{b}-{{task}}")
    for b in (6, 39, 78, 84, 96, 99, 105, 153, 219, 246, 282, 372, 546, 549)] + [
    # Initial events (ablations/initial_events.toml): IF 81 and Composite 282, the machines with
    # first-step cancel holes, then the held-out Composite bases whose machine it changes.
    (f"base {b}, initial events, final policy", f"heldout/initial-events-seeds{b}-{{task}}")
    for b in (15, 39, 81, 102, 282)] + [
    # The sink of unseen touches (ablations/unseen_touch_sink.toml): IF 42 only (stopped once
    # its tuning rule had failed); entered only after the cancel (ablations/sink_after_events.toml):
    # the standard's misses whose machines it changes, then fresh bases where it changes them
    # (ablation_heldout.py).
    (f"base {b}, sink of unseen touches, final policy", f"heldout/unseen-sink-seeds{b}-{{task}}")
    for b in (42,)] + [
    (f"base {b}, sink after events, final policy", f"heldout/sink-after-events-seeds{b}-{{task}}")
    for b in (3, 27, 30, 42, 90, 99, 102, 105)]


def jobs(run):
    """{seed: rows in iteration order} of `smirl` in the run, or None when there is no run."""
    try:
        rows = rundata.metrics(os.path.join(HERE, run))
    except FileNotFoundError:
        return None
    out = {}
    for r in rows:
        if r["algo"] == "smirl":
            out.setdefault(int(r["seed"]), []).append(r)
    for seed in out:
        out[seed].sort(key=lambda r: int(r["iteration"]))
    return out or None


def cell(run):
    j = jobs(run)
    if j is None:
        return "not run"
    quarters = ", ".join(f"{rundata.last_quarter(j[seed]):.2f}" for seed in sorted(j))
    return seeds_text([j[seed][-1] for seed in sorted(j)], f"last quarter {quarters}")


def final_cell(run):
    j = {seed: c for (algo, seed), c in rundata.final_policy(os.path.join(HERE, run)).items()
         if algo == "smirl"}
    if not j:
        return "not run"
    picked = [rundata.chosen(j[seed]) for seed in sorted(j)]
    return seeds_text(picked, "candidate " + ", ".join(c["candidate"] for c in picked))


def seeds_text(results, note):
    """Per seed the success (and branches) of one metrics or final_policy row, a note, and how
    many seeds reach 0.9."""
    finals = [float(r["success_rate"]) for r in results]
    text = ", ".join(f"{f:.2f}" for f in finals)
    if results and results[0].get("success_normal"):
        text += " (" + ", ".join(f"{float(r['success_normal']):.2f}/{float(r['success_cancel']):.2f}"
                                 for r in results) + ")"
    good = sum(f >= 0.9 for f in finals)
    return f"{text}; {note}; **{good}/{len(finals)}**"


def main():
    print("Per cell: final success per seed (IF, Composite: normal/cancel in brackets); mean")
    print("success over the last quarter of the iterations per seed; seeds ending at >= 0.9.\n")
    print("**Tuning seeds** (base seed 0: figure 7's demonstrations and machines; SAC seeds 0, 1, 2")
    print("unless the row says otherwise)\n")
    print("| setting | what | " + " | ".join(TASKS) + " |")
    print("|---|---|" + "---|" * len(TASKS))
    for name, what, pattern in TUNING:
        cells = [cell(pattern.format(task=t)) for t in TASKS]
        print(f"| {name} | {what} | " + " | ".join(cells) + " |")
    for name, what, pattern in FINAL_TUNING:
        cells = [final_cell(pattern.format(task=t)) for t in TASKS]
        print(f"| {name} | {what} | " + " | ".join(cells) + " |")
    print("\n**Held out** (the standard profile; new demonstrations and learned machines from base")
    print("seed B, SAC seeds B, B+1, B+2)\n")
    print("| base seed | " + " | ".join(TASKS) + " |")
    print("|---|" + "---|" * len(TASKS))
    for name, pattern in HELDOUT:
        print(f"| {name} | " + " | ".join(cell(pattern.format(task=t)) for t in TASKS) + " |")
    for name, pattern in FINAL_HELDOUT:
        print(f"| {name} | " + " | ".join(final_cell(pattern.format(task=t)) for t in TASKS) + " |")


if __name__ == "__main__":
    main()
