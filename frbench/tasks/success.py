"""The success test (protocol 1.1) and the per-episode metrics, on trajectories of any length.

A robot succeeds when, at some time within the episode, it is *stably upright*
for `HOLD_SECONDS` without a break, and at the end of that hold its horizontal
displacement from the start is under `MAX_DISPLACEMENT` (docs/protocol.md).
*Upright* at one control step means all of:

* tilt: the base's up axis within `MAX_TILT_DEG` of vertical (for a humanoid
  the pelvis *and* the torso, each within `HUMANOID_MAX_TILT_DEG`);
* height: the base at least `MIN_HEIGHT_FRACTION` (quadruped) or
  `HUMANOID_UP_HEIGHT` / `HUMANOID_REFERENCE_HEIGHT` (humanoid) of its nominal
  height above the terrain beneath it;
* support: no link but the feet touches anything;
* surface: the terrain beneath the base is at most `STEP_TOLERANCE_M` below the
  surface the robot fell on (`StartSurface`): standing on a pit floor, or
  more than one step below the platform or beam tops it lay on, is not a
  recovery. The incline of a slope is one surface (no drop is measured there).

Protocol 1.0 read the height from the terrain beneath the base only (a robot on
a pit floor passed) and used HoST's pelvis-height rule for humanoids (a hand or
head stand passed); both gaps are closed here.

The success test (`SuccessTracker`) runs on numpy arrays or torch tensors on any device (one implementation,
`frbench.arrays`): evaluation feeds numpy signals, the device training path torch ones.

`EpisodeMetrics` (numpy; evaluation only) accumulates, per environment and control step: energy
∫|τ·q̇|dt [J], smoothness (mean |Δ²q| [rad]), peak non-foot contact force [N],
roll (∫ω_x dt, rolled over when its magnitude exceeds π at any time), final and
maximum displacement [m], divergence.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from frbench.robots.kinematics import _axis_rotation, chain_to_link
from frbench.arrays import cummax, device_of, float_dtype, namespace
from frbench.tasks.initial_states import quat_to_matrix
from frbench.tasks.protocol import CONTROL_DT
from frbench.terrains import height_at, support_height

MAX_TILT_DEG = 30.0
MIN_HEIGHT_FRACTION = 0.75
HOLD_SECONDS = 0.5
MAX_DISPLACEMENT = 1.0
#: Humanoid: pelvis height [m] (scaled by nominal height / `HUMANOID_REFERENCE_HEIGHT`) that counts as standing.
HUMANOID_UP_HEIGHT = 0.7
HUMANOID_REFERENCE_HEIGHT = 0.78
#: Humanoid: largest tilt of the pelvis and of the torso from vertical [deg] that counts as upright.
HUMANOID_MAX_TILT_DEG = 30.0
#: How far below the surface the robot fell on the terrain under its base may lie [m]: one step of the
#: steepest stairs (level 10, 0.25 m).
STEP_TOLERANCE_M = 0.25
#: Radius [m] around the base at t = 0 whose highest terrain point is the surface the robot fell on.
START_SURFACE_RADIUS_M = 0.15
HOLD_STEPS = int(round(HOLD_SECONDS / CONTROL_DT))


@dataclass
class StepSignals:
    """What the success test and the metrics read at one control step, each with N rows (numpy arrays, or torch
    tensors for the success test on a device).

    Attributes:
        gravity_z: projected gravity z of the base (N,) (−1 upright).
        height: base height above the terrain beneath it (N,) [m].
        body_contact: any non-foot link touches something (N,).
        displacement: horizontal distance of the base from its start (N,) [m].
        surface_drop: how far the terrain beneath the base lies below the surface the robot fell on (N,) [m]
            (`StartSurface.drop`); None: not measured (0).
        torso_gravity_z: projected gravity z of a humanoid's torso (N,) (`TorsoFrame`); None: not measured.
    """

    gravity_z: np.ndarray
    height: np.ndarray
    body_contact: np.ndarray
    displacement: np.ndarray
    surface_drop: np.ndarray | None = None
    torso_gravity_z: np.ndarray | None = None


class StartSurface:
    """The surface N robots fell on: the highest terrain point within `START_SURFACE_RADIUS_M` of each base at t = 0.

    Args:
        terrain: a `frbench.terrains.Terrain`.
        start_xy: (N, 2) base positions at t = 0 [m].
    """

    def __init__(self, terrain, start_xy: np.ndarray):
        self.terrain = terrain
        self.incline = any(box.rotation()[2, 2] != 1.0 for box in terrain.boxes)
        self.z = np.array([support_height(terrain, xy, START_SURFACE_RADIUS_M) for xy in np.asarray(start_xy)])

    def drop(self, base_xy: np.ndarray, terrain_height: np.ndarray | None = None) -> np.ndarray:
        """(…, N) [m] the start surface's height minus the terrain height beneath ``base_xy`` (…, N, 2); 0 on an
        incline. ``terrain_height`` (…, N) [m]: ``height_at(terrain, base_xy)`` when the caller has it already."""
        if self.incline:
            return np.zeros(np.shape(base_xy)[:-1])
        return self.z - (height_at(self.terrain, base_xy) if terrain_height is None else terrain_height)


class TorsoFrame:
    """A humanoid torso's orientation from the base orientation and the joints between them (forward kinematics).

    Args:
        spec: the robot; its simulation URDF gives the chain from the root link to ``link``.
        link: the torso link's name.
    """

    def __init__(self, spec, link: str = "torso_link"):
        self.chain, self.index = chain_to_link(spec, link)

    def gravity_z(self, base_quat: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(N,) projected gravity z of the torso: −(world z of the torso's z axis); base_quat (N, 4) wxyz, q (N, n)."""
        out = np.empty(len(q))
        for i in range(len(q)):
            rotation = quat_to_matrix(base_quat[i])
            for joint, k in zip(self.chain, self.index):
                rotation = rotation @ joint.origin[:3, :3]
                if k >= 0:
                    rotation = rotation @ _axis_rotation(joint.axis, q[i, k])
            out[i] = -rotation[2, 2]
        return out


def torso_frame(spec) -> TorsoFrame | None:
    """A humanoid's `TorsoFrame` (its ``torso_link``), or None for quadrupeds and humanoids without that link."""
    if spec.kind != "humanoid":
        return None
    try:
        return TorsoFrame(spec)
    except StopIteration:
        return None


class SuccessTracker:
    """Online success test for N episodes (see the module docstring), on numpy arrays (evaluation) or torch
    tensors on any device (the device training path): the signals fed decide, ``like`` (an array) gives the
    namespace, device and float dtype of the tracker's own state (default numpy, float64)."""

    def __init__(self, num_envs: int, kind: str, nominal_height, like=None):
        """``nominal_height`` [m]: one value, or one per environment (N,) when robots differ."""
        xp = namespace(like)
        device = device_of(like) if like is not None else None
        self.kind = kind
        self.nominal_height = nominal_height
        self.success = xp.zeros(num_envs, dtype=xp.bool, device=device)
        self.time_to_recover = xp.full(num_envs, float("nan"), dtype=float_dtype(xp, like), device=device)
        self._streak = xp.zeros(num_envs, dtype=xp.int64, device=device)
        self._step = 0
        nominal = _array(nominal_height)
        if kind == "humanoid":
            self.min_height = HUMANOID_UP_HEIGHT / HUMANOID_REFERENCE_HEIGHT * nominal
            self.max_tilt_deg = HUMANOID_MAX_TILT_DEG
        else:
            self.min_height = MIN_HEIGHT_FRACTION * nominal
            self.max_tilt_deg = MAX_TILT_DEG
        self._cos_bound = float(np.cos(np.radians(self.max_tilt_deg)))

    @property
    def up_height(self) -> "float | np.ndarray":
        """Humanoid: the pelvis height [m] that counts as standing (the key-frame search's objective reads it)."""
        return self.min_height

    @property
    def floor_height(self) -> "float | np.ndarray":
        """Humanoid: protocol 1.0's floor, 0.5 m scaled by nominal height / 0.78 m (the key-frame search's objective)."""
        return 0.5 / HUMANOID_REFERENCE_HEIGHT * _array(self.nominal_height)

    def up_pose(self, s: StepSignals):
        """(N,) the tilt, height and surface conditions (body contact not considered): the *upright bound*."""
        cos_bound = self._cos_bound
        ok = (s.gravity_z <= -cos_bound) & (s.height >= self.min_height)
        if s.torso_gravity_z is not None:
            ok = ok & (s.torso_gravity_z <= -cos_bound)
        if s.surface_drop is not None:
            ok = ok & (s.surface_drop <= STEP_TOLERANCE_M)
        return ok

    def upright(self, s: StepSignals):
        """(N,) the stability condition at this step."""
        return self.up_pose(s) & ~s.body_contact

    def update(self, s: StepSignals, alive=None) -> None:
        """Feed one control step (``alive`` False for diverged episodes, which cannot succeed)."""
        self.update_steps(_leading_step(s), None if alive is None else alive[None])

    def update_steps(self, s: StepSignals, alive=None) -> None:
        """Feed k control steps at once: ``s``'s arrays and ``alive`` are (k, N), step after step. The same as k
        calls of `update` (the streaks, the first step of each hold and the divergence masks are integer and
        boolean bookkeeping, here done with cumulative maxima over the steps instead of a loop)."""
        up = self.upright(s) if alive is None else self.upright(s) & alive
        xp = namespace(up)
        k = up.shape[0]
        steps = xp.arange(1, k + 1, dtype=xp.int64, device=device_of(up))[:, None]  # 1..k
        last_down = cummax(xp.where(up, 0, steps), axis=0)  # the last step not upright (0: none)
        streak = steps - last_down + xp.where(last_down == 0, self._streak, 0)
        holds = (streak >= HOLD_STEPS) & (s.displacement < MAX_DISPLACEMENT)
        # success_t = alive_t & (success_{t-1} | holds_t): true when a hold came after the last dead step
        last_hold = cummax(xp.where(holds, steps, 0), axis=0)
        last_dead = xp.zeros_like(last_hold) if alive is None else cummax(xp.where(alive, 0, steps), axis=0)
        success = (last_hold > last_dead) | (self.success & (last_dead == 0))
        before = xp.concat([self.success[None], success[:-1]])
        done = holds & ~before
        # each environment's last step with a new hold (rows without one keep their time)
        last_done = k - 1 - xp.argmax(xp.astype(xp.flip(done, axis=0), xp.int8), axis=0)
        recovered = xp.astype(self._step + 1 + last_done - HOLD_STEPS + 1, self.time_to_recover.dtype) * CONTROL_DT
        self.time_to_recover = xp.where(xp.any(done, axis=0), recovered, self.time_to_recover)
        self._streak = streak[-1]
        self.success = xp.asarray(success[-1], copy=True)
        self._step += k


def _array(value):
    """``value`` itself when it is an array of any namespace, else ``np.asarray(value)``."""
    from array_api_compat import is_array_api_obj

    return value if is_array_api_obj(value) else np.asarray(value)


def _leading_step(s: StepSignals) -> StepSignals:
    """``s`` with a leading axis of one step: (N,) arrays become (1, N)."""
    return StepSignals(*(None if getattr(s, f.name) is None else _array(getattr(s, f.name))[None]
                         for f in fields(StepSignals)))


def _where_ok(ok: np.ndarray | None, values: np.ndarray, other: "float | np.ndarray" = 0.0) -> np.ndarray:
    """``np.where(ok, values, other)``; ``ok`` None means every row (then ``values`` themselves, the same numbers)."""
    return values if ok is None else np.where(ok, values, other)


def _running_sum(start: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """(k, N): ``start`` (N,) plus the rows of ``steps`` (k, N) added one after another (``np.add.accumulate``
    adds in order, as ``start += row`` does row by row)."""
    return np.add.accumulate(np.concatenate([start[None], steps]), axis=0)[1:]


class EpisodeMetrics:
    """Per-episode metrics of N environments (see the module docstring)."""

    def __init__(self, num_envs: int, n_joints: int):
        self.energy = np.zeros(num_envs)
        self.peak_contact_force = np.zeros(num_envs)
        self.max_displacement = np.zeros(num_envs)
        self.final_displacement = np.zeros(num_envs)
        self.roll = np.zeros(num_envs)
        self.rolled_over = np.zeros(num_envs, dtype=bool)
        self.diverged = np.zeros(num_envs, dtype=bool)
        self._second_diff_sum = np.zeros(num_envs)
        self._second_diff_count = 0
        self._q_prev = None
        self._q_prev2 = None

    def update(self, q, qd, tau, angvel_x, body_force_max, displacement, diverged) -> None:
        """Feed one control step: q, qd, tau (N, n_joints); angvel_x, body_force_max, displacement, diverged (N,)."""
        self.update_steps(*(np.asarray(a)[None] for a in (q, qd, tau, angvel_x, body_force_max, displacement,
                                                          diverged)))

    def update_steps(self, q, qd, tau, angvel_x, body_force_max, displacement, diverged) -> None:
        """Feed k control steps at once, each argument with a leading step axis: q, qd, tau (k, N, n_joints);
        angvel_x, body_force_max, displacement, diverged (k, N). The same numbers as k calls of `update`: the
        running sums are cumulative sums along the steps (one addition after another, as the loop adds), the
        rest maxima and the last valid value."""
        ok = ~diverged if diverged.any() else None  # None: every row (the common case)
        self.energy = _running_sum(self.energy, _where_ok(ok, np.abs(tau * qd).sum(axis=-1) * CONTROL_DT))[-1]
        self.peak_contact_force = np.maximum(self.peak_contact_force, _where_ok(ok, body_force_max).max(axis=0))
        self.max_displacement = np.maximum(self.max_displacement, _where_ok(ok, displacement).max(axis=0))
        if ok is None:
            self.final_displacement = displacement[-1].copy()
        else:
            last = len(ok) - 1 - np.argmax(ok[::-1], axis=0)  # each environment's last valid step
            self.final_displacement = np.where(ok.any(axis=0), displacement[last, np.arange(ok.shape[1])],
                                               self.final_displacement)
        rolls = _running_sum(self.roll, _where_ok(ok, angvel_x * CONTROL_DT))
        self.roll = rolls[-1]
        self.rolled_over |= (np.abs(rolls) > np.pi).any(axis=0)
        self.diverged |= diverged.any(axis=0)
        joints = np.concatenate([p[None] for p in (self._q_prev2, self._q_prev) if p is not None] + [q])
        if len(joints) >= 3:  # the steps that have two predecessors
            second = np.abs(joints[2:] - 2 * joints[1:-1] + joints[:-2]).mean(axis=-1)
            second = _where_ok(None if ok is None else ok[len(ok) - len(second):], second)
            self._second_diff_sum = _running_sum(self._second_diff_sum, second)[-1]
            self._second_diff_count += len(second)
        self._q_prev2 = joints[-2].copy() if len(joints) >= 2 else None
        self._q_prev = joints[-1].copy()

    @property
    def smoothness(self) -> np.ndarray:
        """Mean |Δ²q| per episode [rad] (0 for episodes shorter than three steps)."""
        return self._second_diff_sum / max(self._second_diff_count, 1)
