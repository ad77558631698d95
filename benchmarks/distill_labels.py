"""How consistent the teacher's labels are near standing: step-to-step label changes in a distillation run's data.

``mpc`` replans every ``replan_steps`` (2) control steps and between replannings follows its plan, so a label
change at a replanning step, against one inside a plan, shows how much the newly chosen plan jumps from
one 0.02-s step to the next (near-identical states, different labels). For each run folder it reads the
shards (`frbench.training.distill_data`) and prints the mean |label_t − label_{t−1}| [rad] per joint at
replanning steps and inside plans, for *upright* steps (this and the previous step with the pelvis' projected
gravity z < −``--upright`` and mean |q − q̊| < ``--pose`` rad: standing or close) and for all others, once
over the episodes the teacher acted and once over all (DAgger labels states the student visited).

Run: ``python benchmarks/distill_labels.py runs/distill-g1 runs/distill-g1-long``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

#: o_t = [ω (3), g (3), q − q̊ (J), q̇ (J), a_{t−1} (J)] (`frbench.training.distill_data`).
GRAVITY, JOINTS = slice(3, 6), 6


def changes(obs: np.ndarray, labels: np.ndarray, upright: float, pose: float, replan_steps: int):
    """Per step t ≥ 1 of one episode: |label_t − label_{t−1}| averaged over joints [rad] (T − 1,), whether t
    is a replanning step, and whether steps t − 1 and t are both upright."""
    joints = labels.shape[1]
    q = obs[:, JOINTS:JOINTS + joints]
    up = (obs[:, GRAVITY][:, 2] < -upright) & (np.abs(q).mean(axis=1) < pose)
    step = np.arange(1, len(labels))
    return np.abs(np.diff(labels, axis=0)).mean(axis=1), step % replan_steps == 0, up[1:] & up[:-1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="distillation run folders")
    parser.add_argument("--upright", type=float, default=0.95, help="projected-gravity z below minus this")
    parser.add_argument("--pose", type=float, default=0.15, help="mean |q − q̊| [rad] below this")
    parser.add_argument("--replan-steps", type=int, default=2, help="the teacher's replan_steps")
    args = parser.parse_args()
    for run in args.runs:
        for who in ("teacher", "all"):
            rows = []
            for path in sorted(run.glob("data/round*/*.npz")):
                with np.load(path) as data:
                    if who == "teacher" and json.loads(str(data["meta"]))["acted_by"] != "teacher":
                        continue
                    rows.append(changes(data["obs"], data["actions"], args.upright, args.pose, args.replan_steps))
            change, replan, up = (np.concatenate([r[k] for r in rows]) for k in range(3))
            cells = {f"{phase} {kind}": change[m & (replan if kind == 'replanning' else ~replan)]
                     for phase, m in (("upright", up), ("other", ~up)) for kind in ("replanning", "in-plan")}
            print(f"{run} ({who} acted, {len(rows)} episodes, {int(up.sum())} upright steps): "
                  + ", ".join(f"{k} {v.mean():.3f}" for k, v in cells.items()) + " rad", flush=True)


if __name__ == "__main__":
    main()
