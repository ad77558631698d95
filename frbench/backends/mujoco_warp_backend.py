"""MuJoCo Warp backend: N simulations as the N worlds of one ``mujoco_warp`` model, on a GPU or Warp's CPU device.

See :mod:`frbench.backends.base` for the conventions. The model is the ``MjModel`` that
`frbench.backends.mujoco_model.build_model` compiles for the MuJoCo backend, unchanged (``mjw.put_model``): the
same bodies, geoms, contacts (elliptic cone, impratio 100, terrain priority), Euler integrator and native PD and
motor-friction actuators, so one control period is ``substeps`` calls of ``mjw.step`` with ``ctrl`` holding the
targets (on a GPU, one CUDA graph of them). The state conversion and the actuator fields are the MuJoCo
backend's own (`frbench.backends.mujoco_backend`). Warp computes in float32, MuJoCo C in float64: the two agree
closely over a short horizon and statistically over an episode (``docs/gpu.md``).

Per-world parameters are model fields with a leading world dimension (Warp's batched fields):

* always: ``actuator_gainprm``, ``actuator_biasprm``, ``actuator_forcerange`` (gains, motor strength, motor
  friction; `write_actuator_params`), ``geom_friction`` (terrain friction), ``body_mass`` (payload) and what
  ``mjw.set_const`` derives from the masses (``body_subtreemass``, ``body_invweight0``, ``dof_invweight0``,
  ``actuator_acc0``), recomputed on the device after a payload changes, as the MuJoCo backend's
  ``Batch.set_const`` does;
* with morphology variants (``variants``): every field in which the compiled variants differ
  (`frbench.backends.mujoco_backend.variant_fields`: ``body_pos``, ``body_mass``, ``body_inertia``,
  ``geom_size``, ``geom_pos``, ``geom_aabb``, …). The fields Warp has no per-world form of, and why that is
  harmless, are `frbench.backends.warp_model.NOT_IN_WARP`; any other field that differs raises a ValueError.

Buffers and overflow: contacts and constraint rows per world are sized for the robot and terrain
(`frbench.backends.warp_model.buffer_sizes`). After every control period the backend reads Warp's
``Data.overflow``; a world with a buffer overflow (`BUFFER_OVERFLOW_NAMES`: constraint rows, contacts, broad
phase, …) computed its physics without some constraints, so it is flagged ``diverged`` (as a simulator error is), its
bits kept in ``overflow`` (N,) and the overflow logged once on the ``frbench.warp`` logger with the sizes.
Reaching the solver's iteration limit is not an overflow (MuJoCo C stops there too).

Diverged worlds are "left alone": the state reads return the state at which they diverged, and until their
next ``reset`` they are parked at rest `PARK_HEIGHT` above the terrain (all worlds step together in Warp; a
parked world makes no contacts and no NaNs).

Device access (training on the GPU): `device_state` gives the Warp arrays as torch tensors (``wp.to_torch``,
no copies) and `advance` runs one control period without any host transfer; the numpy methods of the protocol
(``state``, ``contacts``, ``step``) copy to the host and stay the evaluation's interface.
"""

from __future__ import annotations

import logging

import numpy as np

from frbench.backends.base import (
    CONTROL_DT,
    Contacts,
    PhysicsParams,
    RobotState,
    check_base_force,
    check_targets,
    divergence_mask,
)
from frbench.backends.mujoco_backend import (
    ModelLayout,
    contacts_of,
    state_divergence,
    state_of,
    variant_fields,
    variant_models,
    write_actuator_params,
    write_state,
)
from frbench.backends.mujoco_model import build_model, joint_addresses
from frbench.backends.warp_model import (
    BUFFER_OVERFLOW_NAMES,
    NOT_IN_WARP,
    batchable_fields,
    buffer_overflow_mask,
    buffer_sizes,
    import_warp,
    put_batched_model,
    warp_device,
)
from frbench.robots.spec import RobotSpec
from frbench.terrains import make_terrain

#: The fields every world has its own value of (module docstring).
PARAM_FIELDS = ("actuator_gainprm", "actuator_biasprm", "actuator_forcerange", "geom_friction", "body_mass",
                "body_subtreemass", "body_invweight0", "dof_invweight0", "actuator_acc0")
#: Height [m] above the terrain at which a diverged world waits at rest for its reset.
PARK_HEIGHT = 100.0

_log = logging.getLogger("frbench.warp")


class MujocoWarpBackend(ModelLayout):
    """N MuJoCo Warp worlds of ``spec`` on ``terrain``. See `frbench.backends.base.Backend` and the module
    docstring."""

    name = "mujoco-warp"

    def __init__(self, spec: RobotSpec, num_envs: int, terrain=None, variants=None, device: str | None = None,
                 nconmax: int | None = None, njmax: int | None = None):
        """N worlds of ``spec`` on ``terrain`` (flat if None) on ``device`` (default `warp_device`: ``cuda:0``
        when present, else ``cpu``). ``variants``: as in `frbench.backends.mujoco_backend.MujocoBackend`.
        ``nconmax`` / ``njmax``: contacts and constraint rows per world (default `buffer_sizes`)."""
        import mujoco

        wp, mjw = import_warp()
        self._wp, self._mjw = wp, mjw
        self.spec = spec
        self.num_envs = int(num_envs)
        self.terrain = terrain if terrain is not None else make_terrain("flat", 1, 0)
        self.device = device or warp_device()
        self.model = build_model(spec, self.terrain)
        self.physics_dt = float(self.model.opt.timestep)
        self.substeps = int(round(CONTROL_DT / self.physics_dt))
        self._read_layout()
        self.has_variants = variants is not None
        per_world = {}
        if variants is not None:
            batchable = batchable_fields()
            per_world = variant_fields(self.model, variant_models(self.terrain, variants), np.asarray(variants[1]),
                                       lambda name: name in batchable or name in NOT_IN_WARP)
            per_world = {k: v for k, v in per_world.items() if k not in NOT_IN_WARP}
        default_sizes = buffer_sizes(self.model)
        self.nconmax = int(nconmax or default_sizes[0])
        self.njmax = int(njmax or default_sizes[1])
        with wp.ScopedDevice(self.device):
            self.warp_model = put_batched_model(self.model, self.num_envs, sorted({*PARAM_FIELDS, *per_world}))
            self.warp_model.opt.warn_overflow = 0  # read from Data.overflow after each period instead of printed
            self.warp_data = mjw.put_data(self.model, mujoco.MjData(self.model), nworld=self.num_envs,
                                          nconmax=self.nconmax, njmax=self.njmax)
        for name, values in per_world.items():
            getattr(self.warp_model, name).assign(values.astype(np.float32) if values.dtype == np.float64 else values)
        self._overflow_mask = buffer_overflow_mask()
        self._graph = None  # the CUDA graph of one control period, captured on first use (None: not yet tried)
        self._limits = np.asarray(spec.torque_limits)
        self._tau = np.zeros((self.num_envs, spec.n_joints))
        self._base_force = np.zeros((self.num_envs, 3))
        self._mass_changed = False  # a payload or friction was written since the model was put
        self._com: np.ndarray | None = None
        self.diverged = np.zeros(self.num_envs, dtype=bool)
        #: (N,) Warp overflow bits (``mjw.OverflowType``) seen since each world's last reset.
        self.overflow = np.zeros(self.num_envs, dtype=np.int64)
        self._held_qpos = np.zeros((self.num_envs, self.model.nq))
        self._held_qvel = np.zeros((self.num_envs, self.model.nv))
        self._park_qpos = self.model.qpos0.copy()
        self._park_qpos[2] = float(np.max(self.model.geom_pos[self._terrain_geoms, 2], initial=0.0)) + PARK_HEIGHT
        self._overflow_logged = False
        self.set_params(PhysicsParams.nominal(spec, self.num_envs))

    # ------------------------------------------------------------------ arrays
    def _read(self, array) -> np.ndarray:
        """A host copy of a Warp array, float64 for float data."""
        values = array.numpy()
        return values.astype(np.float64) if values.dtype == np.float32 else values.copy()

    def _run(self, function, *args) -> None:
        with self._wp.ScopedDevice(self.device):
            function(*args)

    # ------------------------------------------------------------------ params
    def set_params(self, params: PhysicsParams) -> None:
        """Per-world gains, motor strength and motor friction (the actuators' fields), terrain friction and
        payload (without variants: theirs are compiled in), as the MuJoCo backend sets them."""
        m = self.warp_model
        gain, bias, force_range = (self._read(m.actuator_gainprm), self._read(m.actuator_biasprm),
                                   self._read(m.actuator_forcerange))
        write_actuator_params(gain, bias, force_range, params, self._limits)
        for array, values in ((m.actuator_gainprm, gain), (m.actuator_biasprm, bias),
                              (m.actuator_forcerange, force_range)):
            array.assign(values.astype(np.float32))
        self.params = params
        if self.has_variants:
            return  # friction and payload are the variants' own
        payload = np.zeros(self.num_envs) if params.payload is None else params.payload
        if np.all(params.friction == 1.0) and np.all(payload == 0.0) and not self._mass_changed:
            return  # the compiled model already holds these
        friction, mass = self._read(m.geom_friction), self._read(m.body_mass)
        friction[:, self._terrain_geoms, 0] = params.friction[:, None]
        mass[:, self._root_body] = self._base_mass + payload
        m.geom_friction.assign(friction.astype(np.float32))
        m.body_mass.assign(mass.astype(np.float32))
        self._mass_changed, self._com = True, None
        mjw = self._mjw
        self._run(mjw.set_const, m, self.warp_data, int(mjw.SetConstGroup.FIXED | mjw.SetConstGroup.INERT0))
        self._run(mjw.forward, m, self.warp_data)

    def set_base_force(self, force: np.ndarray) -> None:
        """A force [N] (N, 3), world frame, on each root body's centre of mass during every later physics step."""
        self._base_force = check_base_force(force, self.num_envs)
        xfrc = self._read(self.warp_data.xfrc_applied)
        xfrc[:, self._root_body, 0:3] = self._base_force
        self.warp_data.xfrc_applied.assign(xfrc.astype(np.float32))

    # ------------------------------------------------------------------ state
    def reset(self, ids, state: RobotState) -> None:
        """Place worlds ``ids`` in ``state`` (zero velocities if the state has none); clears their flags."""
        ids = np.asarray(ids, dtype=np.int64)
        if ids.size == 0:
            return
        wp, mjw, d = self._wp, self._mjw, self.warp_data
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[ids] = True
        kept_cfrc, kept_actuator = self._read(d.cfrc_ext), self._read(d.qfrc_actuator)
        self._run(mjw.reset_data, self.warp_model, d, wp.array(mask, dtype=bool, device=self.device))
        qpos, qvel = self._read(d.qpos), self._read(d.qvel)
        rows_qpos, rows_qvel = qpos[ids], np.zeros((ids.size, self.model.nv))
        write_state(rows_qpos, rows_qvel, state, self._qadr, self._dadr)
        qpos[ids], qvel[ids] = rows_qpos, rows_qvel
        d.qpos.assign(qpos.astype(np.float32))
        d.qvel.assign(qvel.astype(np.float32))
        if self._base_force[ids].any():  # reset_data cleared xfrc_applied
            self.set_base_force(self._base_force)
        self._tau[ids] = 0.0
        self.overflow[ids] = 0
        self._com = None
        self._run(mjw.forward, self.warp_model, d)
        # the other worlds keep the readings of their last physics step (the protocol's contacts and torques)
        cfrc = np.where(mask[:, None, None], self._read(d.cfrc_ext), kept_cfrc)
        actuator = np.where(mask[:, None], self._read(d.qfrc_actuator), kept_actuator)
        d.cfrc_ext.assign(cfrc.astype(np.float32))
        d.qfrc_actuator.assign(actuator.astype(np.float32))
        self.diverged[ids] = divergence_mask(state) | state_divergence(qpos[ids], qvel[ids], self._qadr, self._dadr,
                                                                       self._whole_state)
        self._held_qpos[ids], self._held_qvel[ids] = qpos[ids], qvel[ids]  # what a world diverged at reset reads

    def advance(self) -> None:
        """One control period (``substeps`` ``mjw.step`` calls) of every world with the ``ctrl`` the device holds,
        nothing copied to or from the host (on a GPU: one CUDA graph, captured on first use). The numpy
        `step` wraps it; the device training loop calls it after writing ``device_state()["ctrl"]``."""
        wp, mjw = self._wp, self._mjw
        if self._graph is None and self.device.startswith("cuda"):
            try:
                with wp.ScopedDevice(self.device), wp.ScopedCapture() as capture:
                    for _ in range(self.substeps):
                        mjw.step(self.warp_model, self.warp_data)
                self._graph = capture.graph
            except Exception as exc:  # a kernel that cannot be captured: step launch by launch (slower, same physics)
                _log.warning("MuJoCo Warp: no CUDA graph for a control period (%s); stepping launch by launch", exc)
                self._graph = False
        self._com = None
        if self._graph:
            wp.capture_launch(self._graph)
            return
        with wp.ScopedDevice(self.device):
            for _ in range(self.substeps):
                mjw.step(self.warp_model, self.warp_data)

    def step(self, joint_targets) -> None:
        """One control period towards ``joint_targets`` (N, n_joints) [rad]; then the divergence and overflow
        checks (module docstring)."""
        targets = check_targets(joint_targets, self.num_envs, self.spec.n_joints)
        d = self.warp_data
        if self.diverged.all():
            return
        ctrl = np.zeros((self.num_envs, self.model.nu), dtype=np.float32)
        ctrl[:, : self.spec.n_joints] = targets
        d.ctrl.assign(ctrl)
        if self.diverged.any():
            self._park(self.diverged)
        self.advance()
        qpos, qvel = self._read(d.qpos), self._read(d.qvel)
        overflow = d.overflow.numpy() & self._overflow_mask
        if overflow.any():
            d.overflow.zero_()
            self._report_overflow(overflow)
        newly = ~self.diverged & ((overflow != 0) | state_divergence(qpos, qvel, self._qadr, self._dadr,
                                                                      self._whole_state))
        self.overflow |= overflow
        self._held_qpos[newly], self._held_qvel[newly] = qpos[newly], qvel[newly]
        self.diverged |= newly
        self._tau = np.where(self.diverged[:, None], 0.0, self._read(d.qfrc_actuator)[:, self._dadr])

    def _park(self, rows: np.ndarray) -> None:
        """Put worlds ``rows`` (N,) bool at rest `PARK_HEIGHT` above the terrain (module docstring)."""
        d = self.warp_data
        qpos, qvel = self._read(d.qpos), self._read(d.qvel)
        qpos[rows], qvel[rows] = self._park_qpos, 0.0
        d.qpos.assign(qpos.astype(np.float32))
        d.qvel.assign(qvel.astype(np.float32))

    def _report_overflow(self, overflow: np.ndarray) -> None:
        if self._overflow_logged:
            return
        self._overflow_logged = True
        _, mjw = self._wp, self._mjw
        bits = int(np.bitwise_or.reduce(overflow))
        names = [name for name in BUFFER_OVERFLOW_NAMES if bits & int(getattr(mjw.OverflowType, name))]
        _log.warning("MuJoCo Warp: %s overflow in %d of %d worlds (nconmax %d, njmax %d per world); those worlds "
                     "are flagged diverged", "/".join(names), int(np.count_nonzero(overflow)), self.num_envs,
                     self.nconmax, self.njmax)

    def state(self) -> RobotState:
        """State of every world (root frame, canonical joints, applied torques); a diverged world's is the state
        at which it diverged."""
        qpos, qvel = self._read(self.warp_data.qpos), self._read(self.warp_data.qvel)
        if self.diverged.any():
            qpos[self.diverged], qvel[self.diverged] = self._held_qpos[self.diverged], self._held_qvel[self.diverged]
        state = state_of(qpos, qvel, self._qadr, self._dadr)
        state.tau = self._tau.copy()
        return state

    def whole_body_com(self) -> np.ndarray:
        """Whole-body CoM in the world [m] (N, 3) at the current state: the root's ``subtree_com`` after Warp's
        kinematics and centre-of-mass stage on the current ``qpos`` (which the next step recomputes anyway)."""
        if self._com is None:
            self._run(self._mjw.kinematics, self.warp_model, self.warp_data)
            self._run(self._mjw.com_pos, self.warp_model, self.warp_data)
            self._com = self._read(self.warp_data.subtree_com)[:, self._root_body]
        return self._com.copy()

    def mass_properties(self) -> tuple[np.ndarray, np.ndarray]:
        """(total robot mass [kg] (N,), whole-body CoM in the world [m] (N, 3)) as Warp holds them."""
        return self._read(self.warp_model.body_mass)[:, self._root_body :].sum(axis=1), self.whole_body_com()

    def contacts(self) -> Contacts:
        """Net contact force per link from ``cfrc_ext`` (world frame) at the last physics step, the base force
        taken out (as in the MuJoCo backend)."""
        cfrc = self._read(self.warp_data.cfrc_ext)
        return contacts_of(self.spec, self.link_names, cfrc[:, self._link_body], self._base_force)

    def device_state(self) -> dict:
        """The Warp arrays of the worlds as torch tensors on the backend's device, sharing memory (``wp.to_torch``:
        writes go to the simulation). Keys: Data ``qpos`` (N, nq), ``qvel`` (N, nv), ``ctrl`` (N, nu: PD targets
        in columns 0 … J−1), ``qfrc_actuator`` (N, nv), ``cfrc_ext`` (N, nbody, 6: torque, force),
        ``xfrc_applied`` (N, nbody, 6: force, torque), ``subtree_com`` (N, nbody, 3), ``overflow`` (N,) int
        (Warp's bits, `buffer_overflow_mask`); Model ``actuator_gainprm`` / ``actuator_biasprm`` (N, nu, 10),
        ``actuator_forcerange`` (N, nu, 2), ``geom_friction`` (N, ngeom, 3), ``body_mass`` (N, nbody); and the
        index bookkeeping ``qadr`` / ``dadr`` (the canonical joints' qpos / qvel columns), ``link_body`` (the
        links' body ids), ``root_body``. float32 throughout; free joint qpos[0:7] = position, quaternion wxyz,
        qvel[0:6] = world linear velocity, body angular velocity (the protocol's frames)."""
        wp, d, m = self._wp, self.warp_data, self.warp_model
        arrays = {name: getattr(d, name) for name in ("qpos", "qvel", "ctrl", "qfrc_actuator", "cfrc_ext",
                                                      "xfrc_applied", "subtree_com", "overflow")}
        arrays.update({name: getattr(m, name) for name in ("actuator_gainprm", "actuator_biasprm",
                                                           "actuator_forcerange", "geom_friction", "body_mass")})
        tensors = {name: wp.to_torch(array) for name, array in arrays.items()}
        qadr, dadr = joint_addresses(self.model, self.spec)
        link_body = np.array([self.model.body(name).id for name in self.link_names])
        return {**tensors, "qadr": qadr, "dadr": dadr, "link_body": link_body, "root_body": self._root_body}

    def close(self) -> None:
        """Release the device arrays."""
        self.warp_data = self.warp_model = None
        self._graph = None

