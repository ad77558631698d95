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
    from frbench.render import use_headless_gl

    use_headless_gl()  # before anything imports mujoco
    from frbench.commands.render import parse_size
    from frbench.errors import FrbenchError
    from frbench.io import check_output_path
    from frbench.render import SceneRenderer, write_png
    from frbench.robot_checks.lookup import get_robot
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import RecoveryTask, open_backend
    from frbench.terrains import FAMILIES, make_terrain

    check_output_path(args.out, suffixes=(".png",))
    if args.family not in FAMILIES:
        from frbench.errors import unknown_name

        raise unknown_name("terrain", args.family, FAMILIES)
    if not 1 <= args.level <= 10:
        raise FrbenchError(f"--level {args.level} is out of range: levels are 1 to 10")
    width, height = parse_size(args.size)
    spec = get_robot(args.robot)
    terrain = make_terrain(args.family, args.level, args.seed)
    starts = draw_starts(spec, terrain, args.family, args.level, args.seed, [0])
    with open_backend("mujoco", spec, 1, terrain) as physics:
        task = RecoveryTask(spec, physics, terrain, 1)
        task.reset(starts)
        state = task.state
    renderer = SceneRenderer(spec, terrain, width, height)
    renderer.camera.distance *= 2.0
    renderer.camera.elevation = -32.0
    try:
        text = f"{args.family} level {args.level} (seed {args.seed})\n{spec.name}, {starts.kinds[0]} start"
        image = renderer.frame(state.base_pos[0], state.base_quat[0], state.q[0], text)
    finally:
        renderer.close()
    write_png(image, args.out)
    print(f"{args.family} level {args.level} (seed {args.seed}): {terrain.description}; "
          f"{len(terrain.boxes)} boxes; {spec.name} {starts.kinds[0]} start. Wrote {args.out}")
    return 0
