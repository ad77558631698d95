"""``frbench render``: a video of one episode (any backend, drawn by MuJoCo)."""

from __future__ import annotations

import argparse
from pathlib import Path

#: Simulator names as the overlay writes them.


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``render`` to the CLI."""
    p = sub.add_parser("render", help="write a GIF/MP4 of one evaluation episode")
    p.add_argument("--policy", default="scripted", help="policy name, checkpoint or run folder")
    p.add_argument("--robot", default="go2", help="robot name or URDF path")
    p.add_argument("--backend", default="mujoco",
                   help="simulator that runs the episode (mujoco, pybullet; physx with the physx extra)")
    p.add_argument("--terrain", default="flat", help="terrain family")
    p.add_argument("--level", type=int, default=1, help="difficulty level 1-10")
    p.add_argument("--seed", type=int, default=0, help="evaluation seed")
    p.add_argument("--episode", type=int, default=0, help="episode index within the cell")
    p.add_argument("--fps", type=int, default=25, help="frames per second (the control rate is 50 Hz)")
    p.add_argument("--size", default="640x480", help="WIDTHxHEIGHT in pixels")
    p.add_argument("--frames", type=Path, default=None,
                   help="also write the frames at 1/3, 2/3 and the end of the episode as PNGs into this folder")
    p.add_argument("--out", type=Path, default=Path("episode.gif"), help="output .gif or .mp4")
    p.set_defaults(func=run)


def parse_size(text: str, option: str = "--size") -> tuple[int, int]:
    """``"640x480"`` → (640, 480)."""
    from frbench.errors import FrbenchError

    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise FrbenchError(f"{option} {text!r}: expected WIDTHxHEIGHT, e.g. 640x480") from None
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        raise FrbenchError(f"{option} {text!r}: width and height must be 16 to 4096 pixels")
    return width, height


def run(args) -> int:
    """Run the episode, record it, draw it, write it."""
    import time

    from frbench.render import VIDEO_SUFFIXES, use_headless_gl

    use_headless_gl()  # before anything imports mujoco
    from frbench.evaluation.grid import EvaluationRequest, validate
    from frbench.io import check_output_path

    check_output_path(args.out, suffixes=VIDEO_SUFFIXES)
    if args.frames is not None:
        check_output_path(args.frames, option="--frames", folder=True)
    width, height = parse_size(args.size)
    policy = validate(EvaluationRequest(policy=args.policy, robots=[args.robot], backends=[args.backend],
                                        terrains=[args.terrain], levels=[args.level], seeds=[args.seed], episodes=1))
    start = time.perf_counter()
    spec, trajectory, outcome = record_episode(policy, args)
    simulated = time.perf_counter()
    frames = draw_episode(spec, args, trajectory, width, height)
    drawn = time.perf_counter()
    written = write_outputs(frames, args)
    print(f"{spec.name} on {args.terrain} level {args.level} ({outcome}). Wrote {len(frames)} frames to "
          f"{', '.join(map(str, written))} (simulation {simulated - start:.1f} s, drawing {drawn - simulated:.1f} s, "
          f"encoding {time.perf_counter() - drawn:.1f} s)")
    return 0


def record_episode(policy, args):
    """Run one protocol episode of ``policy``; returns (spec, `Trajectory`, a one-phrase outcome)."""
    from frbench.backends.base import CONTROL_DT
    from frbench.evaluation.episodes import run_episodes
    from frbench.render import Trajectory
    from frbench.robot_checks.lookup import get_robot
    from frbench.tasks.initial_states import draw_starts
    from frbench.terrains import make_terrain

    spec = get_robot(args.robot)
    terrain = make_terrain(args.terrain, args.level, args.seed)
    starts = draw_starts(spec, terrain, args.terrain, args.level, args.seed, [args.episode])
    trajectory = Trajectory()
    task = run_episodes(spec, args.backend, terrain, starts, policy, seed=args.seed,
                        on_reset=lambda task: trajectory.add(task.state),
                        on_step=lambda task, _: trajectory.add(task.state, time=task.t * CONTROL_DT,
                                                               recovered=bool(task.success.success[0])))
    recovered_at = task.success.time_to_recover[0]
    outcome = (f"{starts.kinds[0]} start, {args.backend}: "
               + (f"recovered at t = {recovered_at:.2f} s" if task.success.success[0] else "did not recover"))
    trajectory.recovered_at = float(recovered_at) if task.success.success[0] else None
    return spec, trajectory, outcome


def draw_episode(spec, args, trajectory, width: int, height: int) -> list:
    """Frames (H, W, 3) uint8 at ``args.fps``, each with the time, success state and simulator written on it."""
    from frbench.render import SIMULATOR_LABELS, SceneRenderer, caption
    from frbench.terrains import make_terrain

    stride = max(1, round(50 / args.fps))
    simulator = SIMULATOR_LABELS.get(args.backend, args.backend)
    renderer = SceneRenderer(spec, make_terrain(args.terrain, args.level, args.seed), width, height)
    recovered_at = getattr(trajectory, "recovered_at", None)
    try:
        frames = []
        for k in range(0, len(trajectory.q), stride):
            shown = recovered_at if trajectory.recovered[k] else None
            text = caption(f"{spec.name}, {args.terrain} level {args.level}", simulator, trajectory.time[k], shown)
            frames.append(renderer.frame(trajectory.base_pos[k], trajectory.base_quat[k], trajectory.q[k], text))
    finally:
        renderer.close()
    return frames


def write_outputs(frames: list, args) -> list:
    """The video, and with ``--frames`` three PNG stills; returns the paths written."""
    from frbench.render import write_png, write_video

    stride = max(1, round(50 / args.fps))
    written = [write_video(frames, args.out, fps=round(50 / stride))]
    if args.frames is not None:
        for fraction in (1 / 3, 2 / 3, 1.0):
            k = min(len(frames) - 1, round(fraction * (len(frames) - 1)))
            written.append(write_png(frames[k], args.frames / f"{args.out.stem}-{k:03d}.png"))
    return written
