"""The backend protocol: N simulations of one robot on one terrain, batched.

Conventions (every backend converts at its edge; nothing above this layer
knows which simulator runs):

* SI units; world frame z up; gravity −9.81 m/s² along z.
* Base pose is the pose of the URDF **root link frame** (not its inertial
  frame): ``base_pos`` (N, 3) [m], ``base_quat`` (N, 4) **w, x, y, z**.
* ``base_linvel`` (N, 3) [m/s] of the root frame origin in the world frame;
  ``base_angvel`` (N, 3) [rad/s] in the **body** frame.
* Joint arrays (N, n_joints) follow the robot spec's canonical joint order:
  ``q`` [rad], ``qd`` [rad/s], ``tau`` [N·m] (the torque applied at the last
  physics step).
* Actuation, identical in every backend (`actuator_torque`): at every physics step
  ``tau = motor_strength · clip(kp (q* − q) − kd qd, ±torque_limit) − f · clip(qd / v_f, ±1)``,
  the last term a Coulomb motor friction of ``motor_friction`` f [N·m], linear
  below v_f = `MOTOR_FRICTION_VELOCITY` (zero unless domain randomisation sets it).
  Every term is explicit in the state at the start of the physics step: MuJoCo
  computes it with native actuators (`frbench.backends.mujoco_model`), PyBullet
  in numpy. One control period is 0.02 s (50 Hz) = ``control_dt / physics_dt``
  physics steps; the physics step comes from the robot spec.
* Contacts (`Contacts`) are read at the last physics step of a control
  period and include every contact acting on a link (terrain and self).
* Friction: the robot's links have coefficient 1 and the terrain the
  per-simulation ``friction``; each backend combines them so the effective
  coefficient of a robot–terrain contact equals ``friction`` (MuJoCo: geom
  priority; Bullet: product with 1). No restitution, no joint damping, no
  velocity damping of bodies.
* A simulation that diverges (NaN, explosion, a simulator error) is flagged
  in ``diverged`` and left alone; the others go on. ``reset`` clears the flag.
* Arrays: a backend hands out its state, contacts and flags as arrays of one namespace (`frbench.arrays`):
  numpy on the host for the CPU simulators (float64), torch tensors on the backend's device for MuJoCo Warp
  when it is built with ``device_arrays`` (training; float32). It accepts targets, states, parameters and forces
  as numpy arrays or as arrays of its own namespace. The summaries below (`divergence_mask`, `Contacts`) are
  written once for both.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Protocol

import numpy as np

from frbench.arrays import copy_of, namespace
from frbench.backends.contact_layout import contact_layout, on_device, vector_norm
from frbench.robots.spec import RobotSpec
from frbench.control import CONTROL_DT  # noqa: F401  (the control period [s], re-exported for the backends)

#: A state with |value| above this (m, rad, m/s, rad/s) is treated as diverged.
DIVERGENCE_LIMIT = 1e3
#: A link counts as in contact when its net contact force exceeds this [N].
CONTACT_FORCE_THRESHOLD = 1.0


@dataclass
class RobotState:
    """Kinematic state of N robots; see the module docstring for frames and units."""

    base_pos: np.ndarray
    base_quat: np.ndarray
    base_linvel: np.ndarray
    base_angvel: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray | None = None

    @classmethod
    def at_rest(cls, base_pos, base_quat, q) -> "RobotState":
        """States with zero velocities: base_pos (N, 3) [m], base_quat (N, 4) wxyz, q (N, n_joints) [rad]."""
        base_pos, q = np.atleast_2d(base_pos).astype(float), np.atleast_2d(q).astype(float)
        n = len(base_pos)
        return cls(
            base_pos=base_pos,
            base_quat=np.broadcast_to(np.atleast_2d(base_quat), (n, 4)).astype(float).copy(),
            base_linvel=np.zeros((n, 3)),
            base_angvel=np.zeros((n, 3)),
            q=np.broadcast_to(q, (n, q.shape[-1])).copy(),
            qd=np.zeros((n, q.shape[-1])),
        )

    @classmethod
    def standing(cls, spec: RobotSpec, num_envs: int, clearance: float = 0.01) -> "RobotState":
        """Upright at the default pose, feet ``clearance`` [m] above flat ground at z = 0."""
        pos = np.tile([0.0, 0.0, spec.nominal_height + clearance], (num_envs, 1))
        return cls.at_rest(pos, [1.0, 0.0, 0.0, 0.0], np.tile(spec.default_pose, (num_envs, 1)))

    def take(self, ids) -> "RobotState":
        """The states of simulations ``ids`` (copies, in the arrays' namespace)."""
        return RobotState(**{f.name: (None if getattr(self, f.name) is None else copy_of(getattr(self, f.name)[ids]))
                             for f in fields(self)})

    def copy(self) -> "RobotState":
        """A deep copy."""
        return self.take(slice(None))

    def on_host(self) -> "RobotState":
        """These states as float64 numpy arrays (themselves when they are numpy arrays; a copy from a device)."""
        from frbench.arrays import is_host, to_host

        if is_host(self.base_pos):
            return self
        return RobotState(**{f.name: (None if getattr(self, f.name) is None
                                      else to_host(getattr(self, f.name)).astype(np.float64)) for f in fields(self)})


@dataclass
class Contacts:
    """Contact readings of N robots at the last physics step.

    Attributes:
        link_force: (N, n_links, 3) net contact force on each simulated link,
            world frame [N], links in the simulation URDF's order.
        group_contact: (N, n_contact_groups) bool, a group's links touch anything
            (force above `CONTACT_FORCE_THRESHOLD`).
        foot_force: (N, n_feet) norm of the net contact force on each foot [N].
        foot_contact: (N, n_feet) bool.
        knee_force_xy: (N, n_knee_groups) norm of the horizontal part of the net
            contact force on each knee group [N].
        body_force_max: (N,) largest net contact force on any non-foot link [N].
    """

    link_force: np.ndarray
    group_contact: np.ndarray
    foot_force: np.ndarray
    foot_contact: np.ndarray
    knee_force_xy: np.ndarray
    body_force_max: np.ndarray


@dataclass
class PhysicsParams:
    """Per-simulation physical parameters (domain randomisation without recompiling).

    Attributes:
        kp: (N, n_joints) PD stiffness [N·m/rad].
        kd: (N, n_joints) PD damping [N·m·s/rad].
        motor_strength: (N, n_joints) torque scale [-].
        friction: (N,) terrain friction coefficient [-].
        payload: (N,) mass added to the root link at its CoM [kg].
        motor_friction: (N, n_joints) Coulomb friction torque of each joint [N·m], or None for none.
    """

    kp: np.ndarray
    kd: np.ndarray
    motor_strength: np.ndarray
    friction: np.ndarray
    payload: np.ndarray = field(default=None)
    motor_friction: np.ndarray | None = None

    def like(self, ref) -> "PhysicsParams":
        """These parameters as arrays of ``ref``'s namespace, device and float dtype (themselves for numpy ``ref``);
        converted once per device and kept with the parameters (which are not changed after they are set)."""
        from frbench.arrays import is_host, like

        if is_host(ref):
            return self
        converted = self.__dict__.setdefault("_converted", {})
        key = (str(ref.device), str(ref.dtype))
        if key not in converted:
            converted[key] = PhysicsParams(**{f.name: (None if getattr(self, f.name) is None
                                                       else like(getattr(self, f.name), ref)) for f in fields(self)})
        return converted[key]

    def on_host(self) -> "PhysicsParams":
        """These parameters as numpy arrays (themselves when they are)."""
        from frbench.arrays import is_host, to_host

        if all(getattr(self, f.name) is None or is_host(getattr(self, f.name)) for f in fields(self)):
            return self
        return PhysicsParams(**{f.name: (None if getattr(self, f.name) is None else to_host(getattr(self, f.name)))
                                for f in fields(self)})

    @classmethod
    def nominal(cls, spec: RobotSpec, num_envs: int, friction: float = 1.0) -> "PhysicsParams":
        """The spec's gains, full strength, the given friction, no payload."""
        ones = np.ones((num_envs, spec.n_joints))
        return cls(
            kp=ones * np.asarray(spec.kp),
            kd=ones * np.asarray(spec.kd),
            motor_strength=ones.copy(),
            friction=np.full(num_envs, float(friction)),
            payload=np.zeros(num_envs),
        )


#: Joint speed [rad/s] below which the motor's Coulomb friction is linear in q̇ (f·clip(q̇ / v_f, ±1); a sign()
#: would chatter under explicit integration at rest). The saturated line is what a MuJoCo actuator computes
#: natively (affine bias, force range ±f); its slope at rest, f / v_f, is that of f·tanh(q̇ / v_f).
MOTOR_FRICTION_VELOCITY = 0.1


def torque_limit_rows(spec: RobotSpec, num_envs: int, variants=None) -> np.ndarray:
    """Torque limits [N·m]: ``spec``'s (n_joints,), or each simulation's robot's (N, n_joints) when the morphology
    ``variants`` (specs, assignment, …) differ in them (robots of different sizes)."""
    own = np.asarray(spec.torque_limits)
    if variants is None or all(s.torque_limits == spec.torque_limits for s in variants[0]):
        return own
    return np.array([variants[0][k].torque_limits for k in np.asarray(variants[1])], dtype=float).reshape(num_envs, -1)


def actuator_torque(params: PhysicsParams, limits: np.ndarray, targets: np.ndarray, q: np.ndarray,
                    qd: np.ndarray, rows=slice(None)) -> np.ndarray:
    """The joint torques [N·m] of every backend's explicit PD actuator (module docstring), for ``rows``.

    ``targets``, ``q``, ``qd``: the rows' (…, n_joints) arrays; ``limits`` (n_joints,) torque limits [N·m], or
    (N, n_joints) per simulation (`torque_limit_rows`).
    """
    if limits.ndim == 2:
        limits = limits[rows]
    kp, kd, strength = params.kp[rows], params.kd[rows], params.motor_strength[rows]
    tau = strength * np.minimum(np.maximum(kp * (targets - q) - kd * qd, -limits), limits)
    if params.motor_friction is not None:
        tau = tau - params.motor_friction[rows] * np.clip(qd / MOTOR_FRICTION_VELOCITY, -1.0, 1.0)
    return tau


class Backend(Protocol):
    """What a task needs from a simulator. See the module docstring for conventions."""

    name: str
    spec: RobotSpec
    num_envs: int
    physics_dt: float
    substeps: int
    link_names: tuple[str, ...]
    diverged: np.ndarray

    def reset(self, ids: np.ndarray, state: RobotState) -> None:
        """Place simulations ``ids`` in ``state`` (rows match ``ids``); clears their divergence flag."""

    def step(self, joint_targets: np.ndarray) -> None:
        """Advance every simulation one control period towards ``joint_targets`` (N, n_joints) [rad]."""

    def state(self) -> RobotState:
        """Current state of all simulations (fresh arrays)."""

    def contacts(self) -> Contacts:
        """Contact readings at the last physics step."""

    def set_params(self, params: PhysicsParams) -> None:
        """Set every simulation's physical parameters (arrays with N rows)."""

    def mass_properties(self) -> tuple[np.ndarray, np.ndarray]:
        """(total robot mass [kg] (N,), whole-body CoM [m] (N, 3)) as the simulator holds them."""

    def whole_body_com(self) -> np.ndarray:
        """Whole-body centre of mass of every robot in the world [m] (N, 3), at the current state, in one
        vectorised read (cheap enough for every control step)."""

    def set_base_force(self, force: np.ndarray) -> None:
        """Apply ``force`` [N] (N, 3, world frame) at each root link's centre of mass in every later physics
        step, until changed (training aids such as a vertical assist force; evaluation never sets it)."""

    def close(self) -> None:
        """Free the simulator."""


def divergence_mask(state: RobotState):
    """(N,) bool: rows with a non-finite or exploding value (numpy or torch, as the state's arrays)."""
    parts = [state.base_pos, state.base_quat, state.base_linvel, state.base_angvel, state.q, state.qd]
    xp = namespace(*parts)
    stacked = xp.concat([xp.reshape(p, (p.shape[0], -1)) for p in parts], axis=1)
    return ~xp.all(xp.isfinite(stacked) & (xp.abs(stacked) < DIVERGENCE_LIMIT), axis=1)


def summarize_contacts(spec: RobotSpec, link_names: tuple[str, ...], link_force: np.ndarray) -> Contacts:
    """`Contacts` from per-link net forces (N, n_links, 3) — the same rule for every backend. Each summary is
    computed when it is first read (`SummarizedContacts`)."""
    return SummarizedContacts(contact_layout(link_names, spec.contact_groups, spec.knee_groups, spec.foot_links),
                              link_force)


class SummarizedContacts(Contacts):
    """`Contacts` whose summaries are computed from ``link_force`` (N, n_links, 3) by ``layout`` (a
    `frbench.backends.contact_layout.ContactLayout`) when first read, then kept: a control step whose
    contacts nobody reads costs the copy of the forces only. Reads as the dataclass does (fields, equality)."""

    def __init__(self, layout, link_force: np.ndarray):  # noqa: D107 (the summaries are filled in on demand)
        self.link_force = link_force
        self._layout = layout

    def __getattr__(self, name: str):
        rule = _SUMMARIES.get(name)
        if rule is None or "_layout" not in self.__dict__:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        value = rule(self, self._layout)
        self.__dict__[name] = value
        return value


#: How each summary of `SummarizedContacts` follows from the link forces (and the summaries it names).
_SUMMARIES = {
    "norm": lambda c, layout: vector_norm(c.link_force),
    "group_contact": lambda c, layout: layout.group_contact(c.norm > CONTACT_FORCE_THRESHOLD),
    "foot_force": lambda c, layout: c.norm[:, on_device(layout.feet, c.norm)],
    "foot_contact": lambda c, layout: c.foot_force > CONTACT_FORCE_THRESHOLD,
    "knee_force_xy": lambda c, layout: vector_norm(layout.knee_sum(c.link_force)[..., :2]),
    "body_force_max": lambda c, layout: (namespace(c.norm).max(c.norm[:, on_device(layout.non_foot, c.norm)], axis=1)
                                         if layout.has_non_foot else namespace(c.norm).zeros_like(c.norm[:, 0])),
}


def check_base_force(force: np.ndarray, num_envs: int) -> np.ndarray:
    """``force`` as a finite (num_envs, 3) float array [N], or a ValueError naming the problem."""
    force = np.asarray(force, dtype=float)
    if force.shape != (num_envs, 3) or not np.isfinite(force).all():
        raise ValueError(f"base force: expected a finite ({num_envs}, 3) array [N], got shape {force.shape}")
    return force.copy()


def check_targets(joint_targets: np.ndarray, num_envs: int, n_joints: int) -> np.ndarray:
    """``joint_targets`` as a float64 (N, n_joints) array, or a ValueError naming the shape."""
    targets = np.asarray(joint_targets, dtype=np.float64)
    if targets.shape != (num_envs, n_joints):
        raise ValueError(f"joint targets of shape {targets.shape}, expected ({num_envs}, {n_joints})")
    return targets
