"""MuJoCo backend: N simulations on ``mujoco.batch.Batch`` (a thread pool, one MjData each).

See :mod:`frbench.backends.base` for the conventions. MuJoCo's free joint
already reports what frbench wants: root link frame position, quaternion
w-first, linear velocity in the world frame and angular velocity in the body
frame, so the conversion here is only index bookkeeping.

The actuation is MuJoCo's own (native PD and motor-friction actuators, see
`frbench.backends.mujoco_model`), so one control period is ONE
``Batch.step(nstep=substeps)`` call: one dispatch to the thread pool instead
of one per physics step, and nothing more (the contact forces and actuator
torques read afterwards are those of the last physics step, as the conventions
say). Every per-simulation parameter (gains, strength,
motor friction, terrain friction, payload, and the morphology variants' masses,
inertias, dimensions) is an expanded model field of one batch
(``Batch.expand``), so nothing is recompiled when they change. The whole-body
centre of mass at the current state comes from a second, robot-only batch
(`frbench.backends.mujoco_com`), built the first time it is asked for.
"""

from __future__ import annotations

import os

import mujoco
import numpy as np
from mujoco import batch as mjbatch

from frbench.backends.base import (
    CONTROL_DT,
    DIVERGENCE_LIMIT,
    MOTOR_FRICTION_VELOCITY,
    Contacts,
    PhysicsParams,
    RobotState,
    check_base_force,
    check_targets,
    divergence_mask,
    summarize_contacts,
    torque_limit_rows,
)
from frbench.arrays import copy_of, is_host, like, namespace
from frbench.backends.contact_layout import as_slice, on_device, vector_norm
from frbench.backends.mujoco_com import CentreOfMass
from frbench.backends.mujoco_model import build_model, joint_addresses
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec
from frbench.terrains import make_terrain

#: MuJoCo's warnings that mean a simulation blew up (it then resets that MjData itself).
_INSTABILITY = as_slice(np.array([int(getattr(mujoco.mjtWarning, w))
                                  for w in ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC")]))


def default_threads() -> int:
    """Threads for the batch: ``$FRBENCH_MUJOCO_THREADS``, else all cores (2 on the reference machine)."""
    return int(os.environ.get("FRBENCH_MUJOCO_THREADS") or max(1, os.cpu_count() or 1))


class ModelLayout:
    """Where a backend built on `build_model`'s ``self.model`` finds ``self.spec``'s state (`_read_layout`)."""

    def _read_layout(self, link_names: tuple[str, ...] | None = None) -> None:
        """Set ``link_names`` (given, or the simulation URDF's) and the addresses: ``_qadr`` / ``_dadr`` (the
        canonical joints' qpos / qvel columns, `as_slice`), ``_whole_state`` (`holds_whole_state`), ``_link_body``
        (the links' bodies), ``_root_body``, ``_base_mass`` [kg] (the root's compiled mass) and ``_terrain_geoms``
        (the world body's geoms)."""
        model = self.model
        qadr, dadr = joint_addresses(model, self.spec)
        self._qadr, self._dadr = as_slice(qadr), as_slice(dadr)
        #: every coordinate is the free joint's or a canonical joint's: `divergence_mask` reads qpos and qvel whole
        self._whole_state = holds_whole_state(model, self._qadr, self._dadr)
        self.link_names = tuple(link_names) if link_names is not None else sim_robot_file(self.spec).links
        link_body = np.array([model.body(name).id for name in self.link_names])
        self._link_body = as_slice(link_body)
        self._root_body = int(link_body[0])
        self._base_mass = float(model.body_mass[self._root_body])
        self._terrain_geoms = np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] == 0], dtype=int)


class MujocoBackend(ModelLayout):
    """N MuJoCo simulations of ``spec`` on ``terrain``. See `frbench.backends.base.Backend`."""

    name = "mujoco"

    def __init__(self, spec: RobotSpec, num_envs: int, terrain=None, nthread: int | None = None, variants=None):
        """N simulations of ``spec`` on ``terrain`` (flat if None).

        ``variants``: optional (specs, assignment, frictions, payloads) for
        morphology randomisation — robots with the same links and joints as
        ``spec`` (other dimensions and masses); simulation i runs
        ``specs[assignment[i]]`` with its terrain friction and root payload [kg]
        (``set_params`` then changes gains, strength and motor friction only).
        Each variant is compiled once and the model fields in which it differs
        from ``spec``'s model are written into the batch's expanded fields.
        """
        self.spec = spec
        self.num_envs = int(num_envs)
        self.terrain = terrain if terrain is not None else make_terrain("flat", 1, 0)
        self.model = build_model(spec, self.terrain)
        self.physics_dt = float(self.model.opt.timestep)
        self.substeps = int(round(CONTROL_DT / self.physics_dt))
        self.batch = mjbatch.Batch(self.model, self.num_envs, nthread or default_threads(), persistent=True)
        self._read_layout()
        self.has_variants = variants is not None
        if variants is not None:
            expand_variants(self.batch, self.model, variant_models(self.terrain, variants), np.asarray(variants[1]))
        self._qpos = self.batch.bind("qpos")
        self._qvel = self.batch.bind("qvel")
        self._ctrl = self.batch.bind("ctrl")
        self._cfrc_ext = self.batch.bind("cfrc_ext")
        self._qfrc_actuator = self.batch.bind("qfrc_actuator")
        self._xfrc_applied = self.batch.bind("xfrc_applied")
        self._gain = self.batch.expand("actuator_gainprm")
        self._bias = self.batch.expand("actuator_biasprm")
        self._force_range = self.batch.expand("actuator_forcerange")
        self._base_force = np.zeros((self.num_envs, 3))
        self._limits = torque_limit_rows(spec, self.num_envs, variants)  # (J,) or (N, J) [N·m]
        self._tau = np.zeros((self.num_envs, spec.n_joints))
        self.diverged = np.zeros(self.num_envs, dtype=bool)
        self._com_of: CentreOfMass | None = None  # built by the first `whole_body_com`
        self._com: np.ndarray | None = None  # the CoM of the current state, once computed
        self._com_fields_changed = True  # the batch's kinematic fields changed since they were mirrored
        self.set_params(PhysicsParams.nominal(spec, self.num_envs))

    # ------------------------------------------------------------------ params
    def set_params(self, params: PhysicsParams) -> None:
        """Per-simulation gains, motor strength and motor friction (the actuators' expanded fields), terrain
        friction and payload (without variants: theirs are compiled in)."""
        write_actuator_params(self._gain, self._bias, self._force_range, params, self._limits)
        self.params = params
        if self.has_variants:
            return  # friction and payload are the variants' own
        payload = np.zeros(self.num_envs) if params.payload is None else params.payload
        if np.all(params.friction == 1.0) and np.all(payload == 0.0) and self.batch.expanded("body_mass") is None:
            return  # the compiled model already holds these
        friction = self.batch.expand("geom_friction")
        mass = self.batch.expand("body_mass")
        friction[:, self._terrain_geoms, 0] = params.friction[:, None]
        mass[:, self._root_body] = self._base_mass + payload
        self.batch.set_const()
        self._com_fields_changed, self._com = True, None
        self.batch.forward(stage=mujoco.mjtStage.mjSTAGE_VEL)  # the stages the next step continues from

    def set_base_force(self, force: np.ndarray) -> None:
        """A force [N] (N, 3), world frame, on each root body's centre of mass during every later physics step."""
        self._base_force = check_base_force(force, self.num_envs)
        xfrc = np.array(self._xfrc_applied)
        xfrc[:, self._root_body, 0:3] = self._base_force
        self._xfrc_applied[:] = xfrc

    # ------------------------------------------------------------------ state
    def reset(self, ids, state: RobotState) -> None:
        """Place simulations ``ids`` in ``state`` (zero velocities if the state has none)."""
        ids = np.asarray(ids, dtype=np.int32)
        if ids.size == 0:
            return
        self.batch.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        if self._base_force[ids].any():  # mj_resetData cleared xfrc_applied
            self.set_base_force(self._base_force)
        qpos = self._qpos[ids]
        qvel = np.zeros((ids.size, self.model.nv))
        write_state(qpos, qvel, state, self._qadr, self._dadr)
        self._qpos[ids] = qpos
        self._qvel[ids] = qvel
        self._ctrl[ids] = 0.0
        self._tau[ids] = 0.0
        self._com = None
        warnings_before = self.batch.warning[ids][:, _INSTABILITY, 0].sum(axis=1)
        self.batch.forward(ids)
        bad = self.batch.warning[ids][:, _INSTABILITY, 0].sum(axis=1) > warnings_before
        self.diverged[ids] = bad | divergence_mask(state)

    def step(self, joint_targets) -> None:
        """One control period: ``substeps`` MuJoCo steps in one batch call, the actuators tracking the targets."""
        targets = check_targets(joint_targets, self.num_envs, self.spec.n_joints)
        ids = np.flatnonzero(~self.diverged).astype(np.int32) if self.diverged.any() else None
        if ids is not None and ids.size == 0:
            return
        self._ctrl[:, : self.spec.n_joints] = targets
        warnings_before = self.batch.warning[:, _INSTABILITY, 0].sum(axis=1)
        self._com = None
        try:
            self.batch.step(ids, nstep=self.substeps)
        except mjbatch.SimulationError as exc:
            self.diverged[np.asarray(exc.ids)] = True
        self.diverged |= self.batch.warning[:, _INSTABILITY, 0].sum(axis=1) > warnings_before
        self._tau = np.where(self.diverged[:, None], 0.0, self._qfrc_actuator[:, self._dadr])
        self.diverged |= self._divergence()

    def _divergence(self) -> np.ndarray:
        """(N,) `divergence_mask` of the current state (`state_divergence`)."""
        return state_divergence(self._qpos, self._qvel, self._qadr, self._dadr, self._whole_state)

    def state(self) -> RobotState:
        """State of every simulation (root frame, canonical joints, applied torques)."""
        state = state_of(self._qpos, self._qvel, self._qadr, self._dadr)
        state.tau = self._tau.copy()
        return state

    def whole_body_com(self) -> np.ndarray:
        """Whole-body CoM in the world [m] (N, 3) at the current state: the root's ``subtree_com`` as the batch's
        position stage would compute it (`frbench.backends.mujoco_com`)."""
        if self._com is None:
            if self._com_of is None:
                robot_alone = build_model(self.spec, make_terrain("flat", 1, 0))
                self._com_of = CentreOfMass(self.model, robot_alone, self.num_envs, self._root_body,
                                            self.batch.nthread)
            if self._com_fields_changed:
                self._com_of.mirror(self.batch)
                self._com_fields_changed = False
            self._com = self._com_of(self._qpos)
        return self._com.copy()

    def mass_properties(self) -> tuple[np.ndarray, np.ndarray]:
        """(total robot mass [kg] (N,), whole-body CoM in the world [m] (N, 3)) as MuJoCo holds them."""
        mass = self.batch.expanded("body_mass")
        masses = (mass if mass is not None else np.tile(self.model.body_mass, (self.num_envs, 1)))[:, self._root_body :]
        return masses.sum(axis=1), self.whole_body_com()

    def contacts(self) -> Contacts:
        """Net contact force per link from ``cfrc_ext`` (world frame), summarised by group. MuJoCo's ``cfrc_ext``
        also holds ``xfrc_applied``: the base force (`set_base_force`) is taken out again, so that an assist
        force is no contact (as in PyBullet, whose contacts are contact points)."""
        return contacts_of(self.spec, self.link_names, self._cfrc_ext[:, self._link_body], self._base_force)

    def close(self) -> None:
        """Release the batch."""
        self.batch = None


def holds_whole_state(model: mujoco.MjModel, qadr, dadr) -> bool:
    """Whether every coordinate of ``model`` is the root's free joint or a canonical joint (``qadr``, ``dadr``:
    `as_slice` of `joint_addresses`), so that `state_divergence` may read qpos and qvel whole."""
    return (isinstance(qadr, slice) and isinstance(dadr, slice)
            and qadr == slice(7, model.nq) and dadr == slice(6, model.nv))


def write_actuator_params(gain: np.ndarray, bias: np.ndarray, force_range: np.ndarray, params: PhysicsParams,
                          limits: np.ndarray) -> None:
    """Write ``params``' gains, strength and motor friction into the per-simulation actuator fields of a model
    built by `build_model`, in place: ``gain`` (N, nu, 10) ``actuator_gainprm``, ``bias`` (N, nu, 10)
    ``actuator_biasprm``, ``force_range`` (N, nu, 2) ``actuator_forcerange``; ``limits`` (J,) or (N, J) torque
    limits [N·m]. The formula is `write_actuator_fields`'."""
    strength = np.asarray(params.motor_strength, dtype=float)
    if np.any(strength < 0):
        raise ValueError("motor_strength: expected values >= 0 (the strength scales the PD's force range)")
    friction = np.zeros((len(strength), limits.shape[-1])) if params.motor_friction is None else params.motor_friction
    write_actuator_fields(gain, bias, force_range, params.kp, params.kd, strength, np.asarray(friction), limits)


def write_actuator_fields(gain, bias, force_range, kp, kd, strength, motor_friction, limits,
                          friction_velocity: float = MOTOR_FRICTION_VELOCITY) -> None:
    """The one formula from a world's PD gains, motor strength and motor friction to its actuator fields, in
    place, for numpy arrays (MuJoCo C, Warp on the host) and torch tensors on a device alike.

    Args:
        gain: (N, nu, 10) ``actuator_gainprm``.
        bias: (N, nu, 10) ``actuator_biasprm``.
        force_range: (N, nu, 2) ``actuator_forcerange``.
        kp, kd: (N, J) PD gains [N·m/rad, N·m·s/rad].
        strength: (N, J) motor strength factors, ≥ 0 (scales the PD's gains and force range).
        motor_friction: (N, J) Coulomb motor friction [N·m].
        limits: (J,) torque limits [N·m], or (N, J) per world (morphology variants of different sizes).
        friction_velocity: the velocity [rad/s] at which the friction actuator saturates.

    Rows 0 … J−1 are the PD actuators, J … 2J−1 the motor friction (`frbench.backends.mujoco_model`).
    """
    j = limits.shape[-1]
    gain[:, :j, 0] = strength * kp
    bias[:, :j, 1] = -strength * kp
    bias[:, :j, 2] = -strength * kd
    force_range[:, :j, 0] = -strength * limits
    force_range[:, :j, 1] = strength * limits
    bias[:, j:, 2] = -motor_friction / friction_velocity
    force_range[:, j:, 0] = -motor_friction
    force_range[:, j:, 1] = motor_friction


def write_state(qpos, qvel, state: RobotState, qadr, dadr) -> None:
    """Write ``state`` (rows match) into ``qpos`` (n, nq) and ``qvel`` (n, nv) in place: the root's free joint
    (quaternion normalised) and the canonical joints at ``qadr`` / ``dadr``. numpy or torch (the state's arrays
    converted into ``qpos``'s namespace and device)."""
    def own(value):
        return value if is_host(qpos) else like(value, qpos)

    quat = own(state.base_quat)
    qpos[:, 0:3] = own(state.base_pos)
    qpos[:, 3:7] = quat / vector_norm(quat)[:, None]
    qpos[:, on_device(qadr, qpos)] = own(state.q)
    qvel[:, 0:3] = own(state.base_linvel)
    qvel[:, 3:6] = own(state.base_angvel)
    qvel[:, on_device(dadr, qvel)] = own(state.qd)


def state_of(qpos, qvel, qadr, dadr) -> RobotState:
    """The `RobotState` (fresh arrays, no torques) held in ``qpos`` (N, nq) and ``qvel`` (N, nv), numpy or torch."""
    return RobotState(
        base_pos=copy_of(qpos[:, 0:3]),
        base_quat=copy_of(qpos[:, 3:7]),
        base_linvel=copy_of(qvel[:, 0:3]),
        base_angvel=copy_of(qvel[:, 3:6]),
        q=copy_of(qpos[:, on_device(qadr, qpos)]),
        qd=copy_of(qvel[:, on_device(dadr, qvel)]),
    )


def state_divergence(qpos, qvel, qadr, dadr, whole_state: bool):
    """(N,) `divergence_mask` of the state in ``qpos`` / ``qvel``; read from them whole when they hold nothing but
    the root and the canonical joints (`holds_whole_state`; |x| < limit is False for NaN and ±inf, so it covers
    finiteness). numpy or torch."""
    if not whole_state:
        return divergence_mask(state_of(qpos, qvel, qadr, dadr))
    xp = namespace(qpos)
    return ~(xp.all(xp.abs(qpos) < DIVERGENCE_LIMIT, axis=1) & xp.all(xp.abs(qvel) < DIVERGENCE_LIMIT, axis=1))


def contacts_of(spec: RobotSpec, link_names: tuple[str, ...], link_cfrc_ext, base_force: np.ndarray) -> Contacts:
    """`Contacts` from the links' ``cfrc_ext`` rows (N, n_links, 6: torque, force; world frame; numpy or torch), the
    base force (N, 3) [N] (numpy) taken out of the root's (MuJoCo's ``cfrc_ext`` also holds ``xfrc_applied``)."""
    link_force = copy_of(link_cfrc_ext[..., 3:6])
    if base_force.any():
        link_force[:, 0] -= base_force if is_host(link_force) else like(base_force, link_force)
    return summarize_contacts(spec, link_names, link_force)


def variant_models(terrain, variants) -> list[mujoco.MjModel]:
    """The compiled models of morphology ``variants`` (specs, assignment, frictions, payloads) on ``terrain``:
    each with its terrain friction and its payload [kg] on the root body."""
    specs, _, frictions, payloads = variants
    models = []
    for variant, friction, payload in zip(specs, frictions, payloads):
        model = build_model(variant, terrain, friction=float(friction))
        model.body_mass[model.body(sim_robot_file(variant).links[0]).id] += payload
        models.append(model)
    return models


def variant_fields(model: mujoco.MjModel, variants: list[mujoco.MjModel], assignment: np.ndarray,
                   batchable) -> dict[str, np.ndarray]:
    """Every model field in which a variant differs from ``model``, with each simulation's value
    ((N, *shape): ``variants[assignment[i]]``'s). ``batchable(name)`` says whether a field can take
    per-simulation values (a ValueError names the first that differs and cannot); the variants must be compiled
    from robots with the same links, joints and geoms (same sizes)."""
    changed = {}
    for name in sorted(n for n in dir(model) if isinstance(getattr(model, n, None), np.ndarray)):
        base = getattr(model, name)
        values = [getattr(v, name) for v in variants]
        if any(v.shape != base.shape for v in values):
            raise ValueError(f"morphology variants: model field {name} has another shape than the base robot's")
        if all(np.array_equal(v, base) for v in values):
            continue
        if not batchable(name):
            raise ValueError(f"morphology variants: model field {name} differs between variants but cannot be "
                             "given per-simulation values")
        changed[name] = np.stack(values)[assignment]
    return changed


def expand_variants(batch: mjbatch.Batch, model: mujoco.MjModel, variants: list[mujoco.MjModel],
                    assignment: np.ndarray) -> list[str]:
    """Run simulation i of ``batch`` (built on ``model``) as ``variants[assignment[i]]``: every model field in
    which a variant differs from ``model`` is expanded and given each simulation's value (`variant_fields`);
    returns the expanded fields."""
    changed = variant_fields(model, variants, assignment, lambda name: name in mjbatch.MODEL_FIELDS)
    for name, values in changed.items():
        batch.expand(name)[:] = values
    return list(changed)
