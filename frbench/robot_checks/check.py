"""``frbench robot check``: the public conformance check of a robot.

Loads the robot in Pinocchio, MuJoCo and PyBullet and compares total mass and
whole-body CoM at the default pose and at random configurations, then holds
it standing with the PD for 2 s in both simulators. For a robot given by path
the report also carries its derived gains and physics step (`frbench.robots.gains`),
its kinematic and measured standing heights, and the check fails when a
simulator settles more than `SAG_TOLERANCE` below the kinematic height. A
humanoid must first be able to stand on its feet at all (`static_support`):
a biped on point or line feet (Bolt) balances by control, not by holding a
pose, and the check says so instead of reporting its fall. A plugin author
runs this on a new robot; the test suite runs it on every built-in one.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from frbench.backends import make_backend
from frbench.backends.base import RobotState
from frbench.robot_checks.lookup import get_robot
from frbench.backends.hold import hold_default_pose
from frbench.robots import ground_truth
from frbench.robots.builtin import BUILTIN_ROBOTS
from frbench.robots.humanoid_gains import support
from frbench.robots.spec import RobotSpec

MASS_TOLERANCE = 1e-6  # kg
COM_TOLERANCE = 1e-4  # m
HEIGHT_TOLERANCE = 0.10  # fraction of nominal height
FORCE_TOLERANCE = 0.05  # fraction of m·g
SAG_TOLERANCE = 0.10  # fraction of the kinematic standing height (robots given by path)
#: [rad] a humanoid's CoM must be this far from the edge of its feet's support polygon, as a tilt about that
#: edge (edge distance / CoM height), to stand by holding a pose: G1 has 0.12, Talos 0.11, iCub 0.14, Bolt 0.025.
MIN_TILT_MARGIN = 0.05
STAND_SECONDS = 2.0
BACKEND_NAMES = ("mujoco", "pybullet")


@dataclass
class CheckReport:
    """Result of :func:`check_robot`; ``asdict`` gives the ``--json`` output."""

    robot: str
    ok: bool = True
    mass: dict[str, float] = field(default_factory=dict)
    max_mass_error: float = 0.0
    com: dict[str, list] = field(default_factory=dict)
    max_com_error: float = 0.0
    standing: dict[str, dict] = field(default_factory=dict)
    support: dict | None = None
    kind: str = ""
    physics_dt: float = 0.0
    kp: list = field(default_factory=list)
    kd: list = field(default_factory=list)
    kinematic_height: float | None = None
    derivation: dict | None = None
    seconds: float = 0.0
    problems: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        """JSON-ready dict."""
        return asdict(self)


def random_configurations(spec: RobotSpec, rng: np.random.Generator, n: int):
    """(base_pos (n, 3), base_quat (n, 4) wxyz, q (n, n_joints)): uniform joints, random orientation."""
    quat = rng.normal(size=(n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = rng.uniform(spec.joint_lower, spec.joint_upper, size=(n, spec.n_joints))
    pos = np.column_stack([rng.uniform(-1, 1, size=(n, 2)), rng.uniform(1.0, 2.0, size=n)])
    return pos, quat, q


def check_robot(spec: RobotSpec, n_random: int = 3, seed: int = 0, stand: bool = True,
                backends: tuple[str, ...] = BACKEND_NAMES) -> CheckReport:
    """Compare mass and CoM across Pinocchio and ``backends`` (default MuJoCo and PyBullet); test standing."""
    started = time.perf_counter()
    extra = dict(spec.extra)
    report = CheckReport(robot=spec.name, kind=spec.kind, physics_dt=spec.physics_dt, kp=list(spec.kp), kd=list(spec.kd))
    if "kinematic_height" in extra:
        report.kinematic_height = float(extra["kinematic_height"])
    if "derivation" in extra:
        report.derivation = json.loads(extra["derivation"])
    rng = np.random.default_rng(seed)
    pos, quat, q = random_configurations(spec, rng, n_random)
    pos = np.vstack([[0.0, 0.0, 1.0], pos])
    quat = np.vstack([[1.0, 0.0, 0.0, 0.0], quat])
    q = np.vstack([spec.default_pose, q])
    reference_mass = ground_truth.total_mass(spec)
    reference_com = np.array([ground_truth.center_of_mass(spec, p, o, j) for p, o, j in zip(pos, quat, q)])
    report.mass["pinocchio"] = reference_mass
    report.com["pinocchio"] = reference_com.tolist()
    states = RobotState.at_rest(pos, quat, q)
    for name in backends:
        backend = make_backend(name, spec, len(pos))
        try:
            backend.reset(np.arange(len(pos)), states)
            masses, coms = backend.mass_properties()
        finally:
            backend.close()
        report.mass[name] = float(masses[0])
        report.com[name] = coms.tolist()
        report.max_mass_error = max(report.max_mass_error, float(np.max(np.abs(masses - reference_mass))))
        report.max_com_error = max(report.max_com_error, float(np.max(np.linalg.norm(coms - reference_com, axis=1))))
    if report.max_mass_error > MASS_TOLERANCE:
        report.problems.append(f"total mass differs by {report.max_mass_error:.3g} kg (tolerance {MASS_TOLERANCE:g})")
    if report.max_com_error > COM_TOLERANCE:
        report.problems.append(f"centre of mass differs by {report.max_com_error:.3g} m (tolerance {COM_TOLERANCE:g})")
    if stand and spec.kind == "humanoid":
        report.support = static_support(spec)
        if not report.support["ok"]:
            report.problems.append(report.support["reason"])
    if stand:
        for name in backends:
            result = stand_test(spec, name)
            report.standing[name] = result
            if report.support and not report.support["ok"]:
                continue  # it falls; the support problem says why
            if not result["ok"]:
                report.problems.append(f"{name}: does not stand ({result['reason']})")
            kinematic = report.kinematic_height
            if kinematic and result["height"] < (1 - SAG_TOLERANCE) * kinematic:
                report.problems.append(
                    f"{name}: sags to {result['height']:.3f} m, {100 * (1 - result['height'] / kinematic):.1f} % below its "
                    f"kinematic standing height {kinematic:.3f} m; set a stiffer kp in the sidecar"
                )
    report.ok = not report.problems
    report.seconds = time.perf_counter() - started
    return report


def static_support(spec: RobotSpec) -> dict:
    """Can the humanoid's feet hold its CoM? The support polygon at the default pose against `MIN_TILT_MARGIN`.

    Returns {"ok", "reason", "edge_distance" [m], "tilt_margin" [rad], "com_height" [m], "polygon_depth" [m, m]}.
    The reason names what would fix it: a pose that brings the CoM over the feet (``default_pose``)
    when the feet are long enough, else soles in the URDF (no sidecar key adds foot area).
    """
    feet = support(spec)
    height = float(feet.com[2])
    need = MIN_TILT_MARGIN * height
    out = {
        "ok": feet.tilt_margin >= MIN_TILT_MARGIN, "reason": "", "edge_distance": feet.edge_distance,
        "tilt_margin": feet.tilt_margin, "com_height": height, "polygon_depth": [float(v) for v in feet.depth],
    }
    if out["ok"]:
        return out
    # the best a pose can do: soles set flat, the CoM over their middle, half the shorter extent from an edge
    best = min(max(float(feet.depth[0]), feet.sole_length), float(feet.depth[1])) / 2
    if best >= need:
        fix = (f"set [default_pose] in the sidecar so the soles lie flat and the CoM stands over their middle "
               f"(they leave up to {best:.3f} m)")
    else:
        fix = (f"no sidecar key can fix it: its feet are at most {feet.sole_length:.3f} m across, {best:.3f} m on each "
               f"side of the CoM in any pose; give each foot link a sole (a box collision) at least {2 * need:.3f} m "
               f"long, or balance it with a controller (the standing test holds a pose)")
    where = "from the edge of" if feet.edge_distance >= 0 else "outside"
    out["reason"] = (
        f"cannot stand by holding a pose: its CoM is {abs(feet.edge_distance):.3f} m {where} the feet's support "
        f"polygon ({feet.depth[0]:.3f} m × {feet.depth[1]:.3f} m), a tilt of {feet.tilt_margin:.3f} rad at its CoM "
        f"height {height:.3f} m (at least {MIN_TILT_MARGIN:g} rad, {need:.3f} m, needed); {fix}"
    )
    return out


def stand_test(spec: RobotSpec, backend_name: str, seconds: float = STAND_SECONDS) -> dict:
    """Hold the default pose with the PD for ``seconds`` on flat ground; report height and vertical force."""
    held = hold_default_pose(spec, backend_name, seconds)
    state, contacts, diverged = held.state, held.contacts, held.diverged
    weight = ground_truth.total_mass(spec) * 9.81
    height = float(state.base_pos[0, 2]) if np.isfinite(state.base_pos[0, 2]) else float("nan")
    force_z = float(contacts.link_force[0, :, 2].sum())
    height_error = abs(height - spec.nominal_height) / spec.nominal_height if np.isfinite(height) else np.inf
    force_error = abs(force_z - weight) / weight if np.isfinite(force_z) else np.inf
    feet_only = not contacts.group_contact[0].any()
    reasons = []
    if diverged:
        reasons.append("simulation diverged")
    if height_error > HEIGHT_TOLERANCE:
        reasons.append(f"base height {height:.3f} m is {100 * height_error:.1f} % from nominal {spec.nominal_height:.3f} m")
    if force_error > FORCE_TOLERANCE:
        reasons.append(f"vertical contact force {force_z:.1f} N is {100 * force_error:.1f} % from m·g {weight:.1f} N")
    if not feet_only:
        reasons.append("a body part other than the feet touches the ground; set a taller [default_pose] or the feet in the sidecar")
    return {
        "ok": not reasons,
        "reason": "; ".join(reasons),
        "height": height,
        "nominal_height": spec.nominal_height,
        "force_z": force_z,
        "weight": weight,
    }


def checks_for_evaluation(names) -> dict[str, dict]:
    """The check of every robot in ``names`` that is not built in (given by path, added, or a plugin).

    Returns spec name → {"ok", "problems", "physics_dt", "nominal_height"}; `frbench evaluate` prints
    the failures on stderr and records these in the results' ``robots`` table.
    """
    out = {}
    for name in names:
        if name in BUILTIN_ROBOTS:
            continue
        spec = get_robot(name)
        report = check_robot(spec)
        out[spec.name] = {
            "ok": report.ok, "problems": report.problems, "physics_dt": spec.physics_dt,
            "nominal_height": spec.nominal_height,
        }
    return out
