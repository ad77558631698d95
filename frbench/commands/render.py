"""``frbench render``: a video of one episode (any backend, drawn by MuJoCo)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``render`` to the CLI."""
    p = sub.add_parser("render", help="write a GIF/MP4 of one evaluation episode")
    p.add_argument("--policy", default="scripted", help="policy name, checkpoint or run folder")
    p.add_argument("--robot", default="go2", help="robot name or URDF path")
    p.add_argument("--backend", default="mujoco", help="simulator that runs the episode (mujoco or pybullet)")
    p.add_argument("--terrain", default="flat", help="terrain family")
    p.add_argument("--level", type=int, default=1, help="difficulty level 1-10")
    p.add_argument("--seed", type=int, default=0, help="evaluation seed")
    p.add_argument("--episode", type=int, default=0, help="episode index within the cell")
    p.add_argument("--fps", type=int, default=25, help="frames per second (the control rate is 50 Hz)")
    p.add_argument("--size", default="640x480", help="WIDTHxHEIGHT in pixels")
    p.add_argument("--out", type=Path, default=Path("episode.gif"), help="output .gif or .mp4")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run the episode, record it, draw it, write it."""
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering
    import numpy as np

    from frbench.errors import FrbenchError
    from frbench.evaluation.grid import EvaluationRequest, validate
    from frbench.policies.base import checked_actions
    from frbench.render import SceneRenderer, Trajectory, write_video
    from frbench.robots import get_robot
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import EPISODE_STEPS, RecoveryTask
    from frbench.terrains import make_terrain

    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise FrbenchError(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. 640x480") from None
    if args.out.suffix.lower() not in (".gif", ".mp4"):
        raise FrbenchError(f"--out {args.out}: expected a .gif or .mp4 file")
    policy = validate(EvaluationRequest(policy=args.policy, robots=[args.robot], backends=[args.backend],
                                        terrains=[args.terrain], levels=[args.level], seeds=[args.seed], episodes=1))
    spec = get_robot(args.robot)
    terrain = make_terrain(args.terrain, args.level, args.seed)
    starts = draw_starts(spec, terrain, args.terrain, args.level, args.seed, [args.episode])
    task = RecoveryTask(spec, args.backend, terrain, 1)
    trajectory = Trajectory()
    try:
        obs = task.reset(starts)
        policy.reset(spec, 1)
        trajectory.add(task.state)
        for _ in range(EPISODE_STEPS):
            obs = task.step(checked_actions(policy, policy.act(obs), 1, spec.n_joints))
            trajectory.add(task.state)
    finally:
        task.close()
    stride = max(1, round(50 / args.fps))
    renderer = SceneRenderer(spec, terrain, width, height)
    try:
        frames = [renderer.frame(p, o, q) for p, o, q in list(zip(trajectory.base_pos, trajectory.base_quat, trajectory.q))[::stride]]
    finally:
        renderer.close()
    write_video(frames, args.out, fps=round(50 / stride))
    outcome = "recovered" if task.success.success[0] else "did not recover"
    when = f" at t = {task.success.time_to_recover[0]:.2f} s" if task.success.success[0] else ""
    print(f"{spec.name} on {args.terrain} level {args.level} ({starts.kinds[0]} start, {args.backend}): "
          f"{outcome}{when}. Wrote {len(frames)} frames to {args.out}")
    return 0 if np.isfinite(len(frames)) else 1
