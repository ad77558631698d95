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

Device and arrays. The worlds live on ``device`` (``cpu`` or ``cuda:N``, `frbench.backends.devices.parse_device`'s
value, the same ordinal torch uses). The backend works on torch views of Warp's arrays (``wp.to_torch``, no
copies) and hands out its state, contacts and flags either as those tensors on the device (``device_arrays``:
training, where everything above it computes in torch, `frbench.arrays`) or as float64 numpy copies on the host
(evaluation and the Gymnasium envs: the float32 values read into float64, as MuJoCo C's numbers are, and the
summaries computed on the host). Both go through the MuJoCo backend's functions (`state_of`, `contacts_of`,
`write_state`, `state_divergence`). With device arrays a control period runs nothing on the host: no
synchronisation (the divergence and overflow flags are set on the device; an overflow is logged at the next
reset) and, on a GPU, one CUDA graph that also runs the kinematics and centre-of-mass stages of the new state
(``whole_body_com`` then reads ``subtree_com``). On a GPU, Warp keeps its own stream, ordered with torch's
current stream both ways around every Warp call (stream waits, no host synchronisation).

A compiled world (`CompiledWorld`: the ``MjModel``, the variants' model fields, the link names) can be handed in
instead of compiled here: a device bundle's (`frbench.training.device_bundle`), on a machine without the robot
files.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging

import numpy as np

from frbench.arrays import to_host
from frbench.backends.base import (
    CONTROL_DT,
    Contacts,
    PhysicsParams,
    RobotState,
    check_base_force,
    check_targets,
    divergence_mask,
    torque_limit_rows,
)
from frbench.backends.contact_layout import on_device
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
from frbench.backends.mujoco_model import build_model
from frbench.backends.warp_model import (
    BUFFER_OVERFLOW_NAMES,
    NOT_IN_WARP,
    batchable_fields,
    buffer_overflow_mask,
    buffer_sizes,
    import_warp,
    put_batched_model,
)
from frbench.robots.spec import RobotSpec
from frbench.terrains import make_terrain

#: The fields every world has its own value of (module docstring).
PARAM_FIELDS = ("actuator_gainprm", "actuator_biasprm", "actuator_forcerange", "geom_friction", "body_mass",
                "body_subtreemass", "body_invweight0", "dof_invweight0", "actuator_acc0")
#: Height [m] above the terrain at which a diverged world waits at rest for its reset.
PARK_HEIGHT = 100.0

_log = logging.getLogger("frbench.warp")


@dataclasses.dataclass
class CompiledWorld:
    """A world the backend runs: ``model`` (the ``MjModel`` of `build_model`: the robot on the terrain),
    ``fields`` (model field → (K, …) values of each of K morphology variants, the fields in which they differ;
    empty without variants) and ``link_names`` (the simulation URDF's links)."""

    model: object
    fields: dict
    link_names: tuple

    @classmethod
    def of(cls, spec: RobotSpec, terrain, variants=None) -> "CompiledWorld":
        """Compile ``spec`` on ``terrain`` and, with ``variants`` (specs, assignment, frictions, payloads), every
        variant (the fields Warp cannot batch, `NOT_IN_WARP`, left out; another that differs is a ValueError)."""
        from frbench.robots.sim_urdf import sim_robot_file

        model = build_model(spec, terrain)
        fields = {}
        if variants is not None:
            batchable = batchable_fields()
            count = len(variants[0])
            fields = variant_fields(model, variant_models(terrain, variants), np.arange(count),
                                    lambda name: name in batchable or name in NOT_IN_WARP)
            fields = {k: v for k, v in fields.items() if k not in NOT_IN_WARP}
        return cls(model, fields, tuple(sim_robot_file(spec).links))


class MujocoWarpBackend(ModelLayout):
    """N MuJoCo Warp worlds of ``spec`` on ``terrain``. See `frbench.backends.base.Backend` and the module
    docstring."""

    name = "mujoco-warp"

    def __init__(self, spec: RobotSpec, num_envs: int, terrain=None, variants=None, device: str = "cpu",
                 device_arrays: bool = False, world: CompiledWorld | None = None, nconmax: int | None = None,
                 njmax: int | None = None):
        """N worlds of ``spec`` on ``terrain`` (flat if None) on ``device`` (``cpu`` or ``cuda:N``); ``device_arrays``:
        hand out torch tensors on the device instead of numpy copies (module docstring). ``variants``: as in
        `frbench.backends.mujoco_backend.MujocoBackend` (with ``world`` only the assignment is read). ``world``: a
        `CompiledWorld` to run instead of compiling one. ``nconmax`` / ``njmax``: contacts and constraint rows per
        world (default `buffer_sizes`)."""
        import mujoco
        import torch

        wp, mjw = import_warp()
        self._wp, self._mjw, self._torch = wp, mjw, torch
        self.spec = spec
        self.num_envs = n = int(num_envs)
        self.device, self.device_arrays = str(device), bool(device_arrays)
        self._cuda = self.device.startswith("cuda")
        if world is None:
            self.terrain = terrain if terrain is not None else make_terrain("flat", 1, 0)
            world = CompiledWorld.of(spec, self.terrain, variants)
        else:
            self.terrain = terrain
        self.model = world.model
        self.physics_dt = float(self.model.opt.timestep)
        self.substeps = int(round(CONTROL_DT / self.physics_dt))
        self._read_layout(world.link_names)
        self.has_variants = variants is not None
        assignment = np.asarray(variants[1]) if variants is not None else None
        per_world = {k: np.asarray(v)[assignment] for k, v in world.fields.items()} if variants is not None else {}
        default_sizes = buffer_sizes(self.model)
        self.nconmax = int(nconmax or default_sizes[0])
        self.njmax = int(njmax or default_sizes[1])
        with wp.ScopedDevice(self.device):
            self.warp_model = put_batched_model(self.model, n, sorted({*PARAM_FIELDS, *per_world}))
            self.warp_model.opt.warn_overflow = 0  # read from Data.overflow instead of printed
            self.warp_data = mjw.put_data(self.model, mujoco.MjData(self.model), nworld=n, nconmax=self.nconmax,
                                          njmax=self.njmax)
        for name, values in per_world.items():
            getattr(self.warp_model, name).assign(values.astype(np.float32) if values.dtype == np.float64 else values)
        wp.synchronize_device(self.device)  # the model and data in place before torch touches them
        d, m = self.warp_data, self.warp_model
        view = wp.to_torch
        self._qpos, self._qvel, self._ctrl = view(d.qpos), view(d.qvel), view(d.ctrl)
        self._qfrc_actuator, self._cfrc_ext, self._xfrc = view(d.qfrc_actuator), view(d.cfrc_ext), view(d.xfrc_applied)
        self._subtree_com, self._overflow_bits = view(d.subtree_com), view(d.overflow)
        self._fields = {name: view(getattr(m, name)) for name in ("actuator_gainprm", "actuator_biasprm",
                                                                 "actuator_forcerange", "geom_friction", "body_mass")}
        self._overflow_mask = buffer_overflow_mask()
        self._graph = None  # the CUDA graph of one control period, captured on first use (None: not yet tried)
        self._limits = torque_limit_rows(spec, n, variants)  # (J,) or (N, J) [N·m]
        self._base_force = np.zeros((n, 3))
        self._mass_changed = False  # a payload or friction was written since the model was put
        self._com_current = False  # ``subtree_com`` holds the current state's (device arrays: after every period)
        tensor = dict(device=self._qpos.device)
        self._diverged = torch.zeros(n, dtype=torch.bool, **tensor)
        #: Warp's overflow bits (``mjw.OverflowType``) seen since each world's last reset.
        self._overflow = torch.zeros(n, dtype=self._overflow_bits.dtype, **tensor)
        self._tau = torch.zeros(n, spec.n_joints, dtype=self._qpos.dtype, **tensor)
        self._held_qpos, self._held_qvel = torch.zeros_like(self._qpos), torch.zeros_like(self._qvel)
        park = self.model.qpos0.copy()
        park[2] = float(np.max(self.model.geom_pos[self._terrain_geoms, 2], initial=0.0)) + PARK_HEIGHT
        self._park_qpos = torch.as_tensor(park, dtype=self._qpos.dtype, **tensor)
        self._overflow_logged = False
        self.set_params(PhysicsParams.nominal(spec, n))

    # ------------------------------------------------------------------ arrays
    def _out(self, x):
        """``x`` (a tensor of the backend) as the backend hands it out: itself (device arrays) or a host copy,
        float data as float64 (module docstring)."""
        if self.device_arrays:
            return x
        host = to_host(x)
        return host.astype(np.float64) if host.dtype == np.float32 else host.copy()

    def _own(self, value, dtype=None):
        """``value`` (numpy or torch) as a tensor on the backend's device (float32 for float data by default)."""
        torch = self._torch
        tensor = torch.as_tensor(value, device=self._qpos.device)
        if dtype is None and tensor.is_floating_point():
            dtype = self._qpos.dtype
        return tensor if dtype is None else tensor.to(dtype)

    @contextlib.contextmanager
    def _scope(self):
        """Warp on the backend's device; on a GPU its stream ordered with torch's current stream both ways (stream
        waits, no host synchronisation): torch's writes happen before Warp's kernels read them, Warp's results
        before torch reads them."""
        wp = self._wp
        with wp.ScopedDevice(self.device):
            if not self._cuda:
                yield
                return
            torch_stream = wp.stream_from_torch(self._torch.cuda.current_stream(self._qpos.device))
            warp_stream = wp.get_stream(self.device)
            warp_stream.wait_stream(torch_stream)
            yield
            torch_stream.wait_stream(warp_stream)

    def _run(self, function, *args) -> None:
        with self._scope():
            function(*args)

    @property
    def diverged(self):
        """(N,) bool: diverged (or overflowed) since the last reset (a tensor on the device, not to be changed,
        or a numpy copy)."""
        return self._diverged if self.device_arrays else to_host(self._diverged).copy()

    @property
    def overflow(self):
        """(N,) Warp overflow bits (``mjw.OverflowType``) seen since each world's last reset."""
        return self._overflow if self.device_arrays else to_host(self._overflow).astype(np.int64)

    # ------------------------------------------------------------------ params
    def _write_fields(self, values: dict) -> None:
        """Model field name → float64 host values (N, …), written into the worlds (float32)."""
        for name, value in values.items():
            self._fields[name].copy_(self._own(value.astype(np.float32)))

    def set_params(self, params: PhysicsParams) -> None:
        """Per-world gains, motor strength and motor friction (the actuators' fields), terrain friction and
        payload (without variants: theirs are compiled in), as the MuJoCo backend sets them (computed on the host
        in float64, once per call)."""
        fields = {name: to_host(self._fields[name]).astype(np.float64)
                  for name in ("actuator_gainprm", "actuator_biasprm", "actuator_forcerange")}
        write_actuator_params(*fields.values(), params.on_host(), self._limits)
        self._write_fields(fields)
        self.params = params
        if self.has_variants:
            return  # friction and payload are the variants' own
        host = params.on_host()
        payload = np.zeros(self.num_envs) if host.payload is None else host.payload
        if np.all(host.friction == 1.0) and np.all(payload == 0.0) and not self._mass_changed:
            return  # the compiled model already holds these
        friction = to_host(self._fields["geom_friction"]).astype(np.float64)
        mass = to_host(self._fields["body_mass"]).astype(np.float64)
        friction[:, self._terrain_geoms, 0] = host.friction[:, None]
        mass[:, self._root_body] = self._base_mass + payload
        self._write_fields({"geom_friction": friction, "body_mass": mass})
        self._mass_changed = True
        mjw = self._mjw
        self._run(mjw.set_const, self.warp_model, self.warp_data,
                  int(mjw.SetConstGroup.FIXED | mjw.SetConstGroup.INERT0))
        self._run(mjw.forward, self.warp_model, self.warp_data)
        self._com_current = True

    def set_base_force(self, force) -> None:
        """A force [N] (N, 3), world frame, on each root body's centre of mass during every later physics step."""
        self._base_force = check_base_force(to_host(force), self.num_envs)
        self._xfrc[:, self._root_body, 0:3] = self._own(self._base_force)

    # ------------------------------------------------------------------ state
    def reset(self, ids, state: RobotState) -> None:
        """Place worlds ``ids`` in ``state`` (numpy or torch; zero velocities if the state has none); clears their
        flags. The rows are written in the state's namespace (numpy: float64, as MuJoCo C's), then as float32."""
        torch = self._torch
        ids = torch.as_tensor(to_host(ids) if not isinstance(ids, torch.Tensor) else ids, dtype=torch.int64,
                              device=self._qpos.device)
        if ids.numel() == 0:
            return
        self._report_overflow()
        mask = torch.zeros(self.num_envs, dtype=torch.bool, device=self._qpos.device)
        mask[ids] = True
        kept_cfrc, kept_actuator = self._cfrc_ext.clone(), self._qfrc_actuator.clone()
        self._run(self._mjw.reset_data, self.warp_model, self.warp_data, self._wp.from_torch(mask))
        host = state.base_pos is not None and not isinstance(state.base_pos, torch.Tensor)
        rows_qpos = to_host(self._qpos[ids]).astype(np.float64) if host else self._qpos[ids].clone()
        rows_qvel = np.zeros((len(ids), self.model.nv)) if host else torch.zeros_like(self._qvel[ids])
        write_state(rows_qpos, rows_qvel, state, self._qadr, self._dadr)
        self._qpos[ids] = self._own(rows_qpos)
        self._qvel[ids] = self._own(rows_qvel)
        if self._base_force[to_host(ids)].any():  # reset_data cleared xfrc_applied
            self.set_base_force(self._base_force)
        self._tau[ids] = 0.0
        self._overflow[ids] = 0
        self._run(self._mjw.forward, self.warp_model, self.warp_data)
        self._com_current = True
        # the other worlds keep the readings of their last physics step (the protocol's contacts and torques)
        self._cfrc_ext.copy_(torch.where(mask[:, None, None], self._cfrc_ext, kept_cfrc))
        self._qfrc_actuator.copy_(torch.where(mask[:, None], self._qfrc_actuator, kept_actuator))
        placed = divergence_mask(state)
        placed = self._own(to_host(placed)) if host else placed
        qpos, qvel = self._qpos[ids], self._qvel[ids]
        self._diverged[ids] = placed | state_divergence(qpos, qvel, self._qadr, self._dadr, self._whole_state)
        self._held_qpos[ids], self._held_qvel[ids] = qpos, qvel  # what a world diverged at reset reads

    def advance(self) -> None:
        """One control period (``substeps`` ``mjw.step`` calls) of every world with the ``ctrl`` it holds, nothing
        copied to or from the host (on a GPU: one CUDA graph, captured on first use); with device arrays also the
        kinematics and centre-of-mass stages of the new state (module docstring)."""
        wp = self._wp
        if self._graph is None and self._cuda:
            try:
                with self._scope(), wp.ScopedCapture() as capture:
                    self._period()
                self._graph = capture.graph
            except Exception as exc:  # a kernel that cannot be captured: step launch by launch (slower, same physics)
                _log.warning("MuJoCo Warp: no CUDA graph for a control period (%s); stepping launch by launch", exc)
                self._graph = False
        with self._scope():
            if self._graph:
                wp.capture_launch(self._graph)
            else:
                self._period()
        self._com_current = self.device_arrays

    def _period(self) -> None:
        mjw, m, d = self._mjw, self.warp_model, self.warp_data
        for _ in range(self.substeps):
            mjw.step(m, d)
        if self.device_arrays:  # the readings of the new state (`whole_body_com`), inside the graph
            mjw.kinematics(m, d)
            mjw.com_pos(m, d)

    def step(self, joint_targets) -> None:
        """One control period towards ``joint_targets`` (N, n_joints) [rad] (numpy or torch); then the divergence
        and overflow flags (module docstring), set on the device."""
        torch = self._torch
        if isinstance(joint_targets, torch.Tensor):
            if tuple(joint_targets.shape) != (self.num_envs, self.spec.n_joints):
                raise ValueError(f"joint targets of shape {tuple(joint_targets.shape)}, expected "
                                 f"({self.num_envs}, {self.spec.n_joints})")
            targets = self._own(joint_targets)
        else:
            targets = self._own(check_targets(joint_targets, self.num_envs, self.spec.n_joints))
        self._ctrl[:, : self.spec.n_joints] = targets
        diverged = self._diverged[:, None]  # parked at rest until their reset (all worlds step together)
        self._qpos.copy_(torch.where(diverged, self._park_qpos, self._qpos))
        self._qvel.copy_(torch.where(diverged, 0.0, self._qvel))
        self.advance()
        overflow = self._overflow_bits & self._overflow_mask
        self._overflow_bits.zero_()
        newly = ~self._diverged & ((overflow != 0) | state_divergence(self._qpos, self._qvel, self._qadr,
                                                                       self._dadr, self._whole_state))
        self._overflow |= overflow
        self._held_qpos.copy_(torch.where(newly[:, None], self._qpos, self._held_qpos))
        self._held_qvel.copy_(torch.where(newly[:, None], self._qvel, self._held_qvel))
        self._diverged |= newly
        self._tau = torch.where(self._diverged[:, None], 0.0, self._qfrc_actuator[:, on_device(self._dadr, self._tau)])
        if not self.device_arrays:
            self._report_overflow()

    def _report_overflow(self) -> None:
        """Log the first overflow once (on the ``frbench.warp`` logger, with the sizes)."""
        if self._overflow_logged:
            return
        overflow = to_host(self._overflow)
        if not overflow.any():
            return
        self._overflow_logged = True
        bits = int(np.bitwise_or.reduce(overflow))
        mjw = self._mjw
        names = [name for name in BUFFER_OVERFLOW_NAMES if bits & int(getattr(mjw.OverflowType, name))]
        _log.warning("MuJoCo Warp: %s overflow in %d of %d worlds (nconmax %d, njmax %d per world); those worlds "
                     "are flagged diverged", "/".join(names), int(np.count_nonzero(overflow)), self.num_envs,
                     self.nconmax, self.njmax)

    def state(self) -> RobotState:
        """State of every world (root frame, canonical joints, applied torques); a diverged world's is the state
        at which it diverged."""
        torch = self._torch
        diverged = self._diverged[:, None]
        qpos = self._out(torch.where(diverged, self._held_qpos, self._qpos))
        qvel = self._out(torch.where(diverged, self._held_qvel, self._qvel))
        state = state_of(qpos, qvel, self._qadr, self._dadr)
        state.tau = self._out(self._tau.clone())
        return state

    def whole_body_com(self):
        """Whole-body CoM in the world [m] (N, 3) at the current state: the root's ``subtree_com`` after Warp's
        kinematics and centre-of-mass stages on the current ``qpos`` (with device arrays, part of the period)."""
        if not self._com_current:
            self._run(self._mjw.kinematics, self.warp_model, self.warp_data)
            self._run(self._mjw.com_pos, self.warp_model, self.warp_data)
            self._com_current = True
        return self._out(self._subtree_com[:, self._root_body].clone())

    def mass_properties(self):
        """(total robot mass [kg] (N,), whole-body CoM in the world [m] (N, 3)) as Warp holds them."""
        mass = self._out(self._fields["body_mass"])[:, self._root_body :]
        return (mass.sum(dim=1) if self.device_arrays else mass.sum(axis=1)), self.whole_body_com()

    def contacts(self) -> Contacts:
        """Net contact force per link from ``cfrc_ext`` (world frame) at the last physics step, the base force
        taken out (as in the MuJoCo backend)."""
        link = self._cfrc_ext[:, on_device(self._link_body, self._cfrc_ext)]
        return contacts_of(self.spec, self.link_names, self._out(link), self._base_force)

    def close(self) -> None:
        """Release the device arrays."""
        self.warp_data = self.warp_model = None
        self._graph = None
