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
)
from frbench.backends.contact_layout import as_slice
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


class MujocoBackend:
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
        qadr, dadr = joint_addresses(self.model, spec)
        self._qadr, self._dadr = as_slice(qadr), as_slice(dadr)
        #: every coordinate is the free joint's or a canonical joint's: `divergence_mask` reads qpos and qvel whole
        self._whole_state = (isinstance(self._qadr, slice) and isinstance(self._dadr, slice)
                             and self._qadr == slice(7, self.model.nq) and self._dadr == slice(6, self.model.nv))
        self.link_names = sim_robot_file(spec).links
        link_body = np.array([self.model.body(name).id for name in self.link_names])
        self._link_body = as_slice(link_body)
        self._root_body = int(link_body[0])
        self._base_mass = float(self.model.body_mass[self._root_body])
        self.has_variants = variants is not None
        if variants is not None:
            specs, assignment, frictions, payloads = variants
            models = []
            for variant, friction, payload in zip(specs, frictions, payloads):
                model = build_model(variant, self.terrain, friction=float(friction))
                model.body_mass[model.body(sim_robot_file(variant).links[0]).id] += payload
                models.append(model)
            expand_variants(self.batch, self.model, models, np.asarray(assignment))
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
        self._terrain_geoms = np.array(
            [g for g in range(self.model.ngeom) if self.model.geom_bodyid[g] == 0], dtype=int
        )
        self._limits = np.asarray(spec.torque_limits)
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
        j = self.spec.n_joints
        strength = np.asarray(params.motor_strength, dtype=float)
        if np.any(strength < 0):
            raise ValueError("motor_strength: expected values >= 0 (the strength scales the PD's force range)")
        self._gain[:, :j, 0] = strength * params.kp
        self._bias[:, :j, 1] = -strength * params.kp
        self._bias[:, :j, 2] = -strength * params.kd
        self._force_range[:, :j, 0] = -strength * self._limits
        self._force_range[:, :j, 1] = strength * self._limits
        friction = np.zeros((self.num_envs, j)) if params.motor_friction is None else params.motor_friction
        self._bias[:, j:, 2] = -np.asarray(friction) / MOTOR_FRICTION_VELOCITY
        self._force_range[:, j:, 0] = -friction
        self._force_range[:, j:, 1] = friction
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
        qpos[:, 0:3] = state.base_pos
        qpos[:, 3:7] = state.base_quat / np.linalg.norm(state.base_quat, axis=1, keepdims=True)
        qpos[:, self._qadr] = state.q
        qvel[:, 0:3] = state.base_linvel
        qvel[:, 3:6] = state.base_angvel
        qvel[:, self._dadr] = state.qd
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
        """(N,) `divergence_mask` of the current state; read from qpos and qvel whole when they hold nothing but
        the root and the canonical joints (|x| < limit is False for NaN and ±inf, so it covers finiteness)."""
        if not self._whole_state:
            return divergence_mask(self._raw_state())
        return ~((np.abs(self._qpos) < DIVERGENCE_LIMIT).all(axis=1) & (np.abs(self._qvel) < DIVERGENCE_LIMIT).all(axis=1))

    def _raw_state(self) -> RobotState:
        qpos, qvel = self._qpos, self._qvel
        return RobotState(
            base_pos=qpos[:, 0:3].copy(),
            base_quat=qpos[:, 3:7].copy(),
            base_linvel=qvel[:, 0:3].copy(),
            base_angvel=qvel[:, 3:6].copy(),
            q=qpos[:, self._qadr].copy(),
            qd=qvel[:, self._dadr].copy(),
        )

    def state(self) -> RobotState:
        """State of every simulation (root frame, canonical joints, applied torques)."""
        state = self._raw_state()
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
        link_force = np.array(self._cfrc_ext[:, self._link_body, 3:6])
        if self._base_force.any():
            link_force[:, 0] -= self._base_force
        return summarize_contacts(self.spec, self.link_names, link_force)

    def close(self) -> None:
        """Release the batch."""
        self.batch = None


def expand_variants(batch: mjbatch.Batch, model: mujoco.MjModel, variants: list[mujoco.MjModel],
                    assignment: np.ndarray) -> list[str]:
    """Run simulation i of ``batch`` (built on ``model``) as ``variants[assignment[i]]``: every model field in
    which a variant differs from ``model`` is expanded and given each simulation's value. The variants must be
    compiled from robots with the same links, joints and geoms (same sizes); returns the expanded fields."""
    changed = []
    for name in sorted(n for n in dir(model) if isinstance(getattr(model, n, None), np.ndarray)):
        base = getattr(model, name)
        values = [getattr(v, name) for v in variants]
        if any(v.shape != base.shape for v in values):
            raise ValueError(f"morphology variants: model field {name} has another shape than the base robot's")
        if all(np.array_equal(v, base) for v in values):
            continue
        if name not in mjbatch.MODEL_FIELDS:
            raise ValueError(f"morphology variants: model field {name} differs between variants but cannot be "
                             "given per-simulation values")
        batch.expand(name)[:] = np.stack(values)[assignment]
        changed.append(name)
    return changed
