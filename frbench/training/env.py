"""The training environment: frbench's batched backends behind rsl-rl's `VecEnv`.

N fallen robots on a world of all terrain tiles (`terrain_grid`), each on the
tile its curriculum level says, with randomised morphologies (or one named
robot), randomised gains and motor strength, friction and payload, trained on
the paper's rewards. Episodes are `TrainEnvConfig.episode_steps` control steps
(350 in the paper) and end together by time-out; all environments then get new
fallen starts on their (possibly new) tiles.

Observation groups (float32 TensorDict, N rows):

* ``policy``  o_t (6 + 3J = 42): [ω, g, q − q̊, q̇, a_{t−1}];
* ``history`` the last H = 5 o_t, oldest first (H·42);
* ``long_history`` (only with ``TrainEnvConfig.long_history`` = T > 0) the last
  T o_t, oldest first (T·42), for RMA's adaptation module;
* ``privileged`` the critic's s_t (277): [o_t, 187-point height scan, 4 group
  masses [kg], Kp (J) and Kd (J), CoM xy in the base yaw frame [m], 13 contact
  flags, 4 foot force norms [N], friction];
* ``mass`` (4) and ``contact`` (13): the estimator's labels (Pinocchio masses
  incl. payload; backend contact flags); ``velocity`` (3): base linear
  velocity, body frame [m/s]; ``extrinsics`` (11): RMA's environment factors.

Action a (J) [-]: joint targets q* = q̊ + ``action_scale``·a, clipped to the
joint limits (the paper's q* = q̊ + a with a scale, as legged_gym).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from frbench.backends import make_backend
from frbench.backends.base import PhysicsParams, RobotState
from frbench.policies.learned import residual_targets
from frbench.policies.scripted_humanoid import DEFAULT_GATE_PHASES, gate_phase_ids
from frbench.robots import get_robot, ground_truth
from frbench.tasks.initial_states import draw_start
from frbench.tasks.observations import (
    flatten,
    projected_gravity,
    proprioception,
    rotate_to_body,
)
from frbench.tasks.recovery import EPISODE_STEPS
from frbench.tasks.success import StepSignals, SuccessTracker
from frbench.terrains import FAMILIES
from frbench.training.curriculum import TerrainCurriculum
from frbench.training.demo_starts import assist_probability, record_demo_starts
from frbench.training.feasibility import can_stand
from frbench.training.height_raster import HeightRaster
from frbench.training.randomization import (
    CONTROL_RANGES,
    morphology_spec,
    sample_morphologies,
    sample_physics,
)
from frbench.training.rewards import RewardConfig, RewardInputs, compute_rewards
from frbench.training.terrain_grid import build_grid

#: Why frbench's training rewards differ from the paper's table (see docs/training.md).
MOTION_PENALTY_REASON = (
    "x0.1: at the paper's weights the joint-velocity, -acceleration and torque penalties outweigh the upright "
    "reward about 10:1 at the start of training; with ~10M steps on 2 CPU cores the policy then learns to lie "
    "still instead of rolling over"
)


HEIGHT_REASON = (
    "added (not in the paper), weight 6: with the paper's table alone, 2 M steps of training rolled robots onto "
    "their bellies without ever rising (0 % success, target-posture reward 0); a term that pays for height, as in "
    "MuJoCo Playground's getup task, gives the rise a gradient. At weight 2 lying belly-down (upright term full) "
    "still earned about half of standing, and after 2.2 M steps policies let even standing starts collapse; at "
    "weight 6 standing pays about twice lying on the belly"
)

SAFETY_FORCE_REASON = (
    "x0.1: the knee force frbench measures is the net contact force on thigh and calf, which includes leg-on-leg "
    "self-contact while the legs are folded (55-120 N on each knee during a scripted roll of Go2); at the paper's "
    "weight it cost as much as the upright reward pays (-0.06 vs +0.09 per step at 2 M steps)"
)


#: Target-posture kernel width of frbench's training [rad²] (the paper: 1); see docs/training.md.
POSTURE_SIGMA2 = 3.0


#: The motion penalties `training_reward_config` scales (joint velocity, acceleration and torques).
MOTION_PENALTY_TERMS = ("joint_velocity", "joint_acceleration", "joint_torques")
#: Their scale relative to the paper's weights when a run starts (see `MOTION_PENALTY_REASON`).
MOTION_PENALTY_SCALE = 0.1


def training_reward_config() -> "RewardConfig":
    """The paper's reward table, motion and knee-force penalties x0.1, plus a base-height term (reasons recorded
    in the config)."""
    from frbench.training.rewards import PAPER_WEIGHTS

    config = RewardConfig()
    for term in MOTION_PENALTY_TERMS:
        config = config.with_weight(term, MOTION_PENALTY_SCALE * PAPER_WEIGHTS[term], MOTION_PENALTY_REASON)
    config = config.with_weight("safety_force", 0.1 * PAPER_WEIGHTS["safety_force"], SAFETY_FORCE_REASON)
    config = config.with_weight("base_height", 6.0, HEIGHT_REASON)
    return dataclasses.replace(config, posture_sigma2=POSTURE_SIGMA2)


HUMANOID_REASONS = {
    "feet_contact": "humanoids: replaced by feet_on_ground, which pays only once the base has risen (a G1 lying "
                    "with its soles on the floor would otherwise be paid for it)",
    "head_height": "humanoid term (HoST, HumanUP): pays for lifting the head, the signal of sitting and rising up",
    "feet_on_ground": "humanoid term: both feet under the robot once it has risen",
    "upper_body_posture": "humanoid term: waist and arms back to their standing pose once upright",
    "action_jerk": "humanoid term: HoST's smoothness (second difference of the actions)",
}


def humanoid_reward_config() -> "RewardConfig":
    """frbench's quadruped training rewards plus the humanoid terms (each with its reason); see docs/training.md."""
    config = training_reward_config().without(("feet_contact",), HUMANOID_REASONS["feet_contact"])
    for term, weight in (("head_height", 2.0), ("feet_on_ground", 1.0), ("upper_body_posture", 1.0),
                         ("action_jerk", -0.01)):
        config = config.with_weight(term, weight, HUMANOID_REASONS[term])
    return config


#: The humanoid's "head": a point this far [m] above the torso link's origin along its z axis (the G1's head
#: centre stands about 1.23 m above flat ground in the default pose).
HEAD_FRAME, HEAD_OFFSET_M = "torso_link", 0.40
#: Joint-name fragments of a humanoid's legs; every other joint belongs to the upper body (waist, arms).
LEG_JOINT_WORDS = ("hip", "knee", "ankle")


#: Gain ranges of frbench's training (the paper: Kp [20, 80], Kd [0.6, 2.0]); see docs/training.md.
TRAINING_GAIN_RANGES = {"kp": (50.0, 80.0), "kd": (1.0, 2.0)}

#: A named robot's own per-joint Kp and Kd are multiplied by one factor per episode drawn from this range.
NAMED_ROBOT_GAIN_FACTORS = (0.9, 1.1)

#: Standard gravity [m/s²] (both backends simulate g = 9.81 downwards).
GRAVITY = 9.81
GAIN_RANGE_REASON = (
    "robots sampled from the paper's morphology table weigh 21-35 kg (6 of 6 in a check); with Kp 20 every one "
    "sinks 40-65 % below its standing height and touches the ground with its body, with Kp 80 every one stands, "
    "so Kp < 50 makes most episodes impossible to win"
)


@dataclass
class TrainEnvConfig:
    """Training environment settings (saved in every checkpoint)."""

    num_envs: int = 256
    backend: str = "mujoco"
    robot: str | None = None  # None: randomised morphologies
    num_morphologies: int = 32
    episode_steps: int = 350
    settle_steps: int = 25
    action_scale: float = 1.0  # the paper's q* = q̊ + a
    families: tuple[str, ...] = FAMILIES
    curriculum: bool = True
    start_level: int = 1
    randomize: bool = True
    gain_ranges: dict = field(default_factory=lambda: dict(TRAINING_GAIN_RANGES))
    #: Rows of the paper's morphology table replaced for this run, field → (low, high) [kg or m]
    #: (``morphology.morphology_ranges``); empty: the paper's table.
    morphology_ranges: dict = field(default_factory=dict)
    reward: RewardConfig = field(default_factory=training_reward_config)
    history: int = 5
    #: Frames of the ``long_history`` group (RMA's adaptation module reads 50); 0: no such group.
    long_history: int = 0
    seed: int = 0
    #: Starting states along a getting-up motion (`demo_starts`): the fraction of episodes that start from
    #: a recorded ``scripted`` state, falling linearly to 0 at ``demo_start_until`` env steps (0: off).
    demo_start_fraction: float = 0.0
    demo_start_until: float = 0.0
    #: Re-record the bank every this many episodes, from ``demo_steps`` control steps, one snapshot per ``demo_stride``.
    demo_refresh_episodes: int = 10
    demo_steps: int = 300
    demo_stride: int = 5
    #: A vertical assist force on the base, as a fraction of the robot's weight, falling linearly to 0 at
    #: ``assist_until`` env steps (0: off); HoST's way of making getting up cheap to learn. Never in evaluation.
    assist_force: float = 0.0
    assist_until: float = 0.0
    #: A policy name (e.g. ``"scripted-humanoid"``) whose joint targets the learned action is added to:
    #: q* = base(o) + action_scale·a (a residual policy); None: q* = q̊ + action_scale·a.
    base_controller: str | None = None
    #: The base controller's tunable parameters at the start of the run (name → value; empty: it has none).
    base_controller_parameters: dict = field(default_factory=dict)
    #: Gated residual: q* = base(o) + gate·action_scale·a with the base controller's ``residual_gate()`` (N,)
    #: (``keyframe-humanoid``: 1 in its rise, 0 before), so exploration cannot break the motion before the rise.
    residual_gate: bool = False
    #: The base controller's phases in which the gated residual acts (names, `scripted_humanoid.PHASE_NAMES`);
    #: the default is the rise (crouch, rise, hold); the sit-up's ``tuck``, ``prop``, ``rock`` may be added.
    gate_phases: tuple[str, ...] = DEFAULT_GATE_PHASES
    #: With a gated residual: this fraction of episodes starts where the base controller opened its gate in a
    #: recorded run from fresh fallen starts (the key frames' crouch), the controller in that phase, so that
    #: every such episode exercises the rise (0: off). Logged success rates count fresh fallen starts only.
    rise_start_fraction: float = 0.0
    #: The policy decides every ``action_hold`` control steps and its action is held in between (1: every step);
    #: the exploration noise then moves the targets for ``action_hold`` × 0.02 s at a time instead of averaging
    #: out from one 0.02-s step to the next. Rewards are summed over the held steps; ``episode_steps`` stays in
    #: control steps.
    action_hold: int = 1


def _yaw(quat: np.ndarray) -> np.ndarray:
    w, x, y, z = quat.T
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class RecoveryTrainingEnv(VecEnv):
    """See the module docstring."""

    def __init__(self, cfg: TrainEnvConfig, device: str = "cpu"):
        self.cfg_obj = cfg
        self.cfg = {"env": {k: (str(v) if k == "reward" else v) for k, v in cfg.__dict__.items()}}
        self.device = device
        self.num_envs = n = cfg.num_envs
        self.rng = np.random.default_rng(cfg.seed)
        self.grid = build_grid(cfg.families)
        self._setup_robots()
        self.num_actions = self.spec.n_joints
        if cfg.action_hold < 1:
            raise ValueError(f"action_hold {cfg.action_hold}: expected at least 1 control step per decision")
        self.max_episode_length = -(-cfg.episode_steps // cfg.action_hold)  # decisions per episode
        self.episode_length_buf = torch.zeros(n, dtype=torch.long)
        self.curriculum = TerrainCurriculum(n, self.rng, families=cfg.families, start_level=cfg.start_level)
        if not cfg.curriculum:
            self.curriculum.level[:] = self.rng.integers(1, 11, size=n)
        self.tile_keys = sorted(self.grid.tiles)
        self.raster = HeightRaster(self.grid, self.tile_keys)
        self.backend = make_backend(cfg.backend, self.spec, n, terrain=self.grid.world, variants=self.variants)
        self.default_pose = np.asarray(self.spec.default_pose)
        self.lower, self.upper = np.asarray(self.spec.joint_lower), np.asarray(self.spec.joint_upper)
        self.reward_cfg = self._reward_config(cfg.reward)
        self.last_episode_stats: dict[str, float] = {}
        self.env_steps = 0  # env steps taken so far (N per control step); the run restores it on --resume
        self.demo_bank = None
        self._episodes_since_demo = 0
        self.rise_bank = None  # gate-opening states (`_record_rise_bank`), with --rise-starts
        self._episodes_since_rise = 0
        self.from_demo = np.zeros(n, dtype=bool)
        self._reset_all()

    # ------------------------------------------------------------------ set-up
    def _setup_robots(self) -> None:
        cfg, n = self.cfg_obj, self.num_envs
        if cfg.robot:
            specs = [get_robot(cfg.robot)]
        else:
            specs = self._feasible_morphologies()
        self.specs = specs
        self.spec = specs[0]
        self.assignment = np.arange(n) % len(specs)
        self.rng.shuffle(self.assignment)
        k = len(specs)
        if cfg.randomize:
            variant_physics = sample_physics(self.spec, k, self.rng)
            self.variant_friction, self.variant_payload = variant_physics.friction, variant_physics.payload
        else:
            self.variant_friction, self.variant_payload = np.ones(k), np.zeros(k)
        self.variants = (specs, self.assignment, self.variant_friction, self.variant_payload) if k > 1 or cfg.randomize else None
        masses = np.array([ground_truth.group_masses(s) for s in specs])
        masses[:, 0] += self.variant_payload  # the payload sits on the base
        self.env_masses = masses[self.assignment]
        self.env_friction = self.variant_friction[self.assignment]
        self.env_payload = self.variant_payload[self.assignment]
        self.nominal_height = np.array([s.nominal_height for s in specs])[self.assignment]
        self._pin = [ground_truth.load(s) for s in specs]
        self._pin_data = [p.model.createData() for p in self._pin]
        self.humanoid = self.spec.kind == "humanoid"
        self.upper_body = np.array([not any(w in name for w in LEG_JOINT_WORDS) for name in self.spec.joint_names])
        if self.humanoid:
            standing = RobotState.standing(self.spec, 1, clearance=0.0)
            self.nominal_head_height = float(self._head_positions(standing, [0])[0, 2])
        self.controller = None
        if self.cfg_obj.base_controller:
            from frbench.policies.registry import load_base_controller

            self.controller = load_base_controller(self.cfg_obj.base_controller, self.cfg_obj.base_controller_parameters)
            if self.cfg_obj.residual_gate and not hasattr(self.controller, "residual_gate"):
                raise ValueError(f"residual_gate: base controller {self.cfg_obj.base_controller!r} has no residual_gate()")
            if self.cfg_obj.residual_gate:
                gate_phase_ids(self.cfg_obj.gate_phases)  # ValueError naming an unknown phase
            if self.cfg_obj.rise_start_fraction > 0.0 and not self.cfg_obj.residual_gate:
                raise ValueError("rise_start_fraction needs residual_gate (the rise starts where the gate opens)")
            if not self.controller.supports(self.spec):
                raise ValueError(f"base_controller {self.cfg_obj.base_controller!r} does not support {self.spec.name!r}")

    def _feasible_morphologies(self) -> list:
        """``num_morphologies`` sampled robots (CoM shift applied when randomising) that can stand at the lowest
        training gains (`feasibility.can_stand`); the others are redrawn and counted in ``self.rejected``.
        Their parameters are kept in ``self.morphologies``."""
        cfg = self.cfg_obj
        kp, kd = cfg.gain_ranges.get("kp", CONTROL_RANGES["kp"])[0], cfg.gain_ranges.get("kd", CONTROL_RANGES["kd"])[0]
        specs, self.morphologies, self.rejected = [], [], 0
        while len(specs) < cfg.num_morphologies:
            morphology = sample_morphologies(1, self.rng, ranges=cfg.morphology_ranges)[0]
            if cfg.randomize:  # the paper's CoM shift, baked into the morphology's trunk inertial
                shift = self.rng.uniform(*CONTROL_RANGES["com_shift"], size=3)
                morphology = dataclasses.replace(morphology, trunk_com_shift=tuple(map(float, shift)))
            spec = morphology_spec(morphology, f"morph{len(specs):04d}")
            if can_stand(spec, kp, kd):
                specs.append(spec)
                self.morphologies.append(morphology)
            else:
                self.rejected += 1
            if self.rejected > 20 * cfg.num_morphologies:
                raise ValueError(f"{self.rejected} sampled morphologies could not stand at Kp {kp}, Kd {kd}; "
                                 "raise the gain range")
        return specs

    def _reward_config(self, reward: RewardConfig) -> RewardConfig:
        """The velocity-limit threshold read as legged_gym does: 0.8 × each joint's URDF velocity limit.

        The paper writes max(|q̇| − 0.8, 0); FR-Net builds on legged_gym, whose
        ``dof_vel_limits`` reward uses ``soft_dof_vel_limit = 0.8`` of the URDF
        limit. Read literally (0.8 rad/s) the term dominates every other reward.
        """
        import dataclasses

        from frbench.robots.urdf_tree import parse_urdf
        from frbench.training.rewards import DEFAULT_VELOCITY_THRESHOLD

        if reward.velocity_threshold != DEFAULT_VELOCITY_THRESHOLD:
            return reward
        joints = parse_urdf(self.spec.urdf_path).joints
        limits = [joints[name].velocity or 30.0 for name in self.spec.joint_names]
        return dataclasses.replace(reward, velocity_threshold=tuple(0.8 * v for v in limits))

    # ------------------------------------------------------------------ episodes
    def _reset_all(self) -> None:
        """New episodes for every environment: fresh fallen starts, a fraction of them replaced by bank states."""
        cfg = self.cfg_obj
        fraction = assist_probability(cfg.demo_start_fraction, cfg.demo_start_until, self.env_steps)
        if fraction > 0.0 and (self.demo_bank is None or self._episodes_since_demo >= cfg.demo_refresh_episodes):
            self._fresh_starts()
            self.demo_bank = record_demo_starts(self.backend, self.specs, self.assignment, self.tile_row,
                                                cfg.demo_steps, cfg.demo_stride)
            self._episodes_since_demo = 0
        self._episodes_since_demo += 1
        stale = self.rise_bank is None or self._episodes_since_rise >= cfg.demo_refresh_episodes
        if cfg.rise_start_fraction > 0.0 and stale:
            self.rise_bank, self._episodes_since_rise = self._record_rise_bank(), 0
        self._episodes_since_rise += 1
        self._fresh_starts()
        self.from_demo = (self.rng.random(self.num_envs) < fraction) & (
            self.demo_bank.valid if self.demo_bank is not None else False)
        if self.from_demo.any():
            ids = np.flatnonzero(self.from_demo)
            state, targets, tiles = self.demo_bank.sample(ids, self.rng)
            self._restart_from(ids, state, tiles)
            self.action[ids] = (targets - self.default_pose) / cfg.action_scale
        self.action_prev = self.action.copy()  # a_{t-1} while self.action is a_t; both zero at a fresh start
        if self.controller is not None:
            self.controller.reset(self.spec, self.num_envs)
        if cfg.rise_start_fraction > 0.0:
            self._rise_starts(cfg.rise_start_fraction)
        o_t = self._o_t()
        self.history = np.repeat(o_t[:, None, :], cfg.history, axis=1)
        self.long_history = np.repeat(o_t[:, None, :], cfg.long_history, axis=1) if cfg.long_history else None

    def _restart_from(self, ids: np.ndarray, state: RobotState, tiles) -> None:
        """Start environments ``ids`` from recorded ``state`` (len(ids) rows) on their recorded ``tiles``."""
        self.backend.reset(ids, state)
        self.tile_row[ids] = tiles
        self.state, self.contacts = self.backend.state(), self.backend.contacts()
        self.init_xy = self.state.base_pos[:, :2].copy()
        self.qd_prev = self.state.qd.copy()  # the first step's joint acceleration starts from the recorded state

    def _record_rise_bank(self) -> list[tuple[RobotState, int, np.ndarray, int]]:
        """Run a fresh copy of the base controller from fresh fallen starts for one evaluation episode
        (`EPISODE_STEPS`, whatever the training episode length: the gate openings an evaluation can see); the
        state (one row), tile, controller targets (J,) [rad] and way to the crouch (`gate_paths`) of every
        environment at the step its default gate (the crouch) first opened."""
        from frbench.policies.registry import load_base_controller

        self._fresh_starts()
        controller = load_base_controller(self.cfg_obj.base_controller, self.cfg_obj.base_controller_parameters)
        controller.reset(self.spec, self.num_envs)
        bank, opened = [], np.zeros(self.num_envs, dtype=bool)
        state = self.backend.state()
        for _ in range(EPISODE_STEPS):
            self.backend.step(np.asarray(controller.act(proprioception(state, self.default_pose))))
            state = self.backend.state()
            new = (controller.residual_gate() > 0) & ~opened & ~self.backend.diverged
            paths = controller.gate_paths()
            bank += [(state.take([i]), int(self.tile_row[i]), controller.target[i].copy(), int(paths[i]))
                     for i in np.flatnonzero(new)]
            opened |= new
        return bank

    def _rise_starts(self, fraction: float) -> None:
        """Replace a ``fraction`` of the fresh starts by recorded gate-opening states (`_record_rise_bank`,
        re-recorded every ``demo_refresh_episodes`` episodes), the base controller put in its gated phase."""
        drawn = (self.rng.random(self.num_envs) < fraction) & ~self.from_demo
        ids = np.flatnonzero(drawn) if self.rise_bank else np.zeros(0, int)
        if not len(ids):
            return
        picks = self.rng.integers(0, len(self.rise_bank), size=len(ids))
        rows = [self.rise_bank[k][0] for k in picks]
        state = RobotState(**{f: np.concatenate([getattr(r, f) for r in rows]) for f in
                              ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")})
        self._restart_from(ids, state, [self.rise_bank[k][1] for k in picks])
        self.from_demo[ids] = True
        self.controller.enter_gate(ids, np.stack([self.rise_bank[k][2] for k in picks]), self.state.q,
                                   np.array([self.rise_bank[k][3] for k in picks]))

    def _fresh_starts(self) -> None:
        """Fallen starts on every environment's curriculum tile, settled for ``settle_steps`` on soft gains."""
        n, cfg = self.num_envs, self.cfg_obj
        tiles = list(zip(self.curriculum.family.tolist(), self.curriculum.level.tolist()))
        self.tile_row = np.array([self.raster.index[t] for t in tiles])
        pos, quat, q = np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, self.spec.n_joints))
        for i, tile in enumerate(tiles):
            p, o, j, _ = draw_start(self.specs[self.assignment[i]], self.grid.tiles[tile], self.rng)
            dx, dy = self.grid.offsets[tile]
            pos[i], quat[i], q[i] = p + (dx, dy, 0.0), o, j
        if cfg.randomize:
            self.params = self._sample_physics(n)
            self.params.friction, self.params.payload = self.env_friction.copy(), self.env_payload.copy()
            self.params.motor_friction = self.rng.uniform(*CONTROL_RANGES["motor_friction"], size=(n, self.spec.n_joints))
        else:
            self.params = PhysicsParams.nominal(self.spec, n)
        soft = PhysicsParams(self.params.kp * 0.3, self.params.kd * 0.3, self.params.motor_strength,
                             self.params.friction, self.params.payload)
        self.backend.set_params(soft)
        self.backend.set_base_force(np.zeros((n, 3)))
        self.backend.reset(np.arange(n), RobotState.at_rest(pos, quat, q))
        for _ in range(cfg.settle_steps):
            self.backend.step(q)
        self.backend.set_params(self.params)
        self._set_assist()
        self.state = self.backend.state()
        self.contacts = self.backend.contacts()
        self.init_xy = self.state.base_pos[:, :2].copy()
        self.action = np.zeros((n, self.spec.n_joints))
        self.qd_prev = self.state.qd.copy()
        self.success = SuccessTracker(n, self.spec.kind, self.nominal_height)
        self.step_count = 0
        self.episode_length_buf.zero_()

    # ------------------------------------------------------------------ observations
    def _o_t(self) -> np.ndarray:
        targets = self.default_pose + self.cfg_obj.action_scale * self.action
        obs = proprioception(self.state, targets)
        o_t = flatten(obs, self.default_pose)
        o_t[:, -self.spec.n_joints:] = self.action  # the previous action in policy units
        return o_t

    def _com_xy(self) -> np.ndarray:
        """Whole-body CoM minus base position, in the base yaw frame, (N, 2) [m] (the backend's vectorised
        `whole_body_com`, payload included; cross-checked against Pinocchio in tests/test_backends.py)."""
        s = self.state
        delta = self.backend.whole_body_com()[:, :2] - s.base_pos[:, :2]
        yaw = _yaw(s.base_quat)
        c, si = np.cos(yaw), np.sin(yaw)
        return np.stack([c * delta[:, 0] + si * delta[:, 1], -si * delta[:, 0] + c * delta[:, 1]], axis=1)

    def _head_positions(self, state: RobotState, rows=None) -> np.ndarray:
        """World head positions (M, 3) [m] of the robots in ``rows`` (default all; ``state`` has M rows), by Pinocchio."""
        import pinocchio

        rows = range(self.num_envs) if rows is None else rows
        out = np.zeros((len(state.base_pos), 3))
        for m, i in enumerate(rows):
            robot = self._pin[self.assignment[i]]
            data = self._pin_data[self.assignment[i]]
            config = ground_truth.configuration(robot, state.base_pos[m], state.base_quat[m], state.q[m])
            pinocchio.framesForwardKinematics(robot.model, data, config)
            frame = data.oMf[robot.model.getFrameId(HEAD_FRAME)]
            out[m] = frame.translation + frame.rotation[:, 2] * HEAD_OFFSET_M
        return out

    def _observations(self, o_t: np.ndarray) -> TensorDict:
        s, c, p = self.state, self.contacts, self.params
        scan = self.raster.scan(self.tile_row, s.base_pos, _yaw(s.base_quat))
        com_xy = self._com_xy()
        privileged = np.concatenate([
            o_t, np.clip(scan, -1.0, 1.0), self.env_masses, p.kp, p.kd, com_xy,
            c.group_contact.astype(float), np.minimum(c.foot_force, 500.0) / 100.0, p.friction[:, None],
        ], axis=1)
        velocity = rotate_to_body(s.base_quat, s.base_linvel)
        extrinsics = np.concatenate([
            self.env_masses, p.kp.mean(axis=1, keepdims=True) / 50, p.kd.mean(axis=1, keepdims=True),
            p.motor_strength.mean(axis=1, keepdims=True), p.friction[:, None], p.payload[:, None], com_xy,
        ], axis=1)
        groups = {
            "policy": o_t, "history": self.history.reshape(self.num_envs, -1), "privileged": privileged,
            "mass": self.env_masses, "contact": c.group_contact.astype(float), "velocity": velocity,
            "extrinsics": extrinsics,
        }
        if self.long_history is not None:
            groups["long_history"] = self.long_history.reshape(self.num_envs, -1)
        alive = ~self.backend.diverged
        tensors = {}
        for key, value in groups.items():
            value = np.where(alive[:, None], np.nan_to_num(value, nan=0.0, posinf=0.0, neginf=0.0), 0.0)
            tensors[key] = torch.as_tensor(value, dtype=torch.float32)
        return TensorDict(tensors, batch_size=[self.num_envs])

    def get_observations(self) -> TensorDict:
        """The current observation groups."""
        return self._observations(self._o_t())

    # ------------------------------------------------------------------ stepping
    def step(self, actions: torch.Tensor):
        """One decision for every environment (rsl-rl `VecEnv.step`): the action held for
        `TrainEnvConfig.action_hold` control steps (fewer if the episode ends first), their rewards summed."""
        n = self.num_envs
        action_prev2, action_prev = self.action_prev, self.action
        self.action_prev = action_prev
        self.action = np.clip(actions.detach().cpu().numpy().astype(np.float64), -10.0, 10.0)
        reward, term_sums, held = np.zeros(n), {}, 0
        while True:
            step_reward, terms, alive = self._control_step(action_prev, action_prev2)
            reward += step_reward
            term_sums = {k: term_sums.get(k, 0.0) + v for k, v in terms.items()}
            held += 1
            action_prev2, action_prev = action_prev, self.action  # within a decision the action does not change
            if held >= self.cfg_obj.action_hold or self.step_count >= self.cfg_obj.episode_steps:
                break
        if held > 1:  # the next decision's a_{t-2}: the control step before the last one held this action too
            self.action_prev = self.action
        self.episode_length_buf += 1
        o_t = self._o_t()
        self.history = np.concatenate([self.history[:, 1:], o_t[:, None, :]], axis=1)
        if self.long_history is not None:
            self.long_history = np.concatenate([self.long_history[:, 1:], o_t[:, None, :]], axis=1)
        log = {f"/reward/{k}": float(np.mean(v[alive])) / held if alive.any() else 0.0 for k, v in term_sums.items()}
        done = self.step_count >= self.cfg_obj.episode_steps
        if done:
            success = self.success.success.copy()
            self.last_episode_stats = self._episode_stats(success, alive)
            log.update({f"/episode/{k}": v for k, v in self.last_episode_stats.items()})
            if self.cfg_obj.curriculum:  # the curriculum judges fallen starts only
                fallen = np.flatnonzero(~self.from_demo)
                self.curriculum.update(fallen, success[fallen])
            log.update({f"/curriculum/{k}": float(v) for k, v in self.curriculum.stats().items()})
            self._reset_all()
            o_t = self._o_t()
        obs = self._observations(o_t)
        dones = torch.full((n,), bool(done))
        extras = {"time_outs": torch.full((n,), bool(done)), "log": log}
        return obs, torch.as_tensor(reward, dtype=torch.float32), dones, extras

    def _control_step(self, action_prev: np.ndarray, action_prev2: np.ndarray):
        """One control step with the current action: targets, physics, rewards (N,) and terms (name → (N,)),
        success update; returns (reward, terms, alive (N,) bool)."""
        n = self.num_envs
        if self.controller is None:
            targets = self.default_pose + self.cfg_obj.action_scale * self.action
        else:
            base = np.asarray(self.controller.act(proprioception(self.state, self.default_pose)), dtype=np.float64)
            targets = residual_targets(base, self.action, self.cfg_obj.action_scale, self.controller,
                                       self.cfg_obj.residual_gate, self.cfg_obj.gate_phases)
        targets = np.clip(targets, self.lower, self.upper)
        self.qd_prev = self.state.qd
        self.backend.step(targets)
        self.state, self.contacts = self.backend.state(), self.backend.contacts()
        s, c = self.state, self.contacts
        gravity = projected_gravity(s.base_quat)
        ground = self.raster.lookup(self.tile_row, s.base_pos[:, None, :2])[:, 0]
        inputs = RewardInputs(
            projected_gravity=gravity, q=s.q, qd=s.qd, qd_prev=self.qd_prev, tau=s.tau, action=self.action,
            action_prev=action_prev, q_stand=self.default_pose, q_lower=self.lower, q_upper=self.upper,
            foot_contact=c.foot_contact, body_contact=c.group_contact.any(axis=1), knee_force_xy=c.knee_force_xy,
            base_xy=s.base_pos[:, :2], init_xy=self.init_xy, base_height=s.base_pos[:, 2] - ground,
            nominal_height=self.nominal_height, action_prev2=action_prev2, upper_body=self.upper_body,
        )
        if self.humanoid:
            head = self._head_positions(s)
            inputs.head_height = head[:, 2] - self.raster.lookup(self.tile_row, head[:, None, :2])[:, 0]
            inputs.nominal_head_height = self.nominal_head_height
        reward, terms = compute_rewards(inputs, self.reward_cfg)
        alive = ~self.backend.diverged
        reward = np.where(alive, np.nan_to_num(reward), 0.0)
        self.success.update(StepSignals(
            gravity_z=gravity[:, 2], height=s.base_pos[:, 2] - ground, body_contact=c.group_contact.any(axis=1),
            displacement=np.linalg.norm(s.base_pos[:, :2] - self.init_xy, axis=1),
        ), alive=alive)
        self.step_count += 1
        self.env_steps += n
        return reward, terms, alive

    def _sample_physics(self, n: int) -> PhysicsParams:
        """Gains, motor strength, friction and payload for ``n`` episodes. Sampled morphologies draw one Kp and
        Kd for all joints from the training's absolute range (they have no gains of their own); a named robot
        (``cfg.robot``) keeps its own per-joint gains, scaled by one factor per episode from
        `NAMED_ROBOT_GAIN_FACTORS` — one Kp of 50-80 N·m/rad would replace the G1's 40-200 per joint."""
        cfg = self.cfg_obj
        ranges = {**CONTROL_RANGES, **cfg.gain_ranges}
        if not cfg.robot:
            return sample_physics(self.spec, n, self.rng, ranges=ranges)
        params = sample_physics(self.spec, n, self.rng, ranges={k: v for k, v in ranges.items() if k not in ("kp", "kd")})
        params.kp = params.kp * self.rng.uniform(*NAMED_ROBOT_GAIN_FACTORS, size=(n, 1))
        params.kd = params.kd * self.rng.uniform(*NAMED_ROBOT_GAIN_FACTORS, size=(n, 1))
        return params

    def _set_assist(self) -> None:
        """The episode's vertical assist force (`TrainEnvConfig.assist_force`): fraction × weight [N] upwards."""
        self.assist_fraction = assist_probability(self.cfg_obj.assist_force, self.cfg_obj.assist_until, self.env_steps)
        force = np.zeros((self.num_envs, 3))
        force[:, 2] = self.assist_fraction * self.env_masses.sum(axis=1) * GRAVITY
        self.backend.set_base_force(force)

    def _episode_stats(self, success: np.ndarray, alive: np.ndarray) -> dict[str, float]:
        """Success rate of the episodes from fallen starts, overall, per family (all levels) and, on a split
        backend, per simulator (``success_in_<simulator>``); the diverged fraction; with demo starts, their
        share and their success rate."""
        fallen = ~self.from_demo
        stats = {"success_all": float(success[fallen].mean()) if fallen.any() else 0.0,
                 "diverged": float((~alive).mean()), "mean_level": float(self.curriculum.level.mean())}
        if self.cfg_obj.assist_force > 0.0:
            stats["assist_fraction"] = float(self.assist_fraction)
        if self.from_demo.any():
            stats["demo_start_share"] = float(self.from_demo.mean())
            stats["success_demo_starts"] = float(success[self.from_demo].mean())
        for f, family in enumerate(self.cfg_obj.families):
            mine = (self.curriculum.family == f) & fallen
            if mine.any():
                stats[f"success_{family}"] = float(success[mine].mean())
        for simulator, rows in getattr(self.backend, "part_rows", list)():
            mine = np.zeros_like(fallen)
            mine[rows] = fallen[rows]
            if mine.any():
                stats[f"success_in_{simulator}"] = float(success[mine].mean())
        return stats

    def close(self) -> None:
        """Free the simulator."""
        self.backend.close()
