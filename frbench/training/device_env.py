"""Training that stays on the device: rsl-rl's `VecEnv` over MuJoCo Warp, every step's work as torch tensors.

`DeviceTrainingEnv` is the device twin of `frbench.training.env.RecoveryTrainingEnv` (the CPU trainer): the same
config (`TrainEnvConfig`), observation groups, reward table, success test and curriculum rule, for N worlds of one
``mujoco_warp`` model on a GPU (or Warp's CPU device for tests). What the CPU makes once — the compiled grid
world, the batch's robots, the terrain rasters and a bank of settled fallen starts — comes in a
`frbench.training.device_bundle.DeviceBundle`; after that nothing goes to the host per step:

* actions → targets → physics: q* = clip(q̊ + scale·a, limits) written into Warp's ``ctrl`` (shared with torch
  through ``wp.to_torch``), one control period of ``substeps`` ``mjw.step`` calls and the kinematics of the new
  state (on a GPU one CUDA graph);
* the policy's observations, history, the critic's privileged view and the estimator's labels: the one
  implementation of `frbench.tasks.observations` and `frbench.training.observation_groups.privileged_groups`
  on tensors; the height scan and the terrain height from the bundle's rasters; the whole-body CoM is MuJoCo's
  ``subtree_com`` of the root (payload included), contacts from ``cfrc_ext`` by the robot's contact layout;
* rewards: `frbench.training.rewards.compute_rewards` on tensors (the resolved table of the CPU trainer);
* the success test: `frbench.tasks.success.SuccessTracker` on tensors;
* termination: episodes end together after ``episode_steps`` control steps (as in the CPU trainer); a world
  that diverges or overflows Warp's buffers is put back at its episode's start at rest and counts as dead
  (reward 0, no success) until the episode ends;
* resets and the start distribution: each environment starts from a bank entry of its (tile, robot variant),
  drawn with torch's generator on the device; the curriculum (`frbench.training.curriculum` rule: window, up /
  down thresholds, a uniform redraw above the top level) is per-environment level tensors.

Logging happens once per episode end (the statistics) and once per iteration (the reward-term means the run
reads); ``extras["log"]`` carries nothing per step.

Each episode's physics (gains, motor strength, motor friction) is drawn on the device as the CPU trainer draws
it (the first episode's is the CPU trainer's own draw, from the bundle), written into the worlds' actuator
fields by the formula MuJoCo C's backend uses (`frbench.backends.mujoco_backend.write_actuator_fields`).
Differences from the CPU trainer, by design of this first version: starts come from the bank (settled under nominal gains) instead of a fresh settle per episode; no demo, rise or assist starts, no
held actions, no base controller (the bundle refuses such configs).
"""

from __future__ import annotations

import contextlib

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from frbench.backends.base import CONTACT_FORCE_THRESHOLD, RobotState
from frbench.backends.mujoco_backend import write_actuator_fields
from frbench.tasks.observations import flatten, proprioception
from frbench.tasks.success import StepSignals, SuccessTracker
from frbench.training.curriculum import TerrainCurriculum, moved_levels
from frbench.training.device_bundle import check_device_config
from frbench.training.height_raster import HALF_SIZE, RESOLUTION
from frbench.training.observation_groups import privileged_groups
from frbench.training.reward_inputs import RewardInputs
from frbench.training.rewards import compute_rewards, term_arguments
from frbench.training.step_reward import HEAD_OFFSET_M, upper_body_joints

#: Largest |qpos|, |qvel| entry of a healthy world (`frbench.backends.base.DIVERGENCE_LIMIT`).
DIVERGENCE_LIMIT = 1e3
#: MuJoCo model fields Warp's model does not hold; variants may differ in them
#: (`frbench.backends.mujoco_warp_backend._NOT_IN_WARP`, repeated here: that module imports PyBullet's terrain
#: code, which the GPU machine lacks).
_NOT_IN_WARP = frozenset({"body_sameframe", "bvh_aabb", "dof_M0", "dof_length"})
#: Warp's overflow bits that mean a buffer was too small (`frbench.backends.mujoco_warp_backend`).
_BUFFER_OVERFLOWS = ("NEFC", "NJMAX_NNZ", "BROADPHASE", "NARROWPHASE", "CCD", "HFIELD", "NVMAX", "EPA_HORIZON")


class DeviceSpec:
    """The robot facts the run and the checkpoint read (`RobotSpec`'s fields that matter here), from a bundle."""

    def __init__(self, robot: dict):
        self.name, self.kind = robot["name"], robot["kind"]
        self.joint_names = tuple(robot["joint_names"])
        self.n_joints = len(self.joint_names)
        self.default_pose = tuple(robot["default_pose"])
        self.joint_lower, self.joint_upper = tuple(robot["joint_lower"]), tuple(robot["joint_upper"])
        self.contact_groups = tuple(robot["contact_groups"])


class DeviceCurriculum:
    """Per-environment terrain family and level as tensors, moved by `frbench.training.curriculum.moved_levels`,
    the CPU trainer's rule (one level up when a block of ``window`` episodes succeeded at least
    ``promote_threshold`` of the time, down below ``demote_threshold``, a uniform redraw above ``max_level``)."""

    def __init__(self, families: tuple[str, ...], family: torch.Tensor, level: torch.Tensor, generator):
        rule = TerrainCurriculum(1, np.random.default_rng(0), families=families)
        self.families, self.max_level, self.window = tuple(families), rule.max_level, rule.window
        self.promote, self.demote = rule.promote_threshold, rule.demote_threshold
        self.family, self.level = family, level
        self._successes = torch.zeros_like(level)
        self._episodes = torch.zeros_like(level)
        self.generator = generator

    def update(self, judged: torch.Tensor, success: torch.Tensor) -> None:
        """Record the episodes just finished by the environments ``judged`` (N,) bool, ``success`` (N,) bool."""
        self._episodes += judged.long()
        self._successes += (judged & success).long()
        ready = judged & (self._episodes >= self.window)

        def redraw(over: torch.Tensor) -> torch.Tensor:
            return torch.randint(1, self.max_level + 1, over.shape, device=over.device, generator=self.generator)

        new = moved_levels(self.level, self._successes, self._episodes, redraw, promote=self.promote,
                           demote=self.demote, max_level=self.max_level)
        self.level = torch.where(ready, new, self.level)
        self._successes = torch.where(ready, 0, self._successes)
        self._episodes = torch.where(ready, 0, self._episodes)

    def stats(self) -> dict[str, torch.Tensor]:
        """As `TerrainCurriculum.stats`, as 0-d tensors."""
        level = self.level.double()
        out = {"level/all": level.mean(), "level/at_max": (self.level == self.max_level).double().mean()}
        for i, name in enumerate(self.families):
            mine = self.family == i
            out[f"level/{name}"] = (level * mine).sum() / mine.sum().clamp(min=1)
        return out

    def state_dict(self) -> dict:
        """Plain Python state (the run's checkpoint)."""
        return {"families": list(self.families), "family": self.family.tolist(), "level": self.level.tolist(),
                "successes": self._successes.tolist(), "episodes": self._episodes.tolist()}

    def load_state_dict(self, state: dict) -> None:
        """Restore `state_dict`'s values."""
        device = self.level.device
        self.family = torch.tensor(state["family"], device=device)
        self.level = torch.tensor(state["level"], device=device)
        self._successes = torch.tensor(state["successes"], device=device)
        self._episodes = torch.tensor(state["episodes"], device=device)


class TermMeans:
    """Each reward term's mean per env step, summed on the device and read once (``means``, the run's curve)."""

    def __init__(self):
        self._sums: dict[str, torch.Tensor] = {}
        self._count = 0

    def add(self, terms: dict[str, torch.Tensor], alive: torch.Tensor) -> None:
        n = alive.sum().clamp(min=1)
        for name, value in terms.items():
            mean = (value * alive).sum() / n
            self._sums[name] = self._sums[name] + mean if name in self._sums else mean
        self._count += 1

    def means(self) -> dict[str, float]:
        out = {f"reward_{k}": float(v) / max(self._count, 1) for k, v in self._sums.items()}
        self._sums, self._count = {}, 0
        return out


class DeviceTrainingEnv(VecEnv):
    """See the module docstring. ``bundle``: a `DeviceBundle`; ``device``: ``"cuda"`` / ``"cuda:0"`` / ``"cpu"``
    (Warp's device and the tensors'); ``seed``: torch's generator for the bank draws and curriculum redraws."""

    def __init__(self, bundle, device: str = "cpu", seed: int | None = None):
        cfg = bundle.config
        self.cfg_obj = cfg
        self.cfg = {"env": {k: (str(v) if k == "reward" else v) for k, v in cfg.to_dict().items()}}
        check_device_config(cfg)
        self.device = device = "cuda:0" if device == "cuda" else device
        self.num_envs = n = cfg.num_envs
        a = bundle.arrays
        self.spec = DeviceSpec(bundle.meta["robot"])
        self.num_actions = self.spec.n_joints
        self.max_episode_length = cfg.episode_steps
        self.episode_length_buf = torch.zeros(n, dtype=torch.long, device=device)
        self.rng = np.random.default_rng(cfg.seed)  # the run saves it; draws here come from `generator`
        self.generator = torch.Generator(device=device)
        self.seed = cfg.seed if seed is None else int(seed)
        self.generator.manual_seed(self.seed)
        self.env_steps = 0
        self.last_episode_stats: dict[str, float] = {}
        self.reward_means = TermMeans()
        self.env_masses = a["masses"]
        self.specs = [self.spec]
        self._worlds(bundle)

        def t(name, dtype=torch.float32):
            return torch.as_tensor(np.array(a[name]), dtype=dtype, device=device)

        self.default_pose = torch.tensor(self.spec.default_pose, dtype=torch.float32, device=device)
        self.lower = torch.tensor(self.spec.joint_lower, dtype=torch.float32, device=device)
        self.upper = torch.tensor(self.spec.joint_upper, dtype=torch.float32, device=device)
        self.action_scale = float(cfg.action_scale)
        self.kp, self.kd, self.motor_strength = t("kp"), t("kd"), t("motor_strength")
        self.friction, self.payload, self.masses = t("friction"), t("payload"), t("masses")
        self.nominal_height = t("nominal_height")
        self.qadr, self.dadr = t("qadr", torch.long), t("dadr", torch.long)
        self.link_body, self.membership = t("link_body", torch.long), t("membership")
        self.feet, self.knees = t("feet", torch.long), t("knees", torch.long)
        self.root_body = int(bundle.meta["root_body"])
        self.heights, self.centres = t("heights"), t("centres")
        self.raster_n = int(a["heights"].shape[1])
        self.floor = float(bundle.meta["floor"])
        self.tile_of_cell = t("tile_of_cell", torch.long)
        self.curriculum = DeviceCurriculum(cfg.families, t("family", torch.long), t("level", torch.long),
                                           self.generator)
        self._bank(a)
        self.reward_config = bundle.reward
        self.upper_body = torch.as_tensor(upper_body_joints(self.spec), device=device)
        self.head = bundle.meta.get("head")
        self.physics = bundle.meta.get("physics")  # the per-episode draw's ranges (None: nominal physics)
        if self.physics is not None:
            self._nominal_kp = torch.tensor(self.physics["nominal_kp"], device=device)
            self._nominal_kd = torch.tensor(self.physics["nominal_kd"], device=device)
            self._torque_limits = torch.tensor(self.physics["torque_limits"], device=device)
            wp, m = self._wp, self.warp_model
            self._gain, self._bias = wp.to_torch(m.actuator_gainprm), wp.to_torch(m.actuator_biasprm)
            self._force_range = wp.to_torch(m.actuator_forcerange)
        self._arguments = None
        self.episodes_started = 0
        self._new_episodes()

    # ------------------------------------------------------------------ the worlds
    def _worlds(self, bundle) -> None:
        """The ``mujoco_warp`` model with per-world fields (the variants', the actuators'), its data and their
        torch views."""
        import dataclasses

        import mujoco

        from frbench.backends.warp_model import batchable_fields, import_warp, put_batched_model
        from frbench.tasks.protocol import CONTROL_DT

        wp, mjw = import_warp()
        self._wp, self._mjw = wp, mjw
        model, a, n = bundle.model, bundle.arrays, self.num_envs
        self.model = model
        self.substeps = int(round(CONTROL_DT / float(model.opt.timestep)))
        batchable = batchable_fields()  # fields Warp holds per world; the others (`_NOT_IN_WARP`) it does not use
        assignment = np.asarray(a["assignment"])
        per_world = {name[len("variant/"):]: a[name][assignment] for name in a if name.startswith("variant/")}
        unknown = sorted(k for k in per_world if k not in batchable and k not in _NOT_IN_WARP
                         and k in {f.name for f in dataclasses.fields(mjw.Model)})
        if unknown:
            raise ValueError(f"morphology variants differ in model fields Warp cannot batch: {unknown}")
        per_world = {k: v for k, v in per_world.items() if k in batchable}
        per_world.update(actuator_gainprm=a["gainprm"], actuator_biasprm=a["biasprm"],
                         actuator_forcerange=a["forcerange"])
        self.wp_device = "cuda:0" if self.device.startswith("cuda") else "cpu"
        buffers = bundle.meta["buffers"]
        with wp.ScopedDevice(self.wp_device):
            self.warp_model = put_batched_model(model, n, sorted(per_world))
            self.warp_model.opt.warn_overflow = 0
            self.warp_data = mjw.put_data(model, mujoco.MjData(model), nworld=n, nconmax=int(buffers["nconmax"]),
                                          njmax=int(buffers["njmax"]))
        for name, values in per_world.items():
            array = getattr(self.warp_model, name)
            array.assign(np.ascontiguousarray(values, dtype=np.float32 if values.dtype == np.float64 else values.dtype))
        wp.synchronize_device(self.wp_device)  # the model and data in place before torch touches them
        d = self.warp_data
        self.qpos, self.qvel, self.ctrl = wp.to_torch(d.qpos), wp.to_torch(d.qvel), wp.to_torch(d.ctrl)
        self.qfrc_actuator, self.cfrc_ext = wp.to_torch(d.qfrc_actuator), wp.to_torch(d.cfrc_ext)
        self.subtree_com, self.xpos, self.xmat = wp.to_torch(d.subtree_com), wp.to_torch(d.xpos), wp.to_torch(d.xmat)
        self.overflow = wp.to_torch(d.overflow)
        self._overflow_mask = 0
        for name in _BUFFER_OVERFLOWS:
            self._overflow_mask |= int(getattr(mjw.OverflowType, name))
        self._graph = None

    @contextlib.contextmanager
    def _scope(self):
        """Warp on the environment's device; on a GPU its stream ordered with torch's current stream both ways
        (stream waits, no host synchronisation): torch's writes (``ctrl``, reset states) happen before Warp's
        kernels read them, Warp's results before torch reads them. Warp keeps its own stream, on which the CUDA
        graph is captured (a legacy default stream cannot be captured)."""
        wp = self._wp
        with wp.ScopedDevice(self.wp_device):
            if not self.wp_device.startswith("cuda"):
                yield
                return
            torch_stream, warp_stream = wp.stream_from_torch(torch.cuda.current_stream()), wp.get_stream(self.wp_device)
            warp_stream.wait_stream(torch_stream)
            yield
            torch_stream.wait_stream(warp_stream)

    def advance(self) -> None:
        """One control period of every world with the ``ctrl`` held, then the kinematics and centre-of-mass stage on
        the new state (``xpos``, ``xmat``, ``subtree_com`` current, as the CPU backends' readings are; the step
        itself computes them before integrating). On a GPU one CUDA graph, captured on first use, launched on
        torch's stream; nothing crosses to the host."""
        wp = self._wp
        with self._scope():
            if self._graph is None and self.wp_device.startswith("cuda"):
                with wp.ScopedCapture() as capture:
                    self._period()
                self._graph = capture.graph
            if self._graph is not None:
                wp.capture_launch(self._graph)
                return
            self._period()

    def _period(self) -> None:
        mjw, m, d = self._mjw, self.warp_model, self.warp_data
        for _ in range(self.substeps):
            mjw.step(m, d)
        mjw.kinematics(m, d)
        mjw.com_pos(m, d)

    def _forward(self) -> None:
        with self._scope():
            self._mjw.forward(self.warp_model, self.warp_data)

    # ------------------------------------------------------------------ starts and curriculum
    def _bank(self, a) -> None:
        """The settled starts on the device, grouped by (tile, variant) cell; a cell without entries borrows its
        tile's."""
        tiles, variants = np.asarray(a["bank_tile"]), np.asarray(a["bank_variant"])
        k = int(max(variants.max(initial=0), np.asarray(a["assignment"]).max(initial=0))) + 1
        t = int(a["heights"].shape[0])
        key = tiles * k + variants
        order = np.argsort(key, kind="stable")
        counts = np.bincount(key, minlength=t * k)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        for cell in np.flatnonzero(counts == 0):  # borrow the tile's other variants (all entries of the tile)
            mine = np.flatnonzero(tiles[order] == cell // k)
            if mine.size:
                starts[cell], counts[cell] = mine[0], mine.size
        dev = self.device
        self.bank_qpos = torch.as_tensor(a["bank_qpos"][order], device=dev)
        self.bank_qvel = torch.as_tensor(a["bank_qvel"][order], device=dev)
        self.cell_start = torch.as_tensor(starts, device=dev)
        self.cell_count = torch.as_tensor(counts, device=dev)
        self.variant = torch.as_tensor(np.asarray(a["assignment"]), device=dev)
        self.num_variants = k

    def _draw_physics(self) -> None:
        """Each environment's physics for the next episode, drawn on the device as the CPU trainer draws it
        (`TrainingRobots.episode_params`: one Kp and one Kd per environment from the training's range, or the named
        robot's gains times one factor; motor strength and motor friction per joint; friction and payload the
        environment's own), written into the worlds' actuator fields."""
        p, n, j = self.physics, self.num_envs, self.num_actions

        def uniform(bounds, shape):
            low, high = bounds
            return low + (high - low) * torch.rand(shape, device=self.device, generator=self.generator)

        if p["named"]:
            kp = self._nominal_kp * uniform(p["gain_factors"], (n, 1))
            kd = self._nominal_kd * uniform(p["gain_factors"], (n, 1))
        else:
            kp = uniform(p["kp"], (n, 1)).expand(n, j) if p["kp"] else self._nominal_kp.expand(n, j)
            kd = uniform(p["kd"], (n, 1)).expand(n, j) if p["kd"] else self._nominal_kd.expand(n, j)
        strength = uniform(p["motor_strength"], (n, j)) if p["motor_strength"] else torch.ones_like(kp)
        self.kp, self.kd, self.motor_strength = kp.contiguous(), kd.contiguous(), strength
        write_actuator_fields(self._gain, self._bias, self._force_range, kp, kd, strength,
                        uniform(p["motor_friction"], (n, j)), self._torque_limits, p["motor_friction_velocity"])

    def _new_episodes(self) -> None:
        """Every environment starts from a bank entry of its (tile, variant) cell; histories refilled."""
        n = self.num_envs
        # each episode's draws from its own seed (the run's seed and the episode's index by env steps): a resumed
        # run, whose env steps the run restores, continues the sequence instead of repeating its start
        self.generator.manual_seed(self.seed * 1_000_003 + self.env_steps // (n * self.max_episode_length))
        if self.physics is not None and self.episodes_started:  # the first runs the bundle's (the CPU trainer's draw)
            self._draw_physics()
        self.episodes_started += 1
        self.tile = self.tile_of_cell[self.curriculum.family, self.curriculum.level]
        cell = self.tile * self.num_variants + self.variant
        count = self.cell_count[cell]
        pick = (torch.rand(n, device=self.device, generator=self.generator) * count).long().clamp(max=count - 1)
        entry = self.cell_start[cell] + pick.clamp(min=0)
        with self._scope():  # MuJoCo's reset (solver warm start, time, forces cleared)
            self._mjw.reset_data(self.warp_model, self.warp_data)
        self.qpos.copy_(self.bank_qpos[entry])
        self.qvel.copy_(self.bank_qvel[entry])
        self.ctrl.zero_()
        self.ctrl[:, : self.num_actions] = self.qpos[:, self.qadr]
        self._forward()
        self.start_qpos = self.qpos.clone()
        self.t = 0
        self.episode_length_buf.zero_()
        self.dead = torch.zeros(n, dtype=torch.bool, device=self.device)
        self._read_state()
        self.start_xy = self.state.base_pos[:, :2].clone()
        zeros = torch.zeros(n, self.num_actions, device=self.device)
        self.action, self.action_prev, self.action_prev2 = zeros, zeros.clone(), zeros.clone()
        self.targets = self.default_pose.expand(n, -1).clone()  # the engine's previous action at t = 0
        self.success = SuccessTracker(n, self.spec.kind, self.nominal_height, like=self.nominal_height)
        o_t = self._policy_observation()
        self.history = o_t[:, None, :].repeat(1, self.cfg_obj.history, 1)

    # ------------------------------------------------------------------ reading the worlds
    def _read_state(self) -> None:
        q, v = self.qpos, self.qvel
        self.state = RobotState(base_pos=q[:, 0:3].clone(), base_quat=q[:, 3:7].clone(), base_linvel=v[:, 0:3].clone(),
                                base_angvel=v[:, 3:6].clone(), q=q[:, self.qadr], qd=v[:, self.dadr],
                                tau=self.qfrc_actuator[:, self.dadr])
        force = self.cfrc_ext[:, self.link_body, 3:6]
        norm = torch.sqrt((force * force).sum(dim=-1))
        self.group_contact = ((norm > CONTACT_FORCE_THRESHOLD).float() @ self.membership) > 0
        self.foot_force = norm[:, self.feet]
        self.foot_contact = self.foot_force > CONTACT_FORCE_THRESHOLD
        knee = force[:, self.knees].sum(dim=2)  # (N, knee groups, 3)
        self.knee_force_xy = torch.sqrt((knee[..., :2] ** 2).sum(dim=-1))

    def _ground(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """Terrain heights (N, P) [m] at world points (N, P) on each environment's tile (the nearest raster cell,
        the floor off the raster; `HeightRaster._heights`)."""
        centres, size = self.centres[self.tile], self.raster_n
        i = torch.round((x - centres[:, :1] + HALF_SIZE) / RESOLUTION).long()
        jj = torch.round((y - centres[:, 1:] + HALF_SIZE) / RESOLUTION).long()
        inside = (i >= 0) & (i < size) & (jj >= 0) & (jj < size)
        heights = self.heights[self.tile[:, None], i.clamp(0, size - 1), jj.clamp(0, size - 1)]
        return torch.where(inside, heights, self.floor)

    def _yaw(self) -> torch.Tensor:
        w, x, y, z = self.state.base_quat.unbind(dim=1)
        return torch.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

    def _scan(self) -> torch.Tensor:
        from frbench.terrains import SCAN_POINTS

        if not hasattr(self, "_scan_points"):
            self._scan_points = torch.tensor(np.array(SCAN_POINTS), dtype=torch.float32, device=self.device)
        yaw, p = self._yaw(), self.state.base_pos
        c, s = torch.cos(yaw)[:, None], torch.sin(yaw)[:, None]
        px, py = self._scan_points[:, 0][None], self._scan_points[:, 1][None]
        x = p[:, :1] + c * px - s * py
        y = p[:, 1:2] + s * px + c * py
        return p[:, 2:3] - self._ground(x, y)

    def _com_xy(self) -> torch.Tensor:
        """Whole-body CoM minus the base position in the base yaw frame (N, 2) [m] (``subtree_com`` of the root)."""
        delta = self.subtree_com[:, self.root_body, :2] - self.state.base_pos[:, :2]
        yaw = self._yaw()
        c, s = torch.cos(yaw), torch.sin(yaw)
        return torch.stack([c * delta[:, 0] + s * delta[:, 1], -s * delta[:, 0] + c * delta[:, 1]], dim=1)

    # ------------------------------------------------------------------ observations
    def _policy_observation(self) -> torch.Tensor:
        obs = proprioception(self.state, self.targets)
        self.gravity = obs["projected_gravity"]
        o_t = flatten(obs, self.default_pose)
        o_t[:, -self.num_actions:] = self.action
        return o_t

    def get_observations(self, o_t: torch.Tensor | None = None) -> TensorDict:
        """The CPU trainer's groups: ``policy``, ``history``, ``privileged``, ``mass``, ``contact``, ``velocity``,
        ``extrinsics`` (float32, on the device), NaN and dead worlds' rows zero; ``o_t``: the policy observation
        of the current state when the caller has it already."""
        o_t = self._policy_observation() if o_t is None else o_t
        s = self.state
        groups = {"policy": o_t, "history": self.history.reshape(self.num_envs, -1)}
        groups.update(privileged_groups(o_t, self._scan(), self.masses, self.kp, self.kd, self._com_xy(),
                                        self.group_contact, self.foot_force, self.friction, self.motor_strength,
                                        self.payload, s.base_quat, s.base_linvel))
        alive = ~self.dead[:, None]
        groups = {k: torch.where(alive, torch.nan_to_num(v.float(), nan=0.0, posinf=0.0, neginf=0.0), 0.0)
                  for k, v in groups.items()}
        return TensorDict(groups, batch_size=[self.num_envs], device=self.device)

    # ------------------------------------------------------------------ stepping
    def step(self, actions: torch.Tensor):
        """One control step of every world (rsl-rl `VecEnv.step`)."""
        n, j = self.num_envs, self.num_actions
        action = torch.clamp(actions.to(self.device, torch.float32), -10.0, 10.0)
        self.action_prev2, self.action_prev, self.action = self.action_prev, self.action, action
        targets = torch.minimum(torch.maximum(self.default_pose + self.action_scale * action, self.lower), self.upper)
        self.ctrl[:, :j] = targets
        self.targets = targets
        qd_prev = self.state.qd.clone()
        self.advance()
        self.env_steps += n
        self.t += 1
        self.episode_length_buf += 1
        # divergence and buffer overflows: the world returns to its start at rest and is dead for the episode
        bad = ~((self.qpos.abs() < DIVERGENCE_LIMIT).all(dim=1) & (self.qvel.abs() < DIVERGENCE_LIMIT).all(dim=1))
        bad |= (self.overflow & self._overflow_mask) != 0
        self.dead |= bad
        self.qpos.copy_(torch.where(bad[:, None], self.start_qpos, self.qpos))
        self.qvel.copy_(torch.where(bad[:, None], 0.0, self.qvel))
        self.overflow.zero_()
        self._read_state()
        s = self.state
        o_t = self._policy_observation()
        ground = self._ground(s.base_pos[:, :1], s.base_pos[:, 1:2])[:, 0]
        height = s.base_pos[:, 2] - ground
        body_contact = self.group_contact.any(dim=1)
        alive = ~self.dead
        displacement = torch.sqrt(((s.base_pos[:, :2] - self.start_xy) ** 2).sum(dim=1))
        self.success.update(StepSignals(gravity_z=self.gravity[:, 2], height=height, body_contact=body_contact,
                                        displacement=displacement), alive)
        inputs = RewardInputs(
            projected_gravity=self.gravity, q=s.q, qd=s.qd, qd_prev=qd_prev, tau=s.tau, action=action,
            action_prev=self.action_prev, q_stand=self.default_pose, q_lower=self.lower, q_upper=self.upper,
            foot_contact=self.foot_contact, body_contact=body_contact, knee_force_xy=self.knee_force_xy,
            base_xy=s.base_pos[:, :2], init_xy=self.start_xy, base_height=height, nominal_height=self.nominal_height,
            action_prev2=self.action_prev2, upper_body=self.upper_body)
        if self.head is not None:
            body = int(self.head["body"])
            head = self.xpos[:, body] + self.xmat[:, body].reshape(n, 3, 3)[:, :, 2] * HEAD_OFFSET_M
            inputs.head_height = head[:, 2] - self._ground(head[:, :1], head[:, 1:2])[:, 0]
            inputs.nominal_head_height = float(self.head["standing_height"])
        if self._arguments is None:
            self._arguments = term_arguments(self.reward_config, inputs)
        reward, terms = compute_rewards(inputs, self.reward_config, self._arguments)
        reward = torch.where(alive, torch.nan_to_num(reward), 0.0)
        self.last_terms = terms  # the step's weighted terms (N,) each, for tests and benchmarks
        self.reward_means.add(terms, alive)
        self.history = torch.cat([self.history[:, 1:], o_t[:, None, :]], dim=1)
        done = self.t >= self.max_episode_length
        log = {}
        if done:
            success = self.success.success & alive
            stats = self._episode_stats(success, alive)
            if self.cfg_obj.curriculum:
                self.curriculum.update(torch.ones_like(success), success)
            self.last_episode_stats = {k: float(v) for k, v in stats.items()}  # once per episode
            log.update({f"/episode/{k}": v for k, v in stats.items()})
            self._new_episodes()
        obs = self.get_observations(None if done else o_t)  # after an episode end: the new episodes' o_t
        dones = torch.full((n,), bool(done), device=self.device)
        return obs, reward, dones, {"time_outs": dones.clone(), "log": log}

    def _episode_stats(self, success: torch.Tensor, alive: torch.Tensor) -> dict[str, torch.Tensor]:
        """The CPU trainer's statistics (`CurriculumStarts.episode_stats`) as 0-d tensors."""
        ok = success.double()
        stats = {"success_all": ok.mean(), "diverged": (~alive).double().mean(),
                 "mean_level": self.curriculum.level.double().mean()}
        for f, family in enumerate(self.cfg_obj.families):
            mine = self.curriculum.family == f
            stats[f"success_{family}"] = (ok * mine).sum() / mine.sum().clamp(min=1)
        return stats

    def close(self) -> None:
        """Release the device arrays."""
        self.warp_data = self.warp_model = self._graph = None


def device_training_env(cfg, device: str | None = None, bundle_dir=None, log=print) -> DeviceTrainingEnv:
    """The device trainer of ``cfg`` on ``device`` (default ``cuda`` when torch sees one, else ``cpu``): its
    bundle loaded from ``bundle_dir`` (built for the same config; a field that differs is an error naming it)
    or built here on the CPU (`device_bundle.build_bundle`)."""
    from frbench.errors import FrbenchError
    from frbench.training.device_bundle import build_bundle, load_bundle

    device = device or ("cuda" if torch.cuda.is_available() else "cpu")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise FrbenchError(f"--device {device}: torch sees no CUDA device here")
    if bundle_dir is None:
        try:
            bundle = build_bundle(cfg, log=log)
        except ValueError as exc:
            raise FrbenchError(f"--backend mujoco-warp: {exc}") from None
    else:
        bundle = load_bundle(bundle_dir)
        built, wanted = bundle.meta["config"], cfg.to_dict()
        differ = sorted(k for k in set(built) | set(wanted) if built.get(k) != wanted.get(k))
        if differ:
            field = differ[0]
            raise FrbenchError(f"{bundle_dir}/meta.json: config field {field} is {built.get(field)!r}, the run's "
                               f"{wanted.get(field)!r}; build the bundle with the run's flags")
    return DeviceTrainingEnv(bundle, device)
