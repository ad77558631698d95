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
   this gives twice that). A quadruped's leg joint takes the larger of that
   lever and the leg's *reach* below the joint (`leg_reach`: the chain's length
   from the joint to the foot): pushing up from a crouch, or with a foot that
   slid, a foot can meet the ground anywhere within reach, and at the standing
   pose, feet under the hips, the thigh's static torque is almost zero (Go2's
   file: 0.7 N·m, Kp 19 N·m/rad, too weak to lift the nose off the ground when
   standing up; 34 N·m/rad with the reach). Legs get the same gain per position
   in the leg (hip, thigh, calf, ...), the largest over the legs.
3. **Effort.** A joint whose static torque exceeds ``EFFORT_FRACTION`` of its
   effort limit cannot hold the robot: refused, naming the sidecar's
   ``effort`` (or ``default_pose``) key. A quadruped's leg joints are then
   *capped* (``Derivation.effort``, the robot's torque limits unless the
   sidecar sets ``effort``) at the torque that holds a foot's share of the
   weight at the leg's full reach, ``m g / n_feet * reach`` (the longest
   leg's, from its first joint), never below ``|tau| / EFFORT_FRACTION``:
   files give efforts far above what the robot can use (Solo12 1000 N·m on
   2.5 kg, pybullet_data's Laikago 100 N·m on 26 kg), and with them a leg
   caught under the body or against another leg stores its saturated torque
   and, when it frees, throws the robot off the ground (Solo12 diverged in
   both simulators; with the cap it recovers).
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
in both simulators (:func:`frbench.robot_checks.standing.measured_height`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots import ground_truth
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
        effort: the torque limits the robot is simulated with [N·m] (quadrupeds: the file's, capped as in
            step 3 of the module docstring); empty where the derivation leaves them as they are.
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
    effort: tuple[float, ...] = ()

    def as_dict(self) -> dict:
        """JSON-ready, rounded."""
        r = lambda v: [float(f"{x:.4g}") for x in v]  # noqa: E731
        out = {
            "method": "frbench.robots.gains (static torques, sag 0.04 rad, explicit-PD stability)",
            "kp": r(self.kp), "kd": r(self.kd), "physics_dt": self.physics_dt,
            "static_torque": r(self.static_torque), "inertia": r(self.inertia), "foot_force_z": r(self.foot_force_z),
            "stability_b": r(self.stability_b), "stability_a": r(self.stability_a),
            "mode_b": float(f"{self.mode_b:.4g}"), "mode_a": float(f"{self.mode_a:.4g}"),
        }
        if self.effort:
            out["effort"] = r(self.effort)
        return out


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
    reach = {} if humanoid else leg_reach(model, data, spec, legs)
    floor = np.zeros(spec.n_joints)
    for i, name in enumerate(spec.joint_names):
        jid = model.getJointId(name)
        pos = np.array(data.oMi[jid].translation)
        limb = data.mass[jid] * GRAVITY * np.linalg.norm(np.array(data.com[jid]) - pos)
        lever = max(np.linalg.norm(com - pos), reach.get(name, 0.0))
        balance = share * GRAVITY * lever if jid in support else 0.0
        floor[i] = max(limb, balance) / FLOOR_ANGLE

    for i, name in enumerate(spec.joint_names):
        if tau[i] > EFFORT_FRACTION * spec.torque_limits[i]:
            raise RobotFileError(
                f"{spec.urdf_path}: joint {name!r} needs {tau[i]:.3g} N·m to hold the standing pose, more than "
                f"{EFFORT_FRACTION:.0%} of its effort limit {spec.torque_limits[i]:.3g} N·m; set effort.{name} in "
                f"{sidecar_label} (or a less crouched [default_pose])"
            )
    effort = () if humanoid else capped_effort(spec, legs, tau, share, reach)
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
                mode_b=float(b_mode), mode_a=float(a_mode), effort=effort,
            )
    b = kp * PHYSICS_STEPS[-1] ** 2 / inertia
    worst = int(np.argmax(b))
    raise RobotFileError(
        f"{spec.urdf_path}: no stable explicit PD even at {PHYSICS_STEPS[-1]:g} s: the stiffest mode has "
        f"Kp dt²/I = {rate_kp * PHYSICS_STEPS[-1] ** 2:.3g} > {B_MAX:g} (lightest joint {spec.joint_names[worst]!r}, "
        f"{inertia[worst]:.3g} kg·m², Kp {kp[worst]:.3g} N·m/rad); set kp, kd and physics_dt in {sidecar_label}"
    )


def leg_reach(model, data, spec: RobotSpec, legs: tuple[tuple[str, ...], ...]) -> dict[str, float]:
    """Per leg joint, its reach [m]: the length of the chain below it to its foot, the sum of the distances
    between consecutive joint origins and from the leg's last joint to the foot frame (``data`` after
    forward kinematics and frame placements at any pose; legs in the order of ``spec.foot_links``)."""
    reach = {}
    for joints, foot in zip(legs, spec.foot_links):
        points = [np.array(data.oMi[model.getJointId(name)].translation) for name in joints]
        points.append(np.array(data.oMf[model.getFrameId(foot)].translation))
        segments = np.linalg.norm(np.diff(np.array(points), axis=0), axis=1)
        for k, name in enumerate(joints):
            reach[name] = float(segments[k:].sum())
    return reach


def capped_effort(spec: RobotSpec, legs: tuple[tuple[str, ...], ...], tau: np.ndarray, share: float,
                  reach: dict[str, float]) -> tuple[float, ...]:
    """Torque limits [N·m] with the leg joints capped (step 3 of the module docstring).

    Args:
        tau: |static torque| per joint at the standing pose [N·m].
        share: a foot's share of the weight, total mass / number of feet [kg].
        reach: `leg_reach` per leg joint [m].
    """
    longest = max(reach[leg[0]] for leg in legs)
    cap = share * GRAVITY * longest
    leg_joints = {name for leg in legs for name in leg}
    effort = np.asarray(spec.torque_limits, dtype=float).copy()
    for i, name in enumerate(spec.joint_names):
        if name in leg_joints:
            effort[i] = min(effort[i], float(f"{max(cap, tau[i] / EFFORT_FRACTION):.4g}"))
    return tuple(effort.tolist())


def _mode_rate(M: np.ndarray, v_index: np.ndarray, gains: np.ndarray) -> float:
    """Largest eigenvalue of M⁻¹ G, G the gains on the joints' velocity indices (zero on the floating base)."""
    G = np.zeros_like(M)
    G[v_index, v_index] = gains
    return float(np.max(np.linalg.eigvals(np.linalg.solve(M, G)).real))
