"""``frbench robots`` and ``frbench robot check|add|remove``."""

from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``robots`` and ``robot`` to the CLI."""
    listing = sub.add_parser("robots", help="list the robots frbench knows")
    listing.add_argument("--json", action="store_true", help="machine-readable output")
    listing.set_defaults(func=run_list)

    robot = sub.add_parser("robot", help="check, add or remove a robot")
    robot_sub = robot.add_subparsers(dest="robot_command", metavar="ACTION", required=True)
    check = robot_sub.add_parser("check", help="compare mass/CoM across Pinocchio, MuJoCo, PyBullet; test standing")
    check.add_argument("robot", help="robot name or path to a URDF")
    check.add_argument("--json", action="store_true", help="machine-readable output")
    check.add_argument("--seed", type=int, default=0, help="seed of the random configurations")
    check.add_argument("--backends", default="mujoco,pybullet", help="comma-separated simulators to check in "
                       "(default mujoco,pybullet; physx with the physx extra)")
    check.set_defaults(func=run_check)
    add = robot_sub.add_parser("add", help="register a URDF persistently for this user")
    add.add_argument("urdf", help="path to the URDF (a <stem>.frbench.toml sidecar beside it is read)")
    add.add_argument("--name", required=True, help="name to register it under (letters, digits, '_', '-')")
    add.add_argument("--force", action="store_true", help="replace a robot of that name; add even if its check fails")
    add.set_defaults(func=run_add)
    remove = robot_sub.add_parser("remove", help="unregister a robot added with `frbench robot add`")
    remove.add_argument("name", help="the registered name")
    remove.set_defaults(func=run_remove)


def robot_rows() -> list[dict]:
    """One row per registered robot: name, kind, dof, total mass [kg], source; unavailable ones with the reason."""
    from frbench.errors import FrbenchError
    from frbench.robot_checks.lookup import get_robot
    from frbench.robots import ground_truth, robot_names
    from frbench.robots.registry import unavailable_robots

    rows = []
    for name in robot_names():
        try:
            spec = get_robot(name)
            rows.append(
                {
                    "name": name,
                    "kind": spec.kind,
                    "dof": spec.n_joints,
                    "mass_kg": round(ground_truth.total_mass(spec), 6),
                    "nominal_height_m": round(spec.nominal_height, 4),
                    "source": spec.source,
                    "available": True,
                }
            )
        except FrbenchError as exc:
            rows.append({"name": name, "available": False, "reason": str(exc)})
    for name, reason in unavailable_robots().items():
        rows.append({"name": name, "available": False, "reason": reason})
    return rows


def run_list(args) -> int:
    """Print the robot table (or JSON)."""
    rows = robot_rows()
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"{'name':<12} {'kind':<10} {'dof':>3} {'mass [kg]':>10} {'height [m]':>10}  source")
    for row in rows:
        if not row["available"]:
            print(f"{row['name']:<12} unavailable: {row['reason']}")
            continue
        print(
            f"{row['name']:<12} {row['kind']:<10} {row['dof']:>3} {row['mass_kg']:>10.3f} "
            f"{row['nominal_height_m']:>10.3f}  {row['source']}"
        )
    return 0


def run_check(args) -> int:
    """Run the conformance check; exit 1 when it fails."""
    from frbench.backends import BACKENDS
    from frbench.errors import unknown_name
    from frbench.robot_checks.check import check_robot
    from frbench.robot_checks.lookup import get_robot

    backends = tuple(name.strip() for name in args.backends.split(",") if name.strip())
    for name in backends:
        if name not in BACKENDS:
            raise unknown_name("backend", name, BACKENDS)
    report = check_robot(get_robot(args.robot), seed=args.seed, backends=backends)
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
    print(f"  kind {report.kind}, physics step {report.physics_dt:g} s, check took {report.seconds:.1f} s")
    if report.derivation:
        d = report.derivation
        print(f"  derived gains ({d['method']}):")
        print(f"    kp [N·m/rad]        {_row(d['kp'])}")
        print(f"    kd [N·m·s/rad]      {_row(d['kd'])}")
        print(f"    static torque [N·m] {_row(d['static_torque'])}")
        print(f"    inertia [kg·m²]     {_row(d['inertia'])}")
        print(f"    foot forces z [N]   {_row(d['foot_force_z'])}")
    if report.support:
        sup = report.support
        print(f"  static support: CoM {sup['com_height']:.3f} m up, {sup['edge_distance']:.3f} m inside the feet's "
              f"support polygon (tilt margin {sup['tilt_margin']:.3f} rad)")
    if report.kinematic_height:
        print(f"  standing height: kinematic {report.kinematic_height:.3f} m, nominal (measured) {report.standing and next(iter(report.standing.values()))['nominal_height']:.3f} m")
    for problem in report.problems:
        print(f"  FAIL: {problem}")
    print("  OK" if report.ok else "  FAILED")
    return 0 if report.ok else 1


def _row(values, n: int = 12) -> str:
    return " ".join(f"{v:.3g}" for v in values[:n]) + (" ..." if len(values) > n else "")


def run_add(args) -> int:
    """Register a user URDF after its conformance check (exit 1 when the check fails and no --force)."""
    from frbench.robot_checks.check import check_robot
    from frbench.robot_checks.lookup import with_measured_height
    from frbench.robots import add_user_robot
    from frbench.robots.registry import user_robots_file

    def check(spec):
        report = check_robot(with_measured_height(spec))
        return report.ok, report.problems

    spec = add_user_robot(args.urdf, args.name, force=args.force, check=check)
    print(f"added robot {spec.name!r} ({spec.kind}, {spec.n_joints} joints, feet {', '.join(spec.foot_links)}) to {user_robots_file()}")
    return 0


def run_remove(args) -> int:
    """Unregister a user robot."""
    from frbench.robots.registry import remove_user_robot, user_robots_file

    entry = remove_user_robot(args.name)
    print(f"removed robot {args.name!r} ({entry.get('urdf')}) from {user_robots_file()}")
    return 0
