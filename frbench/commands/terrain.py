"""``frbench terrain show|list``: look at a terrain family and level."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``terrain`` to the CLI."""
    p = sub.add_parser("terrain", help="show or list terrains")
    actions = p.add_subparsers(dest="terrain_command", metavar="ACTION", required=True)
    show = actions.add_parser("show", help="render a terrain with a fallen robot on it to a PNG")
    show.add_argument("family", help="flat, rough, slopes, stairs, stones, gaps or beams")
    show.add_argument("--level", type=int, default=5, help="difficulty level 1-10")
    show.add_argument("--seed", type=int, default=0, help="terrain and start seed")
    show.add_argument("--robot", default="go2", help="robot name or URDF path")
    show.add_argument("--size", default="800x600", help="WIDTHxHEIGHT in pixels")
    show.add_argument("--out", type=Path, required=True, help="output PNG")
    show.set_defaults(func=run_show)
    listing = actions.add_parser("list", help="print every family's parameters per level")
    listing.set_defaults(func=run_list)


def run_list(args) -> int:
    """Print the parameter tables (the ones in docs/protocol.md)."""
    from frbench.terrains import parameters_table_markdown

    print(parameters_table_markdown())
    return 0


def run_show(args) -> int:
    """Drop a fallen robot on the terrain, settle it in MuJoCo, draw it."""
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    import imageio.v3 as iio

    from frbench.errors import FrbenchError
    from frbench.render import SceneRenderer
    from frbench.robots import get_robot
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import RecoveryTask
    from frbench.terrains import FAMILIES, make_terrain

    if args.family not in FAMILIES:
        from frbench.errors import unknown_name

        raise unknown_name("terrain", args.family, FAMILIES)
    if not 1 <= args.level <= 10:
        raise FrbenchError(f"--level {args.level} is out of range: levels are 1 to 10")
    if args.out.suffix.lower() != ".png":
        raise FrbenchError(f"--out {args.out}: expected a .png file")
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise FrbenchError(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. 800x600") from None
    spec = get_robot(args.robot)
    terrain = make_terrain(args.family, args.level, args.seed)
    starts = draw_starts(spec, terrain, args.family, args.level, args.seed, [0])
    task = RecoveryTask(spec, "mujoco", terrain, 1)
    try:
        task.reset(starts)
        state = task.state
    finally:
        task.close()
    renderer = SceneRenderer(spec, terrain, width, height)
    renderer.camera.distance *= 1.6
    renderer.camera.elevation = -30.0
    try:
        image = renderer.frame(state.base_pos[0], state.base_quat[0], state.q[0])
    finally:
        renderer.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(args.out, image)
    print(f"{args.family} level {args.level} (seed {args.seed}): {terrain.description}; "
          f"{len(terrain.boxes)} boxes; {spec.name} {starts.kinds[0]} start. Wrote {args.out}")
    return 0
