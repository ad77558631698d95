"""``frbench train``: train a recovery policy with rsl-rl's PPO (FR-Net, its ablations, baselines)."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``train`` to the CLI."""
    from frbench.training.presets import PRESETS

    presets = "; ".join(f"{name}: {preset.description}" for name, preset in PRESETS.items())
    p = sub.add_parser("train", help="train a recovery policy (resumable)")
    p.add_argument("--method", default="frnet",
                   help="frnet, frnet-no-mass, frnet-no-contact, frnet-no-est, dreamriser, rma, ppo; "
                        "rma-adaptation (RMA's phase 2, with --teacher)")
    p.add_argument("--teacher", type=Path, default=None, help="rma-adaptation: the finished 'rma' run folder")
    p.add_argument("--preset", default="paper", metavar="NAME", help=f"a named training setup ({presets})")
    p.add_argument("--robots", default=None, help="train on one named robot instead of randomised morphologies")
    p.add_argument("--steps", type=float, default=None, help="env-step budget (default 20e6; with --resume: extend the budget)")
    p.add_argument("--envs", type=int, default=256, help="parallel environments")
    p.add_argument("--backend", default=None, help="mujoco (default), pybullet, mujoco-warp (on --device), or "
                   "mujoco+pybullet: half the environments in each simulator (with --resume: continue the run there, "
                   "a new stage)")
    p.add_argument("--device", default=None, metavar="DEVICE",
                   help="cpu (default), cuda or cuda:N: where a device simulator (mujoco-warp) runs and the run's "
                        "tensors live (the CPU simulators run on cpu); a run resumes on either")
    p.add_argument("--bundle", type=Path, default=None,
                   help="a device bundle (tools/gpu_run/make_bundle.py): the run's robots, rasters, starts and "
                        "compiled world, built on a CPU machine for this run's flags")
    p.add_argument("--terrains", default=None, help="comma-separated families (default: all seven)")
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", dest="fields",
                   help="set one training-env config field on top of the preset (repeatable), e.g. seed=1, "
                        "action_hold=10, rise_start_fraction=0.3, curriculum=false (docs/training.md lists them); "
                        "with --resume only bodies=paper|wide (a new stage, the robots are redrawn)")
    p.add_argument("--motion-penalties", type=float, default=None, metavar="SCALE",
                   help="joint velocity/acceleration/torque penalties at SCALE x the paper's weights (new runs: "
                        "default 0.1; with --resume: a new reward stage from the run's current step)")
    p.add_argument("--reward-weight", action="append", default=[], metavar="TERM=WEIGHT",
                   help="set one reward term's weight (repeatable; with --resume: part of a new reward stage)")
    p.add_argument("--morphology-range", action="append", default=[], metavar="FIELD=LOW,HIGH",
                   help="replace one row of the paper's morphology table, e.g. calf_width=0.016,0.040 [m] "
                        "(repeatable; with --resume: part of a new stage, the robots are redrawn)")
    p.add_argument("--entropy-coef", type=float, default=None, metavar="COEF",
                   help="PPO's entropy bonus coefficient (new runs: on top of the preset; with --resume: part of a "
                        "new stage from the run's current step)")
    p.add_argument("--checkpoint-every", type=int, default=20, help="iterations between checkpoints")
    p.add_argument("--out", type=Path, default=None, help="run folder (default runs/<method>)")
    p.add_argument("--resume", type=Path, default=None, help="continue the run in this folder")
    p.add_argument("--nproc", type=int, default=1, help="training processes on this machine (each "
                   "with --envs environments; docs/scale.md)")
    p.set_defaults(func=run)


def reward_weight_changes(motion_penalties: float | None, assignments: list[str]) -> dict[str, float]:
    """Reward term → weight from ``--motion-penalties SCALE`` and ``--reward-weight TERM=WEIGHT`` (validated)."""
    from frbench.errors import FrbenchError
    from frbench.training.reward_tables import MOTION_PENALTY_TERMS
    from frbench.training.rewards import PAPER_WEIGHTS, check_weights

    weights = {}
    if motion_penalties is not None:
        if not motion_penalties >= 0:
            raise FrbenchError(f"--motion-penalties {motion_penalties}: expected a scale >= 0 of the paper's weights")
        weights.update({t: motion_penalties * PAPER_WEIGHTS[t] for t in MOTION_PENALTY_TERMS})
    for item in assignments:
        term, sep, value = item.partition("=")
        try:
            weights[term.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise FrbenchError(f"--reward-weight {item!r}: expected TERM=WEIGHT, e.g. action_smoothing=-0.1")
    try:
        check_weights(weights)
    except ValueError as exc:
        raise FrbenchError(f"--reward-weight: {exc}") from None
    return weights


def morphology_range_changes(assignments: list[str]) -> dict[str, tuple[float, float]]:
    """Field → (low, high) from ``--morphology-range FIELD=LOW,HIGH`` (validated)."""
    from frbench.errors import FrbenchError
    from frbench.robots.morphology import morphology_ranges

    ranges = {}
    for item in assignments:
        name, sep, value = item.partition("=")
        parts = value.split(",")
        try:
            if not sep or len(parts) != 2:
                raise ValueError
            ranges[name.strip()] = (float(parts[0]), float(parts[1]))
        except ValueError:
            raise FrbenchError(f"--morphology-range {item!r}: expected FIELD=LOW,HIGH, "
                               "e.g. calf_width=0.016,0.040") from None
    try:
        morphology_ranges(ranges)
    except ValueError as exc:
        raise FrbenchError(f"--morphology-range: {exc}") from None
    return ranges


def field_changes(assignments: list[str]) -> dict:
    """Config field → value from ``--set FIELD=VALUE`` (each parsed by the field's type)."""
    from frbench.errors import FrbenchError
    from frbench.training.config import parse_field

    changes = {}
    for item in assignments:
        name, sep, value = item.partition("=")
        if not sep:
            raise FrbenchError(f"--set {item!r}: expected FIELD=VALUE, e.g. action_hold=10")
        try:
            changes[name.strip()] = parse_field(name.strip(), value)
        except ValueError as exc:
            raise FrbenchError(str(exc)) from None
    return changes


def stage_field_changes(assignments: list[str]) -> dict:
    """Config field → value from ``--set FIELD=VALUE`` on a resumed run: only `config.STAGE_FIELDS` may change."""
    from frbench.errors import FrbenchError
    from frbench.training.config import STAGE_FIELDS

    changes = field_changes(assignments)
    refused = sorted(set(changes) - set(STAGE_FIELDS))
    if refused:
        raise FrbenchError(f"--resume --set {refused[0]}: a resumed run keeps its config; --set changes only "
                           f"{', '.join(STAGE_FIELDS)} there (a new stage)")
    return changes


def new_run_config(args, command: str, weights: dict[str, float], ranges: dict):
    """(env config, rsl-rl overrides) of a new run: the preset, then the flags and ``--set`` fields on top."""
    import dataclasses

    from frbench.errors import FrbenchError, unknown_name
    from frbench.training.config import TrainEnvConfig
    from frbench.training.presets import PRESETS
    from frbench.training.reward_tables import reward_table

    if args.preset not in PRESETS:
        raise unknown_name("preset", args.preset, PRESETS)
    preset = PRESETS[args.preset]
    fields = dict(preset.env)
    fields.update(field_changes(args.fields))
    fields["num_envs"] = args.envs
    if args.robots:
        fields["robot"] = args.robots
    if args.backend:
        fields["backend"] = args.backend
    if args.terrains:
        fields["families"] = tuple(f.strip() for f in args.terrains.split(","))
    if ranges:
        fields["morphology_ranges"] = ranges
    for fraction, until in (("demo_start_fraction", "demo_start_until"), ("assist_force", "assist_until")):
        if fields.get(fraction, 0.0) > 0.0 and not fields.get(until):
            fields[until] = args.steps / 2  # a schedule over the first half of the budget, said and recorded
            print(f"{until} not set: the {fraction} schedule ends at half the budget, {fields[until]:.4g} env steps "
                  f"(--set {until}=STEPS to choose; recorded in config.json)")
    if fields.get("base_controller") and "base_controller_parameters" not in fields:
        from frbench.policies.registry import base_controller_parameters

        fields["base_controller_parameters"] = base_controller_parameters(fields["base_controller"])
    try:
        cfg = TrainEnvConfig(**fields)
    except ValueError as exc:
        raise FrbenchError(f"frbench train --preset {args.preset}: {exc}") from None
    reward = reward_table(cfg.robot_kind())
    if preset.drop_terms:
        reward = reward.without(preset.drop_terms, f"stability-reward ablation (--preset {args.preset})")
    if preset.motion_penalties is not None and args.motion_penalties is None:
        preset_weights = reward_weight_changes(preset.motion_penalties, [f"{k}={v}" for k, v in preset.reward_weights.items()])
        weights = {**preset_weights, **weights}
    else:
        weights = {**preset.reward_weights, **weights}
    for term, weight in weights.items():
        reward = reward.with_weight(term, weight, f"set on the command line ({command})")
    cfg = dataclasses.replace(cfg, reward=reward)
    return cfg, preset.train_overrides()


def run(args) -> int:
    """Create (or resume) the run and train it to its budget."""
    from frbench.backends import training_backend_names
    from frbench.backends.devices import parse_device
    from frbench.errors import FrbenchError, unknown_name
    from frbench.training.methods import METHODS
    from frbench.training.run import ADAPTATION_METHOD, TrainingRun

    if args.nproc != 1:
        from frbench.training.distributed import launch

        return launch(args.nproc, sys.argv[1:], resume=args.resume)
    command = "frbench " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    weights = reward_weight_changes(args.motion_penalties, args.reward_weight)
    if args.backend is not None and args.backend not in training_backend_names():
        raise unknown_name("backend", args.backend, training_backend_names())
    if args.bundle is not None and not args.bundle.is_dir():
        raise FrbenchError(f"--bundle {args.bundle}: no such folder")
    device = {"device": None if args.device is None else parse_device(args.device), "bundle": args.bundle}
    ranges = morphology_range_changes(args.morphology_range)
    if args.entropy_coef is not None and not args.entropy_coef >= 0:
        raise FrbenchError(f"--entropy-coef {args.entropy_coef}: expected a coefficient >= 0")
    algorithm = {} if args.entropy_coef is None else {"entropy_coef": float(args.entropy_coef)}
    if args.resume:
        if args.preset != "paper":
            raise FrbenchError("--resume continues a run with its own config; --preset applies to new runs")
        run_ = TrainingRun(args.resume, total_steps=int(args.steps) if args.steps else None, resume=True,
                           checkpoint_every=args.checkpoint_every, command=command, reward_stage=weights,
                           morphology_stage=ranges, backend_stage=args.backend, algorithm_stage=algorithm,
                           field_stage=stage_field_changes(args.fields), **device)
    else:
        if args.method not in METHODS and args.method != ADAPTATION_METHOD:
            raise unknown_name("training method", args.method, METHODS)
        args.steps = 20e6 if args.steps is None else args.steps
        if args.steps <= 0 or args.envs < 1:
            raise FrbenchError("--steps and --envs must be positive")
        env_cfg, overrides = new_run_config(args, command, weights, ranges)
        if algorithm:
            overrides = {**(overrides or {}), "algorithm": {**(overrides or {}).get("algorithm", {}), **algorithm}}
        out = args.out or Path("runs") / args.method
        run_ = TrainingRun(out, args.method, env_cfg, int(args.steps), args.checkpoint_every, command,
                           teacher=args.teacher, train_overrides=overrides, **device)
    run_.train()
    if run_.ranks.is_main:
        print(f"trained {run_.env_steps / 1e6:.2f}M env steps in {run_.wall / 60:.1f} min; policy at {run_.out / 'policy.pt'}")
    return 0
