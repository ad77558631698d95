"""``frbench train``: train a recovery policy with rsl-rl's PPO (FR-Net, its ablations, baselines)."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``train`` to the CLI."""
    p = sub.add_parser("train", help="train a recovery policy (resumable)")
    p.add_argument("--method", default="frnet",
                   help="frnet, frnet-no-mass, frnet-no-contact, frnet-no-est, dreamriser, rma, ppo; "
                        "rma-adaptation (RMA's phase 2, with --teacher)")
    p.add_argument("--teacher", type=Path, default=None, help="rma-adaptation: the finished 'rma' run folder")
    p.add_argument("--robots", default=None, help="train on one named robot instead of randomised morphologies")
    p.add_argument("--steps", type=float, default=None, help="env-step budget (default 20e6; with --resume: extend the budget)")
    p.add_argument("--envs", type=int, default=256, help="parallel environments")
    p.add_argument("--backend", default=None, help="mujoco (default), pybullet, or mujoco+pybullet: "
                   "half the environments in each simulator (with --resume: continue the run there, a new stage)")
    p.add_argument("--terrains", default=None, help="comma-separated families (default: all seven)")
    p.add_argument("--morphologies", type=int, default=32, help="distinct sampled robots per batch")
    p.add_argument("--no-curriculum", action="store_true", help="uniform random levels instead of the curriculum")
    p.add_argument("--no-randomize", action="store_true",
                   help="nominal physics: no gain, motor, friction, payload or CoM randomisation (the evaluation's)")
    p.add_argument("--no-stability", action="store_true", help="drop the stability reward terms (ablation)")
    p.add_argument("--episode-steps", type=int, default=350, help="training episode length (paper: 350)")
    p.add_argument("--settle-steps", type=int, default=25,
                   help="control steps a fallen start settles on soft gains before the episode (default 25; the "
                        "evaluation's 1 s is 50)")
    p.add_argument("--action-scale", type=float, default=None,
                   help="q* = q̊ + scale·a (default: TrainEnvConfig's; the paper's table reads 1)")
    p.add_argument("--demo-starts", type=float, default=0.0, metavar="FRACTION",
                   help="start this fraction of episodes from states along a scripted getting-up motion "
                        "(annealed to 0 at --demo-until; default 0: off)")
    p.add_argument("--demo-until", type=float, default=None, metavar="STEPS",
                   help="env steps at which the demo-start fraction reaches 0 (default: half the budget)")
    p.add_argument("--assist-force", type=float, default=0.0, metavar="FRACTION",
                   help="vertical assist force on the base as a fraction of the robot's weight, falling linearly "
                        "to 0 at --assist-until (default 0: off; HoST's curriculum; evaluation never applies it)")
    p.add_argument("--assist-until", type=float, default=None, metavar="STEPS",
                   help="env steps at which the assist force reaches 0 (default: half the budget)")
    p.add_argument("--base-controller", default=None, metavar="POLICY",
                   help="train a residual over this policy's joint targets (e.g. scripted-humanoid)")
    p.add_argument("--gate-residual", action="store_true",
                   help="add the residual only where the base controller opens its gate (keyframe-humanoid and "
                        "scripted-humanoid: crouch, rise, hold)")
    p.add_argument("--gate-phases", default=None, metavar="PHASES",
                   help="with --gate-residual: the base controller's phases the residual acts in, comma-separated "
                        "(default crouch,rise,hold; keyframe-humanoid's sit-up adds tuck,prop,rock)")
    p.add_argument("--rise-starts", type=float, default=0.0, metavar="FRACTION",
                   help="with --gate-residual: start this fraction of episodes where the base controller's gate "
                        "opened in a recorded run (the key frames' crouch), so that they exercise the rise")
    p.add_argument("--action-hold", type=int, default=1, metavar="STEPS",
                   help="the policy decides every STEPS control steps and holds its action in between (default 1); "
                        "time-coherent exploration for a residual over key frames")
    p.add_argument("--motion-penalties", type=float, default=None, metavar="SCALE",
                   help="joint velocity/acceleration/torque penalties at SCALE x the paper's weights (new runs: "
                        "default 0.1; with --resume: a new reward stage from the run's current step)")
    p.add_argument("--reward-weight", action="append", default=[], metavar="TERM=WEIGHT",
                   help="set one reward term's weight (repeatable; with --resume: part of a new reward stage)")
    p.add_argument("--morphology-range", action="append", default=[], metavar="FIELD=LOW,HIGH",
                   help="replace one row of the paper's morphology table, e.g. calf_width=0.016,0.040 [m] "
                        "(repeatable; with --resume: part of a new stage, the robots are redrawn)")
    p.add_argument("--init-std", type=float, default=None, metavar="STD",
                   help="initial std of the Gaussian actions (default 0.5; a residual over a balancing controller "
                        "wants less exploration)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--checkpoint-every", type=int, default=20, help="iterations between checkpoints")
    p.add_argument("--out", type=Path, default=None, help="run folder (default runs/<method>)")
    p.add_argument("--resume", type=Path, default=None, help="continue the run in this folder")
    p.add_argument("--nproc", type=int, default=1, help="training processes on this machine (each "
                   "with --envs environments; docs/scale.md)")
    p.set_defaults(func=run)


def reward_weight_changes(motion_penalties: float | None, assignments: list[str]) -> dict[str, float]:
    """Reward term → weight from ``--motion-penalties SCALE`` and ``--reward-weight TERM=WEIGHT`` (validated)."""
    from frbench.errors import FrbenchError
    from frbench.training.env import MOTION_PENALTY_TERMS
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


def run(args) -> int:
    """Create (or resume) the run and train it to its budget."""
    from frbench.backends import training_backend_names
    from frbench.errors import FrbenchError, unknown_name
    from frbench.policies.scripted_humanoid import DEFAULT_GATE_PHASES, gate_phase_ids
    from frbench.terrains import FAMILIES
    from frbench.training.env import TrainEnvConfig, training_reward_config
    from frbench.training.methods import METHODS
    from frbench.training.rewards import STABILITY_TERMS
    from frbench.training.run import TrainingRun

    if args.nproc != 1:
        from frbench.training.distributed import launch

        return launch(args.nproc, sys.argv[1:], resume=args.resume)
    command = "frbench " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    weights = reward_weight_changes(args.motion_penalties, args.reward_weight)
    if args.backend is not None and args.backend not in training_backend_names():
        raise unknown_name("backend", args.backend, training_backend_names())
    ranges = morphology_range_changes(args.morphology_range)
    if args.resume:
        run_ = TrainingRun(args.resume, total_steps=int(args.steps) if args.steps else None, resume=True,
                           checkpoint_every=args.checkpoint_every, command=command, reward_stage=weights,
                           morphology_stage=ranges, backend_stage=args.backend)
    else:
        from frbench.training.run import ADAPTATION_METHOD

        if args.method not in METHODS and args.method != ADAPTATION_METHOD:
            raise unknown_name("training method", args.method, METHODS)
        families = tuple(f.strip() for f in args.terrains.split(",")) if args.terrains else FAMILIES
        for family in families:
            if family not in FAMILIES:
                raise unknown_name("terrain", family, FAMILIES)
        args.steps = 20e6 if args.steps is None else args.steps
        if args.steps <= 0 or args.envs < 1 or args.settle_steps < 0:
            raise FrbenchError("--steps and --envs must be positive, --settle-steps at least 0")
        if not 0.0 <= args.demo_starts <= 1.0:
            raise FrbenchError(f"--demo-starts {args.demo_starts}: expected a fraction in [0, 1]")
        if not 0.0 <= args.assist_force <= 2.0:
            raise FrbenchError(f"--assist-force {args.assist_force}: expected a fraction of the weight in [0, 2]")
        if not 0.0 <= args.rise_starts <= 1.0 or (args.rise_starts and not args.gate_residual):
            raise FrbenchError(f"--rise-starts {args.rise_starts}: expected a fraction in [0, 1], with --gate-residual")
        gate_phases = DEFAULT_GATE_PHASES
        if args.gate_phases is not None:
            gate_phases = tuple(p.strip() for p in args.gate_phases.split(","))
            try:
                gate_phase_ids(gate_phases)
            except ValueError as exc:
                raise FrbenchError(f"--gate-phases {args.gate_phases!r}: {exc}") from None
            if not args.gate_residual:
                raise FrbenchError("--gate-phases needs --gate-residual (they name where the gate opens)")
        if args.gate_residual and not args.base_controller:
            raise FrbenchError("--gate-residual needs --base-controller (the gate is the base controller's)")
        if args.action_hold < 1:
            raise FrbenchError(f"--action-hold {args.action_hold}: expected at least 1 control step per decision")
        if args.init_std is not None and args.init_std <= 0:
            raise FrbenchError(f"--init-std {args.init_std}: expected a positive standard deviation")
        if args.action_scale is not None and args.action_scale <= 0:
            raise FrbenchError(f"--action-scale {args.action_scale}: expected a positive number")
        controller_parameters = {}
        if args.base_controller:
            from frbench.policies.registry import base_controller_parameters

            controller_parameters = base_controller_parameters(args.base_controller)
        reward = training_reward_config()
        if args.robots:
            from frbench.robots import get_robot
            from frbench.training.env import humanoid_reward_config

            if get_robot(args.robots).kind == "humanoid":
                reward = humanoid_reward_config()
        if args.no_stability:
            reward = reward.without(STABILITY_TERMS, "stability-reward ablation (--no-stability)")
        for term, weight in weights.items():
            reward = reward.with_weight(term, weight, f"set on the command line ({command})")
        env_cfg = TrainEnvConfig(
            num_envs=args.envs, backend=args.backend or "mujoco", robot=args.robots, num_morphologies=args.morphologies,
            episode_steps=args.episode_steps, settle_steps=args.settle_steps, families=families, curriculum=not args.no_curriculum,
            randomize=not args.no_randomize,
            reward=reward, morphology_ranges=ranges, seed=args.seed, demo_start_fraction=args.demo_starts,
            base_controller=args.base_controller, base_controller_parameters=controller_parameters,
            residual_gate=args.gate_residual, gate_phases=gate_phases, rise_start_fraction=args.rise_starts,
            demo_start_until=args.demo_until if args.demo_until is not None else args.steps / 2,
            assist_force=args.assist_force, action_hold=args.action_hold,
            assist_until=args.assist_until if args.assist_until is not None else args.steps / 2,
            **({"action_scale": args.action_scale} if args.action_scale is not None else {}),
        )
        out = args.out or Path("runs") / args.method
        overrides = None if args.init_std is None else {"actor": {"distribution_cfg": {"init_std": args.init_std}}}
        run_ = TrainingRun(out, args.method, env_cfg, int(args.steps), args.checkpoint_every, command,
                           teacher=args.teacher, train_overrides=overrides)
    run_.train()
    if run_.ranks.is_main:
        print(f"trained {run_.env_steps / 1e6:.2f}M env steps in {run_.wall / 60:.1f} min; policy at {run_.out / 'policy.pt'}")
    return 0
