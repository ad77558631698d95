"""How consistent the teacher's labels are near standing: step-to-step label changes in a distillation run's data.

``mpc`` replans every ``replan_steps`` (2) control steps and between replannings follows its plan, so a label
change at a replanning step, against one inside a plan, shows how much the newly chosen plan jumps from
one 0.02-s step to the next (near-identical states, different labels). For each run folder it reads the
shards (`frbench.training.distill_data`) and prints the mean |label_t − label_{t−1}| [rad] per joint at
replanning steps and inside plans, for *upright* steps (this and the previous step with the pelvis' projected
gravity z < −``--upright`` and mean |q − q̊| < ``--pose`` rad: standing or close) and for all others, once
over the episodes the teacher acted and once over all (DAgger labels states the student visited).
With ``--student CHECKPOINT`` it also prints that student's mean squared error [rad²] against the labels,
upright and other steps apart; for a mixture-density student (``frbench distill --student mdn``) also the
error of its component nearest to each label (*nearest component*: whether one of its K answers is the
teacher's, where the one it acts with is not) and the mean weight of the component it acts with.

Run: ``python benchmarks/distill_labels.py runs/distill-g1 runs/distill-g1-long --student
runs/distill-g1-long/checkpoints/round5.pt``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

#: o_t = [ω (3), g (3), q − q̊ (J), q̇ (J), a_{t−1} (J)] (`frbench.training.distill_data`).
GRAVITY, JOINTS = slice(3, 6), 6


def upright_steps(obs: np.ndarray, joints: int, upright: float, pose: float) -> np.ndarray:
    """Steps (T,) of o_t (T, 6 + 3·joints) with projected gravity z < −``upright`` and mean |q − q̊| < ``pose``."""
    q = obs[:, JOINTS:JOINTS + joints]
    return (obs[:, GRAVITY][:, 2] < -upright) & (np.abs(q).mean(axis=1) < pose)


def changes(obs: np.ndarray, labels: np.ndarray, upright: float, pose: float, replan_steps: int):
    """Per step t ≥ 1 of one episode: |label_t − label_{t−1}| averaged over joints [rad] (T − 1,), whether t
    is a replanning step, and whether steps t − 1 and t are both upright."""
    up = upright_steps(obs, labels.shape[1], upright, pose)
    step = np.arange(1, len(labels))
    return np.abs(np.diff(labels, axis=0)).mean(axis=1), step % replan_steps == 0, up[1:] & up[:-1]


def squared_errors(actor, data, upright: float, pose: float):
    """Per step of one shard: the student's mean squared error over joints [rad²] (T,), whether the step is
    upright (T,), and for a mixture student the error of its component nearest to the label (T,) and the weight of
    its most probable component (T,) (else NaN)."""
    import torch

    from frbench.training.distill_student import _inputs, student_actions

    obs, labels = data["obs"], data["actions"]
    up = upright_steps(obs, labels.shape[1], upright, pose)
    nearest, weight = np.full(len(labels), np.nan), np.full(len(labels), np.nan)
    if hasattr(actor, "mixture"):
        with torch.inference_mode():
            log_weights, means, _ = (x.numpy() for x in actor.mixture(_inputs(obs, data["history"])))
        nearest = ((means - labels[:, None, :]) ** 2).mean(axis=2).min(axis=1)
        weight = np.exp(log_weights.max(axis=1))
    return ((student_actions(actor, obs, data["history"]) - labels) ** 2).mean(axis=1), up, nearest, weight


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="distillation run folders")
    parser.add_argument("--upright", type=float, default=0.95, help="projected-gravity z below minus this")
    parser.add_argument("--pose", type=float, default=0.15, help="mean |q − q̊| [rad] below this")
    parser.add_argument("--replan-steps", type=int, default=2, help="the teacher's replan_steps")
    parser.add_argument("--student", type=Path, help="a mpc-distill checkpoint: its error on the labels")
    args = parser.parse_args()
    actor = None
    if args.student is not None:
        import torch

        from frbench.policies.checkpoint import read_checkpoint
        from frbench.training.distill_student import build_actor

        torch.set_num_threads(1)
        actor = build_actor(read_checkpoint(args.student))
    for run in args.runs:
        for who in ("teacher", "all"):
            rows, errors = [], []
            for path in sorted(run.glob("data/round*/*.npz")):
                with np.load(path) as data:
                    if who == "teacher" and json.loads(str(data["meta"]))["acted_by"] != "teacher":
                        continue
                    rows.append(changes(data["obs"], data["actions"], args.upright, args.pose, args.replan_steps))
                    if actor is not None:
                        errors.append(squared_errors(actor, data, args.upright, args.pose))
            change, replan, up = (np.concatenate([r[k] for r in rows]) for k in range(3))
            cells = {f"{phase} {kind}": change[m & (replan if kind == 'replanning' else ~replan)]
                     for phase, m in (("upright", up), ("other", ~up)) for kind in ("replanning", "in-plan")}
            print(f"{run} ({who} acted, {len(rows)} episodes, {int(up.sum())} upright steps): "
                  + ", ".join(f"{k} {v.mean():.3f}" for k, v in cells.items()) + " rad", flush=True)
            if errors:
                error, up, nearest, weight = (np.concatenate([e[k] for e in errors]) for k in range(4))
                line = f"  {args.student} MSE: upright {error[up].mean():.3f}, other {error[~up].mean():.3f} rad²"
                if not np.isnan(nearest).all():
                    line += (f"; nearest component: upright {nearest[up].mean():.3f}, other {nearest[~up].mean():.3f}"
                             f"; weight of the acting one: upright {weight[up].mean():.2f}, other {weight[~up].mean():.2f}")
                print(line, flush=True)


if __name__ == "__main__":
    main()
