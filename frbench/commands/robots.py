"""``frbench robots`` and ``frbench robot check|add``."""

from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``robots`` and ``robot`` to the CLI."""
    listing = sub.add_parser("robots", help="list the robots frbench knows")
    listing.add_argument("--json", action="store_true", help="machine-readable output")
    listing.set_defaults(func=run_list)

    robot = sub.add_parser("robot", help="check or add a robot")
    robot_sub = robot.add_subparsers(dest="robot_command", metavar="ACTION", required=True)
    check = robot_sub.add_parser("check", help="compare mass/CoM across Pinocchio, MuJoCo, PyBullet; test standing")
    check.add_argument("robot", help="robot name or path to a URDF")
    check.add_argument("--json", action="store_true", help="machine-readable output")
    check.add_argument("--seed", type=int, default=0, help="seed of the random configurations")
    check.set_defaults(func=run_check)
    add = robot_sub.add_parser("add", help="register a URDF persistently for this user")
    add.add_argument("urdf", help="path to the URDF (a <stem>.frbench.toml sidecar beside it is read)")
    add.add_argument("--name", required=True, help="name to register it under")
    add.set_defaults(func=run_add)


def robot_rows() -> list[dict]:
    """One row per registered robot: name, kind, dof, total mass [kg], source."""
    from frbench.robots import get_robot, ground_truth, robot_names

    rows = []
    for name in robot_names():
        spec = get_robot(name)
        rows.append(
            {
                "name": name,
                "kind": spec.kind,
                "dof": spec.n_joints,
                "mass_kg": round(ground_truth.total_mass(spec), 6),
                "nominal_height_m": round(spec.nominal_height, 4),
                "source": spec.source,
            }
        )
    return rows


def run_list(args) -> int:
    """Print the robot table (or JSON)."""
    rows = robot_rows()
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"{'name':<12} {'kind':<10} {'dof':>3} {'mass [kg]':>10} {'height [m]':>10}  source")
    for row in rows:
        print(
            f"{row['name']:<12} {row['kind']:<10} {row['dof']:>3} {row['mass_kg']:>10.3f} "
            f"{row['nominal_height_m']:>10.3f}  {row['source']}"
        )
    return 0


def run_check(args) -> int:
    """Run the conformance check; exit 1 when it fails."""
    from frbench.robots import get_robot
    from frbench.robots.check import check_robot

    report = check_robot(get_robot(args.robot), seed=args.seed)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
        return 0 if report.ok else 1
    print(f"robot {report.robot}")
    for name, mass in report.mass.items():
        print(f"  total mass  {name:<10} {mass:.9f} kg")
    print(f"  largest mass difference {report.max_mass_error:.3g} kg, CoM difference {report.max_com_error:.3g} m "
          "(default pose + random configurations)")
    for name, result in report.standing.items():
        print(
            f"  standing    {name:<10} height {result['height']:.3f} m (nominal {result['nominal_height']:.3f}), "
            f"vertical contact force {result['force_z']:.1f} N (m·g {result['weight']:.1f})"
        )
    for problem in report.problems:
        print(f"  FAIL: {problem}")
    print("  OK" if report.ok else "  FAILED")
    return 0 if report.ok else 1


def run_add(args) -> int:
    """Register a user URDF."""
    from frbench.robots import add_user_robot
    from frbench.robots.registry import user_robots_file

    spec = add_user_robot(args.urdf, args.name)
    print(f"added robot {spec.name!r} ({spec.n_joints} joints, feet {', '.join(spec.foot_links)}) to {user_robots_file()}")
    return 0
