"""``frbench distill``: DAgger of the ``mpc`` planner into a proprioceptive MLP policy (resumable)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``distill`` to the CLI."""
    p = sub.add_parser("distill", help="distil the mpc planner into a proprioceptive policy (DAgger, resumable)",
                       description="Round 0: behaviour cloning (the teacher acts); rounds >= 1: DAgger (the student "
                                   "acts, the teacher labels every visited state). Rerun the same command to resume. "
                                   "docs/planning.md describes it.")
    p.add_argument("--teacher", default="mpc", help="the planner to imitate (mpc)")
    p.add_argument("--teacher-settings", default="", metavar="FIELD=VALUE,...",
                   help="the teacher's planner settings, $FRBENCH_MPC syntax (default: its defaults)")
    p.add_argument("--robot", default="g1")
    p.add_argument("--terrain", default="flat", help="terrain family of the starts")
    p.add_argument("--level", type=int, default=1)
    p.add_argument("--simulators", default="mujoco,pybullet", help="acting simulators, alternated per batch")
    p.add_argument("--out", type=Path, required=True, help="run folder (resumed when it exists; the training "
                   "settings and --rounds may change, the data settings may not)")
    p.add_argument("--rounds", type=int, default=3, help="round 0 behaviour cloning, then DAgger rounds")
    p.add_argument("--episodes-per-round", type=int, default=32)
    p.add_argument("--batch", type=int, default=2, help="episodes run side by side in one simulator")
    p.add_argument("--steps", type=int, default=250, help="control steps per episode (0.02 s each)")
    p.add_argument("--start-seed", type=int, default=1000,
                   help="start seed of round r, batch b: START_SEED + 1000·r + b (keep it away from evaluation seeds)")
    p.add_argument("--beta", type=float, default=0.0, help="DAgger rounds: fraction of episodes the teacher acts")
    p.add_argument("--frames", type=int, default=3, help="observation history frames of the student")
    p.add_argument("--hidden", default="256,256,128", help="the student MLP's hidden widths")
    p.add_argument("--epochs", type=int, default=30, help="training passes over the data per round")
    p.add_argument("--input-noise", type=float, default=0.0,
                   help="training input noise, a fraction of each input's spread (default 0)")
    p.add_argument("--weight-decay", type=float, default=0.0, help="AdamW weight decay (default 0)")
    p.add_argument("--extra-data", default="", metavar="RUN,...",
                   help="run folders of earlier distillations whose data, all rounds, join the training set "
                        "(a training setting)")
    p.add_argument("--student", default="mse", choices=("mse", "mdn"),
                   help="mse: an MLP trained by MSE (default); mdn: a mixture density network trained by negative "
                        "log-likelihood, acting with its most probable component's mean (a training setting)")
    p.add_argument("--components", type=int, default=5, help="the mdn student's Gaussian components (default 5)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=1, help="processes running batches")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run or resume the distillation; print the progress per batch and round."""
    from frbench.errors import FrbenchError
    from frbench.robots import get_robot
    from frbench.training.distill import DistillConfig, run_distillation

    get_robot(args.robot)  # an unknown robot: a one-line error before anything runs
    simulators = tuple(s.strip() for s in args.simulators.split(",") if s.strip())
    unknown = [s for s in simulators if s not in ("mujoco", "pybullet")]
    if unknown:
        raise FrbenchError(f"--simulators: unknown simulator {unknown[0]!r} (expected mujoco, pybullet)")
    try:
        hidden = tuple(int(w) for w in args.hidden.split(","))
    except ValueError:
        raise FrbenchError(f"--hidden {args.hidden!r}: expected comma-separated integers") from None
    from frbench.policies.mpc import config_from_text

    config_from_text(args.teacher_settings)  # malformed settings: a one-line error now
    config = DistillConfig(teacher=args.teacher, teacher_settings=args.teacher_settings, robot=args.robot,
                           terrain=args.terrain, level=args.level, simulators=simulators, rounds=args.rounds,
                           episodes_per_round=args.episodes_per_round, batch=args.batch, steps=args.steps,
                           start_seed=args.start_seed,
                           beta=args.beta, frames=args.frames, hidden=hidden, epochs=args.epochs,
                           input_noise=args.input_noise, weight_decay=args.weight_decay, seed=args.seed,
                           student=args.student, components=args.components,
                           extra_data=tuple(r.strip() for r in args.extra_data.split(",") if r.strip()))
    progress = run_distillation(args.out, config, jobs=args.jobs, log=lambda line: print(line, flush=True))
    data = progress["dataset"]
    print(f"dataset: {data['episodes']} episodes, {data['samples']} samples, {data['cpu_s']:.0f} teacher CPU s; "
          f"checkpoints in {args.out / 'checkpoints'}")
    return 0
