"""Physically grounded PD gains and physics step for a robot given by path.

Method (all quantities from the robot's own model, with Pinocchio, at its
standing pose with the feet on flat ground):

1. **Static torques.** ``g(q)`` = generalised gravity (``rnea`` at zero
   velocity). The feet carry the weight: contact wrenches F (quadruped: a
   force per foot; humanoid: a force and a moment per foot, moments weighted
   as forces at 0.1 m) solve the floating-base rows ``J_c,base^T F = g_base``
   with the least norm, so the weight is shared by the feet. The joints then
   hold ``tau = g_joints − J_c,joints^T F`` [N·m].
2. **Stiffness.** ``Kp_j = max(|tau_j| / SAG, floor_j)``: the static sag
   ``tau / Kp`` stays within ``SAG`` = 0.04 rad. The floor is the stiffness
   that holds the load a joint can meet when the robot tilts, divided by
   ``FLOOR_ANGLE`` = 0.5 rad: its own subtree's weight at the lever of the
   subtree's CoM, and, on a chain to a foot, the foot's share of the weight at
   the lever of the whole-body CoM (an inverted pendulum needs ``Kp > m g h``;
   this gives twice that). Legs get the same gain per position in the leg
   (hip, thigh, calf, ...), the largest over the legs.
3. **Effort.** A joint whose static torque exceeds ``EFFORT_FRACTION`` of its
   effort limit cannot hold the robot: refused, naming the sidecar's
   ``effort`` (or ``default_pose``) key.
4. **Damping and step.** Explicit PD on a joint of effective inertia ``I``
   (the diagonal of the joint-space mass matrix, ``crba``) integrated with a
   semi-implicit Euler step ``dt`` is stable while ``a = Kd dt / I < 2`` and
   ``b + 2a < 4`` with ``b = Kp dt² / I``. ``Kd = 2 ZETA sqrt(Kp I)`` (damping
   ratio ``ZETA``). Joints couple (a light calf on a light thigh swinging in
   the air meets far less than its diagonal inertia), so ``b`` and ``a`` are
   taken for the stiffest *mode* of the free-floating robot: the largest
   eigenvalues of ``M⁻¹ Kp`` and ``M⁻¹ Kd`` times ``dt²`` and ``dt``. Kd is
   scaled down until ``a <= A_MAX``; the step is the largest of
   `~frbench.robots.sidecar.PHYSICS_STEPS` with ``b <= B_MAX`` (a quarter of
   the stability bound), the same in both simulators. When not even
   1 ms suffices the robot is refused, naming ``kp``, ``kd`` and ``physics_dt``.

The standing height is not derived here: it is measured by settling the robot
in both simulators (:func:`frbench.robots.standing.measured_height`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots.sidecar import PHYSICS_STEPS
from frbench.robots.spec import RobotSpec

GRAVITY = 9.81
SAG = 0.04  # [rad] static sag allowed by Kp
FLOOR_ANGLE = 0.5  # [rad] sag under the tilt loads of the floor
EFFORT_FRACTION = 0.8
ZETA = 0.7
A_MAX = 1.0
B_MAX = 1.0
MOMENT_ARM = 0.1  # [m] weight of foot moments against forces in the least-norm load sharing


@dataclass(frozen=True)
class Derivation:
    """Derived gains and the numbers behind them, per joint in canonical order.

    Attributes:
        kp [N·m/rad], kd [N·m·s/rad], physics_dt [s].
        static_torque: tau holding the standing pose [N·m].
        inertia: joint-space inertia (mass-matrix diagonal) [kg·m²].
        foot_force_z: vertical force per foot [N].
        stability_b, stability_a: Kp dt²/I and Kd dt/I per joint at ``physics_dt``.
        mode_b, mode_a: the same for the stiffest mode of the whole robot (max eigenvalue of M⁻¹ Kp, M⁻¹ Kd).
    """

    kp: tuple[float, ...]
    kd: tuple[float, ...]
    physics_dt: float
    static_torque: tuple[float, ...]
    inertia: tuple[float, ...]
    foot_force_z: tuple[float, ...]
    stability_b: tuple[float, ...]
    stability_a: tuple[float, ...]
    mode_b: float = 0.0
    mode_a: float = 0.0

    def as_dict(self) -> dict:
        """JSON-ready, rounded."""
        r = lambda v: [float(f"{x:.4g}") for x in v]  # noqa: E731
        return {
            "method": "frbench.robots.gains (static torques, sag 0.04 rad, explicit-PD stability)",
            "kp": r(self.kp), "kd": r(self.kd), "physics_dt": self.physics_dt,
            "static_torque": r(self.static_torque), "inertia": r(self.inertia), "foot_force_z": r(self.foot_force_z),
            "stability_b": r(self.stability_b), "stability_a": r(self.stability_a),
            "mode_b": float(f"{self.mode_b:.4g}"), "mode_a": float(f"{self.mode_a:.4g}"),
        }


def _leg_roles(spec: RobotSpec, legs: tuple[tuple[str, ...], ...]) -> list[list[int]]:
    """Groups of joint indices that share a gain: the i-th joint of every leg; other joints alone."""
    index = {name: i for i, name in enumerate(spec.joint_names)}
    groups, used = [], set()
    depth = min((len(leg) for leg in legs), default=0)
    for k in range(depth):
        group = [index[leg[k]] for leg in legs if leg[k] in index]
        groups.append(group)
        used.update(group)
    groups += [[i] for i in range(spec.n_joints) if i not in used]
    return groups


def static_model(spec: RobotSpec):
    """(pinocchio model, data, q, v indices of the canonical joints) at the standing pose, feet at z = 0."""
    import pinocchio

    from frbench.robots import ground_truth

    robot = ground_truth.load(spec)
    model = robot.model
    data = model.createData()
    q = ground_truth.configuration(robot, [0.0, 0.0, spec.nominal_height], [1.0, 0.0, 0.0, 0.0], spec.default_pose)
    v_index = np.array([model.joints[model.getJointId(name)].idx_v for name in spec.joint_names])
    pinocchio.forwardKinematics(model, data, q)
    pinocchio.updateFramePlacements(model, data)
    return model, data, q, v_index


def derive_gains(spec: RobotSpec, legs: tuple[tuple[str, ...], ...], physics_dt: float | None = None,
                 sidecar_label: str = "sidecar") -> Derivation:
    """Kp, Kd and physics step for ``spec`` at its default pose (method in the module docstring).

    Args:
        spec: a spec whose pose, limits, effort and feet are final (gains are ignored).
        legs: per leg, its joints from the body to the foot (roles share gains).
        physics_dt: a fixed step [s] (the sidecar's), else the largest stable one.
    """
    import pinocchio

    model, data, q, v_index = static_model(spec)
    nv = model.nv
    zero = np.zeros(nv)
    g = pinocchio.rnea(model, data, q, zero, zero).copy()
    humanoid = spec.kind == "humanoid"
    rows = 6 if humanoid else 3
    jac = []
    for foot in spec.foot_links:
        frame = model.getFrameId(foot)
        J = pinocchio.computeFrameJacobian(model, data, q, frame, pinocchio.LOCAL_WORLD_ALIGNED)[:rows].copy()
        if humanoid:
            J[3:] *= MOMENT_ARM
        jac.append(J)
    Jc = np.vstack(jac)  # (k, nv)
    F = np.linalg.lstsq(Jc[:, :6].T, g[:6], rcond=None)[0]
    tau_all = g - Jc.T @ F
    tau = np.abs(tau_all[v_index])
    foot_z = F.reshape(len(spec.foot_links), rows)[:, 2]

    M = pinocchio.crba(model, data, q)
    M_full = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
    inertia = np.array([M_full[v, v] for v in v_index])
    pinocchio.centerOfMass(model, data, q, True)
    total = float(data.mass[0])
    com = np.array(data.com[0])
    share = total / len(spec.foot_links)
    support = set()
    for foot in spec.foot_links:
        jid = model.frames[model.getFrameId(foot)].parentJoint
        while jid > 1:
            support.add(jid)
            jid = model.parents[jid]
    floor = np.zeros(spec.n_joints)
    for i, name in enumerate(spec.joint_names):
        jid = model.getJointId(name)
        pos = np.array(data.oMi[jid].translation)
        limb = data.mass[jid] * GRAVITY * np.linalg.norm(np.array(data.com[jid]) - pos)
        balance = share * GRAVITY * np.linalg.norm(com - pos) if jid in support else 0.0
        floor[i] = max(limb, balance) / FLOOR_ANGLE

    for i, name in enumerate(spec.joint_names):
        if tau[i] > EFFORT_FRACTION * spec.torque_limits[i]:
            raise RobotFileError(
                f"{spec.urdf_path}: joint {name!r} needs {tau[i]:.3g} N·m to hold the standing pose, more than "
                f"{EFFORT_FRACTION:.0%} of its effort limit {spec.torque_limits[i]:.3g} N·m; set effort.{name} in "
                f"{sidecar_label} (or a less crouched [default_pose])"
            )
    kp = np.maximum(tau / SAG, floor)
    for group in _leg_roles(spec, legs):
        kp[group] = kp[group].max()

    steps = (physics_dt,) if physics_dt else PHYSICS_STEPS
    rate_kp = _mode_rate(M_full, v_index, kp)  # [1/s²] the stiffest mode of the PD on the free-floating robot
    for dt in steps:
        b = kp * dt**2 / inertia
        b_mode = rate_kp * dt**2
        if b_mode <= B_MAX or physics_dt:
            kd = 2.0 * ZETA * np.sqrt(kp * inertia)
            for group in _leg_roles(spec, legs):
                kd[group] = kd[group].min()
            a_mode = _mode_rate(M_full, v_index, kd) * dt
            if a_mode > A_MAX:
                kd *= A_MAX / a_mode
                a_mode = A_MAX
            a = kd * dt / inertia
            if physics_dt and not b_mode + 2 * a_mode < 4.0:
                raise RobotFileError(
                    f"{sidecar_label}: physics_dt = {dt:g}: expected a step at which the explicit PD is stable "
                    f"(Kp dt²/I of the stiffest mode = {b_mode:.3g}, needs Kp dt²/I + 2 Kd dt/I < 4): a smaller physics_dt or kp"
                )
            return Derivation(
                kp=tuple(float(f"{v:.4g}") for v in kp), kd=tuple(float(f"{v:.4g}") for v in kd), physics_dt=float(dt),
                static_torque=tuple(tau_all[v_index].tolist()), inertia=tuple(inertia.tolist()),
                foot_force_z=tuple(foot_z.tolist()), stability_b=tuple(b.tolist()), stability_a=tuple(a.tolist()),
                mode_b=float(b_mode), mode_a=float(a_mode),
            )
    b = kp * PHYSICS_STEPS[-1] ** 2 / inertia
    worst = int(np.argmax(b))
    raise RobotFileError(
        f"{spec.urdf_path}: no stable explicit PD even at {PHYSICS_STEPS[-1]:g} s: the stiffest mode has "
        f"Kp dt²/I = {rate_kp * PHYSICS_STEPS[-1] ** 2:.3g} > {B_MAX:g} (lightest joint {spec.joint_names[worst]!r}, "
        f"{inertia[worst]:.3g} kg·m², Kp {kp[worst]:.3g} N·m/rad); set kp, kd and physics_dt in {sidecar_label}"
    )


def _mode_rate(M: np.ndarray, v_index: np.ndarray, gains: np.ndarray) -> float:
    """Largest eigenvalue of M⁻¹ G, G the gains on the joints' velocity indices (zero on the floating base)."""
    G = np.zeros_like(M)
    G[v_index, v_index] = gains
    return float(np.max(np.linalg.eigvals(np.linalg.solve(M, G)).real))
