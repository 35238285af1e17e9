#!/usr/bin/env python3
"""Per IRL iteration of one job of a conditional task (IF, Composite): how many episodes of each
branch succeeded, for the stochastic rollouts of the reward update ("agent") and for the
mean-action evaluation ("eval"), read from the job's rollout log; with the first failed
normal-branch episode's labels (`r@8` = red touched on step 8). A branch is "cancel" when the
cancel event fired before blue was first touched. Needs every episode logged for per-iteration
counts (`log_every_nth_episode = 1`; `diagnose_composite_seed1.sh`) and `pip install mcap`.
Usage: python3 experiments/reacher/branches_per_iteration.py LOG.mcap"""
import os
import sys

from mcap.reader import make_reader

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "controls"))
from where_agents_end import fields  # noqa: E402 (the protobuf field reader)

# Field numbers of smirl.v1.EpisodeStart / Step / EpisodeEnd (src/log/schema.rs).
EPISODE, PHASE, LABEL_TEXT, SUCCESS = 1, 3, 6, 7


def branch(labels):
    first_cancel = next((i for i, l in enumerate(labels) if "c" in l), None)
    first_blue = next((i for i, l in enumerate(labels) if "b" in l), None)
    fired_first = first_cancel is not None and (first_blue is None or first_cancel < first_blue)
    return "cancel" if fired_first else "normal"


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    episodes, order = {}, []
    with open(sys.argv[1], "rb") as f:
        topics = ["/episode/start", "/step", "/episode/end"]
        for _, channel, message in make_reader(f).iter_messages(topics=topics):
            fl = fields(message.data)
            ep = fl.get(EPISODE, [0])[0]
            if channel.topic == "/episode/start":
                episodes[ep] = {"phase": fl.get(PHASE, [b""])[0].decode(), "labels": [], "success": 0}
                order.append(ep)
            elif channel.topic == "/step":
                episodes[ep]["labels"].append(fl.get(LABEL_TEXT, [b""])[0].decode())
            else:
                episodes[ep]["success"] = fl.get(SUCCESS, [0])[0]
    # Consecutive episodes of one phase form a block; the log holds, per IRL iteration k, SAC's
    # training episodes, then the rollouts of iteration k ("agent"), then its evaluation.
    blocks = []
    for ep in order:
        e = episodes[ep]
        if not blocks or blocks[-1][0] != e["phase"]:
            blocks.append((e["phase"], []))
        blocks[-1][1].append(e)
    iteration = 1
    print("iteration phase    normal  cancel  first failed normal episode")
    for phase, block in blocks:
        if phase not in ("agent", "eval"):
            continue
        counts = []
        for b in ("normal", "cancel"):
            s = [e["success"] for e in block if branch(e["labels"]) == b]
            counts.append(f"{sum(s):>2}/{len(s):<3}")
        failed = [e["labels"] for e in block if branch(e["labels"]) == "normal" and not e["success"]]
        shown = " ".join(f"{l}@{i}" for i, l in enumerate(failed[0]) if l)[:70] if failed else ""
        print(f"{iteration:>9} {phase:6s} {counts[0]:>7} {counts[1]:>7}  {shown}")
        if phase == "eval":
            iteration += 1


if __name__ == "__main__":
    main()
