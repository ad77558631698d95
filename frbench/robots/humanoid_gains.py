"""PD gains and physics step for a humanoid given by path: stiff enough to stand, no stiffer.

The quadruped derivation (:mod:`frbench.robots.gains`) gives every joint on a
chain to a foot a floor of ``m_foot g h / FLOOR_ANGLE``: the foot's share of
the weight at the lever of the whole-body CoM, as if that joint alone held the
robot up as an inverted pendulum. A biped standing on two flat feet is held by
*several* joints at once (a sideways sway turns both hip rolls and both ankle
rolls), and that per-joint floor made G1's ankle rolls 5× stiffer than the
built-in G1's (217 vs 40 N·m/rad on 0.4 g·m² of foot), which forced a 1 ms
physics step. It is also not enough where it matters: Talos, with those
floors, sinks backwards in both simulators (its knees and ankles creep until
the CoM leaves the heel).

Method, all from the robot's own model at its standing pose (Pinocchio), units
N·m/rad, N·m·s/rad, s:

1. **Static torques** ``tau`` as in :mod:`frbench.robots.gains` (a force and a
   moment per foot, least norm, the weight shared by the feet).
2. **Own load.** ``Kp_j = max(|tau_j| / SAG, limb_j)`` with ``limb_j`` the
   stiffness that holds the joint's own subtree (its weight at the lever of its
   CoM) within ``FLOOR_ANGLE``; legs share gains per position in the leg.
3. **Standing stability.** With both feet fixed to the ground, the robot
   under its PD is statically stable when its stiffness on the constraint
   manifold, ``Nᵀ (K_g + K_p) N``, is positive definite: ``K_g = ∂(g(q) −
   J_cᵀ F)/∂q`` is the stiffness of gravity and of the contact wrenches F
   (negative where the robot can fall), ``N`` a basis of the null space of the
   feet's 6-D contact Jacobian ``J_c``, ``K_p`` the joint gains. The check is
   made with gravity doubled (``STABILITY_MARGIN``, the same factor 2 as
   ``FLOOR_ANGLE``). While the least eigenvalue is negative, its mode's joint
   motions ``d_j`` get stiffness ``ΔKp_j ∝ d_j² I_j`` (``I_j`` the joint's
   mass-matrix diagonal) scaled so the mode's energy becomes non-negative: the
   stiffness goes to the joints that move in the mode, the heavy ones first,
   which cost the physics step least.
   **Sway within the feet.** The robot starts at its pose and sags under its
   static torques; the sag turns ankles, knees and hips and moves the CoM
   (the lean about the ankles is softened by gravity and, with the small
   ankle damping an explicit PD allows on a light foot, hardly damped: the
   first swing overshoots to about twice the sag). The static deflection
   ``δ = N (Nᵀ(K_g + K_p)N)⁻¹ Nᵀ(−τ)`` moves the CoM by ``J_com δ``; its
   horizontal part must stay within ``SWAY_FRACTION`` (a quarter) of the
   distance from the CoM to the edge of the support polygon in that
   direction, so that twice the sag keeps the CoM on the feet with half the
   margin to spare. While it does not, the joints that move in ``δ`` get
   stiffness as above (``∝ δ_j² I_j``), enough to shrink the sway by the
   missing factor. (G1 with hands: ankle pitch 256 → the CoM swayed 14 cm
   forward, over its toes; Talos: knees and ankles crept until its heels
   lifted.) Skipped when the feet leave no margin at all (`support`); the
   check then says why (:func:`frbench.robot_checks.check.static_support`).
4. **Effort.** A static torque above ``EFFORT_FRACTION`` of the effort limit
   is refused, naming the sidecar's ``effort`` and ``default_pose`` keys.
5. **Damping and step.** ``Kd = 2 ζ sqrt(Kp I)``; the stiffest mode of the
   free-floating robot, ``max eig(M⁻¹Kp) dt² <= B_MAX``, chooses the largest
   step of `PHYSICS_STEPS` (as in :mod:`frbench.robots.gains`), the same in
   both simulators; then Kd is lowered where the stiffest *damping* mode
   lives until ``max eig(M⁻¹Kd) dt <= A_MAX`` (`_damping`), not everywhere.

**Support polygon** (`support`): the convex hull of the feet's collision
geometry that touches the ground at the standing pose (within
`CONTACT_BAND` of the lowest point: sphere centres, the corners of a box's
bottom face), in the simulated geometry both simulators use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frbench.errors import RobotFileError
from frbench.robots import ground_truth
from frbench.robots.gains import (
    A_MAX,
    B_MAX,
    EFFORT_FRACTION,
    FLOOR_ANGLE,
    GRAVITY,
    MOMENT_ARM,
    SAG,
    ZETA,
    Derivation,
    _leg_roles,
    _mode_rate,
    static_model,
)
from frbench.robots.kinematics import link_poses
from frbench.robots.sidecar import PHYSICS_STEPS
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec
from frbench.robots.urdf_tree import parse_urdf

#: Gravity is doubled in the standing-stability test (step 3 of the module docstring).
STABILITY_MARGIN = 2.0
#: Each stiffening step aims this much past the mode's zero energy, so few steps are needed.
OVERSHOOT = 1.1
MAX_STIFFENING_STEPS = 200
#: [rad] step of the central differences that give K_g.
DIFF_STEP = 1e-6
#: The static CoM sway may use this fraction of the distance to the support polygon's edge (step 3).
SWAY_FRACTION = 0.25
#: [m] collision geometry this close to the lowest point of the feet touches the ground.
CONTACT_BAND = 0.005


@dataclass(frozen=True)
class HumanoidDerivation(Derivation):
    """`Derivation` plus the standing-stability numbers.

    Attributes:
        standing_stiffness: least eigenvalue of ``Nᵀ(K_p + 2 K_g)N`` at the derived gains (≥ 0 when stable) [mixed N·m/rad, N/m].
        gravity_stiffness: least eigenvalue of ``Nᵀ K_g N`` (negative: the robot falls without its PD).
        stiffening_steps: how many stiffening steps step 3 took.
        sway: horizontal CoM shift of the static deflection at the derived gains [m].
        support_margin: distance from the CoM to the support polygon's edge in the sway's direction [m].
    """

    standing_stiffness: float = 0.0
    gravity_stiffness: float = 0.0
    stiffening_steps: int = 0
    sway: float = 0.0
    support_margin: float = 0.0

    def as_dict(self) -> dict:
        """JSON-ready, rounded."""
        out = super().as_dict()
        out["method"] = "frbench.robots.humanoid_gains (static torques, sag 0.04 rad, standing stability with gravity x2, explicit-PD stability)"
        out["standing_stiffness"] = float(f"{self.standing_stiffness:.4g}")
        out["gravity_stiffness"] = float(f"{self.gravity_stiffness:.4g}")
        out["stiffening_steps"] = self.stiffening_steps
        out["sway"] = float(f"{self.sway:.4g}")
        out["support_margin"] = float(f"{self.support_margin:.4g}")
        return out


@dataclass(frozen=True)
class Support:
    """The support polygon of a humanoid standing at its default pose (root over the origin).

    Attributes:
        polygon: (k, 2) corners, counter-clockwise, world x/y [m].
        com: (3,) whole-body CoM, the lowest foot point at z = 0 [m].
        edge_distance: signed distance from the CoM's ground point to the nearest edge (negative: outside) [m].
        depth: (2,) the polygon's extent along x and y [m].
        sole_length: the largest extent of a foot's geometry along its own axes [m]: the most any pose can stand on.
    """

    polygon: np.ndarray
    com: np.ndarray
    edge_distance: float
    depth: np.ndarray
    sole_length: float = 0.0

    @property
    def tilt_margin(self) -> float:
        """The tilt [rad] that carries the CoM to the nearest edge: edge distance / CoM height."""
        return float(self.edge_distance / self.com[2])

    def margin_towards(self, direction: np.ndarray) -> float:
        """Distance [m] from the CoM to the polygon's edge along ``direction`` (x, y)."""
        u = np.asarray(direction, dtype=float) / max(np.linalg.norm(direction), 1e-12)
        best = np.inf
        for normal, offset in _edges(self.polygon):
            along = normal @ u
            if along > 1e-12:
                best = min(best, (offset - normal @ self.com[:2]) / along)
        return float(best)


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain), counter-clockwise, of (n, 2) points."""
    pts = sorted(set(map(tuple, np.round(points, 9))))
    if len(pts) < 3:
        return np.array(pts)

    def turn(o, a, b):  # z of (a − o) × (b − o): > 0 for a left turn
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and turn(out[-2], out[-1], p) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _edges(polygon: np.ndarray):
    """(outward unit normal, offset) per edge of a counter-clockwise polygon: inside is normal · p <= offset."""
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
        edge = b - a
        length = np.linalg.norm(edge)
        if length < 1e-12:
            continue
        normal = np.array([edge[1], -edge[0]]) / length
        yield normal, float(normal @ a)


def _foot_points(tree, foot: str) -> np.ndarray:
    """(n, 3) points of ``foot``'s collision geometry in its own frame: sphere bottoms, box and cylinder corners."""
    points = []
    for collision in tree.links[foot].collisions:
        if collision.kind == "sphere":
            points.append(collision.origin[:3, 3] - [0.0, 0.0, collision.size[0]])
            continue
        if collision.kind == "box":
            local = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * np.asarray(collision.size) / 2
        elif collision.kind == "cylinder":
            radius, length = collision.size
            ring = np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)]) * radius
            local = np.array([[x, y, e * length / 2] for x, y in ring for e in (-1, 1)])
        else:
            continue
        points += list(local @ collision.origin[:3, :3].T + collision.origin[:3, 3])
    return np.array(points) if points else np.zeros((1, 3))


def support(spec: RobotSpec) -> Support:
    """The support polygon and CoM of ``spec`` at its default pose (module docstring), from the simulated geometry."""
    tree = parse_urdf(sim_robot_file(spec).path)
    poses = link_poses(tree, dict(zip(spec.joint_names, spec.default_pose)))
    local = {foot: _foot_points(tree, foot) for foot in spec.foot_links}
    points = np.vstack([pts @ poses[foot][:3, :3].T + poses[foot][:3, 3] for foot, pts in local.items()])
    lowest = points[:, 2].min()
    polygon = _hull(points[points[:, 2] <= lowest + CONTACT_BAND, :2])
    com = np.array(ground_truth.center_of_mass(spec, [0.0, 0.0, -lowest], [1.0, 0.0, 0.0, 0.0], spec.default_pose))
    if len(polygon) >= 3:
        distance = min(offset - normal @ com[:2] for normal, offset in _edges(polygon))
    else:  # a line or a point: the CoM can at best sit on it
        a, b = polygon[0], polygon[-1]
        t = np.clip((com[:2] - a) @ (b - a) / max((b - a) @ (b - a), 1e-18), 0.0, 1.0)
        distance = -float(np.linalg.norm(com[:2] - (a + t * (b - a))))
    sole = max(float(np.max(np.ptp(pts, axis=0))) for pts in local.values())
    return Support(polygon=polygon, com=com, edge_distance=float(distance), depth=np.ptp(polygon, axis=0), sole_length=sole)


def _contact_jacobian(model, data, q, frames) -> np.ndarray:
    """6-D Jacobians of the feet frames (LOCAL_WORLD_ALIGNED), stacked: (6 k, nv)."""
    import pinocchio

    pinocchio.computeJointJacobians(model, data, q)
    pinocchio.updateFramePlacements(model, data)
    return np.vstack([pinocchio.getFrameJacobian(model, data, f, pinocchio.LOCAL_WORLD_ALIGNED) for f in frames])


def contact_stiffness(spec: RobotSpec):
    """(K_g (nv, nv), N (nv, m), F (6 k,), tau at the joints, pinocchio model, data, q, v indices) at the standing pose.

    ``F`` are the feet's wrenches (world-aligned, at the feet frames [N, N·m]) that carry the weight with the
    least norm (moments weighted as forces at `MOMENT_ARM`); ``K_g`` the symmetric part of ``∂(g − J_cᵀF)/∂q``
    by central differences (F held); ``N`` an orthonormal basis of the null space of ``J_c``.
    """
    import pinocchio

    model, data, q, v_index = static_model(spec)
    nv = model.nv
    zero = np.zeros(nv)
    frames = [model.getFrameId(foot) for foot in spec.foot_links]
    g = pinocchio.rnea(model, data, q, zero, zero).copy()
    Jc = _contact_jacobian(model, data, q, frames)
    weight = np.ones(len(Jc))
    for k in range(len(frames)):
        weight[6 * k + 3: 6 * k + 6] = MOMENT_ARM
    F = weight * np.linalg.lstsq((Jc * weight[:, None])[:, :6].T, g[:6], rcond=None)[0]
    tau = (g - Jc.T @ F)[v_index]

    def load(dv):
        moved = pinocchio.integrate(model, q, dv)
        return pinocchio.rnea(model, data, moved, zero, zero) - _contact_jacobian(model, data, moved, frames).T @ F

    K = np.zeros((nv, nv))
    for k in range(nv):
        dv = np.zeros(nv)
        dv[k] = DIFF_STEP
        K[:, k] = (load(dv) - load(-dv)) / (2 * DIFF_STEP)
    _, s, vt = np.linalg.svd(Jc)
    rank = int(np.sum(s > 1e-9 * s[0]))
    return 0.5 * (K + K.T), vt[rank:].T, F, tau, model, data, q, v_index


def derive_humanoid_gains(spec: RobotSpec, legs: tuple[tuple[str, ...], ...], physics_dt: float | None = None,
                          sidecar_label: str = "sidecar") -> HumanoidDerivation:
    """Kp, Kd and physics step of a humanoid at its default pose (method in the module docstring).

    Args:
        spec: a humanoid spec whose pose, limits, effort and feet are final (gains are ignored).
        legs: per leg, its joints from the pelvis to the foot (legs share gains per position).
        physics_dt: a fixed step [s] (the sidecar's), else the largest stable one.
    """
    import pinocchio

    Kg, N, F, tau_all, model, data, q, v_index = contact_stiffness(spec)
    tau = np.abs(tau_all)
    over = np.flatnonzero(tau > EFFORT_FRACTION * np.asarray(spec.torque_limits))
    if len(over):  # every joint that cannot hold the pose, in one line
        names = [spec.joint_names[i] for i in over]
        needs = ", ".join(f"{n} {tau[i]:.3g} of {spec.torque_limits[i]:.3g}" for n, i in zip(names, over))
        raise RobotFileError(
            f"{spec.urdf_path}: {len(over)} joint(s) need more than {EFFORT_FRACTION:.0%} of their effort limit to hold "
            f"the standing pose ({needs} N·m); set effort.{names[0]}{' and the others' if len(over) > 1 else ''} in "
            f"{sidecar_label} (or a less crouched [default_pose])"
        )
    M = pinocchio.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
    inertia = M[v_index, v_index]
    pinocchio.centerOfMass(model, data, q, True)
    limb = np.zeros(spec.n_joints)
    for i, name in enumerate(spec.joint_names):
        jid = model.getJointId(name)
        lever = np.linalg.norm(np.array(data.com[jid]) - np.array(data.oMi[jid].translation))
        limb[i] = data.mass[jid] * GRAVITY * lever / FLOOR_ANGLE
    roles = _leg_roles(spec, legs)
    kp = np.maximum(tau / SAG, limb)
    for group in roles:
        kp[group] = kp[group].max()

    gravity = N.T @ Kg @ N
    feet = support(spec)
    pinocchio.jacobianCenterOfMass(model, data, q)
    J_com = np.array(data.Jcom)[:2]
    load = np.zeros(len(Kg))
    load[v_index] = -tau_all
    steps = 0
    while True:
        Kp = np.zeros(len(Kg))
        Kp[v_index] = kp
        stiffness = (N.T * Kp) @ N
        values, vectors = np.linalg.eigh(STABILITY_MARGIN * gravity + stiffness)
        if values[0] < 0:  # unstable with gravity doubled: stiffen the weakest mode
            d = (N @ vectors[:, 0])[v_index]
            missing = OVERSHOOT * -values[0]
        else:
            K1 = gravity + stiffness
            x = np.linalg.solve(K1, N.T @ load)
            sway = J_com @ (N @ x)
            allowed = SWAY_FRACTION * feet.margin_towards(sway) if np.linalg.norm(sway) > 1e-12 else np.inf
            if np.linalg.norm(sway) <= allowed or feet.edge_distance <= 0:
                break
            d = (N @ x)[v_index]  # stiffen the deflection's shape until it shrinks by the missing factor
            missing = OVERSHOOT * (np.linalg.norm(sway) / allowed - 1.0) * float(x @ K1 @ x)
        if steps >= MAX_STIFFENING_STEPS:
            raise RobotFileError(
                f"{spec.urdf_path}: no joint stiffness holds the standing pose within its feet after {steps} steps "
                f"(least stiffness {values[0]:.3g}); set kp and [default_pose] in {sidecar_label}"
            )
        share = d**2 * inertia
        kp = kp + missing * share / np.sum(share * d**2)
        for group in roles:
            kp[group] = kp[group].max()
        steps += 1
    kp = np.array([float(f"{v:.4g}") for v in kp])
    kd, dt, b_mode, a_mode = _damping_and_step(spec, legs, M, v_index, kp, inertia, physics_dt, sidecar_label)
    foot_z = F.reshape(len(spec.foot_links), 6)[:, 2]
    return HumanoidDerivation(
        kp=tuple(kp.tolist()), kd=tuple(float(f"{v:.4g}") for v in kd), physics_dt=float(dt),
        static_torque=tuple(tau_all.tolist()), inertia=tuple(inertia.tolist()), foot_force_z=tuple(foot_z.tolist()),
        stability_b=tuple((kp * dt**2 / inertia).tolist()), stability_a=tuple((kd * dt / inertia).tolist()),
        mode_b=float(b_mode), mode_a=float(a_mode),
        standing_stiffness=float(values[0]), gravity_stiffness=float(np.linalg.eigvalsh(gravity)[0]),
        stiffening_steps=steps, sway=float(np.linalg.norm(sway)), support_margin=float(feet.margin_towards(sway)),
    )


def _damping(M: np.ndarray, v_index: np.ndarray, kd: np.ndarray, dt: float) -> np.ndarray:
    """Kd [N·m·s/rad] lowered only where the stiffest damping mode lives, until ``max eig(M⁻¹Kd) dt <= A_MAX``.

    Each pass takes the mode of ``Kd v = λ M v`` with the largest λ and scales each joint's Kd by
    ``(A_MAX / (λ dt))^w``, ``w`` the joint's share of the mode's damping energy (``Kd_j v_j²``, the
    largest 1). Scaling every Kd by one factor (as :mod:`frbench.robots.gains` does) left G1's wrists
    and ankles with a tenth of their damping (wrist yaw 0.013 N·m·s/rad): the hands flailed at
    190 rad/s in a fall and MuJoCo diverged in one of 8 scripted episodes at 2.5 ms.
    """
    L_inv = np.linalg.inv(np.linalg.cholesky(M))
    for _ in range(MAX_STIFFENING_STEPS):
        G = np.zeros_like(M)
        G[v_index, v_index] = kd
        values, vectors = np.linalg.eigh(L_inv @ G @ L_inv.T)
        if values[-1] * dt <= A_MAX:
            break
        mode = (L_inv.T @ vectors[:, -1])[v_index]
        share = kd * mode**2
        kd = kd * (A_MAX / (values[-1] * dt)) ** (share / share.max())
    return kd


def _damping_and_step(spec, legs, M, v_index, kp, inertia, physics_dt, sidecar_label):
    """(Kd, dt, b, a of the stiffest mode): step 5 of the module docstring."""
    rate_kp = _mode_rate(M, v_index, kp)  # [1/s²]
    for dt in ((physics_dt,) if physics_dt else PHYSICS_STEPS):
        b_mode = rate_kp * dt**2
        if b_mode > B_MAX and not physics_dt:
            continue
        kd = _damping(M, v_index, 2.0 * ZETA * np.sqrt(kp * inertia), dt)
        for group in _leg_roles(spec, legs):
            kd[group] = kd[group].min()
        a_mode = _mode_rate(M, v_index, kd) * dt
        if physics_dt and not b_mode + 2 * a_mode < 4.0:
            raise RobotFileError(
                f"{sidecar_label}: physics_dt = {dt:g}: expected a step at which the explicit PD is stable "
                f"(Kp dt²/I of the stiffest mode = {b_mode:.3g}, needs Kp dt²/I + 2 Kd dt/I < 4): a smaller physics_dt or kp"
            )
        return kd, dt, b_mode, a_mode
    worst = int(np.argmax(kp / inertia))
    raise RobotFileError(
        f"{spec.urdf_path}: no stable explicit PD even at {PHYSICS_STEPS[-1]:g} s: the stiffest mode has "
        f"Kp dt²/I = {rate_kp * PHYSICS_STEPS[-1] ** 2:.3g} > {B_MAX:g} (joint {spec.joint_names[worst]!r}, "
        f"{inertia[worst]:.3g} kg·m², Kp {kp[worst]:.3g} N·m/rad); set kp, kd and physics_dt in {sidecar_label}"
    )
