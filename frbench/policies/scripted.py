"""``scripted``: a model-based fall-recovery controller for quadrupeds (no training).

A per-environment state machine driven by proprioception only: the projected
gravity g (body frame; (0, 0, -1) upright, (0, 0, +1) on the back), the
measured joint angles (only to start from where the legs are) and the control
steps spent in the current phase. Every pose is computed from the robot spec
(joint limits, default pose; canonical order FL, FR, RL, RR x hip, thigh, calf),
written in canonical leg angles: the Unitree sign convention with legs that
hang straight down at zero. `frbench.robots.joint_frame` maps any robot's joint
directions, joint zeros (the segment directions read from its kinematics) and
knee direction onto them, so the same code drives Go2, Go1, Aliengo,
Spot-like, Lite3-like and quadrupeds given by path: Solo and ANYmal (knees
forward), Spirit and Vision60 (legs folded at zero angles), Laikago's toe files
(legs bent at zero). The roll direction d = +1 rolls the left side down (g_y
grows), d = -1 the right side. Phases:

``FOLD``    fold the legs against the body (calves at their folded limit, feet
            under the hips); then choose from g: belly down -> ``BELLY``;
            standing on the nose or tail -> ``TOPPLE``; already on a side ->
            ``ROLL_B``; otherwise (back) -> ``ROLL_A``, rolling towards the
            side that is already lower (sign of g_y).
``TOPPLE``  the legs at the lower end straighten along the body and push
            that end away until the robot falls over; then ``FOLD`` again.
``ROLL_A``  back -> side. The legs of the side that must go up straighten and
            swing back past vertical so that they point out of the robot's
            back into the ground and lever that side up; the legs of the other
            side stay folded and swing inwards, over the belly, out of the way.
``ROLL_B``  side -> belly. The levering legs abduct outwards (a spoke of a
            wheel turning on), which lifts the back, while the folded lower legs
            swing outwards and back under the back, so the body tips onto its
            belly instead of sliding.
``BELLY``   belly down: fold the legs under the body, hips splayed a little
            for a wide, roll-resistant base; wait until level and still.
``STAND``   interpolate from the folded pose to the default pose.
``HOLD``    hold the default pose.

A roll that stalls or times out is retried the other way round; a robot that
tips over while standing, holding or tucking starts again from ``FOLD``. Targets
move by smoothstep interpolation between poses (knees fold before the thighs
swing, folded legs swing before they straighten) and stay inside the joint
limits.
"""

from __future__ import annotations

import numpy as np

from frbench.backends.base import CONTROL_DT
from frbench.robots.joint_frame import joint_frame
from frbench.robots.spec import QUADRUPED_LEGS, RobotSpec

FOLD, ROLL_A, ROLL_B, BELLY, STAND, HOLD, TOPPLE = range(7)
PHASE_NAMES = ("fold", "roll_a", "roll_b", "belly", "stand", "hold", "topple")

#: Interpolation time [control steps] from the previous targets to each phase's pose.
RAMP_STEPS = np.array([15, 20, 15, 15, 40, 1, 15])
#: Per phase, the (begin, end) fractions of the ramp over which the calves and the other joints move:
#: folding phases fold the knees first, rolls swing the folded legs before straightening them.
CALF_WINDOW = np.array([(0.0, 0.5), (0.4, 1.0), (0.4, 1.0), (0.0, 0.5), (0.0, 1.0), (0.0, 1.0), (0.4, 1.0)])
OTHER_WINDOW = np.array([(0.3, 1.0), (0.0, 0.6), (0.0, 0.6), (0.3, 1.0), (0.0, 1.0), (0.0, 1.0), (0.0, 0.6)])

#: Steps a roll phase may last before the roll is retried in the other direction.
ROLL_TIMEOUT = 60
#: Steps after its ramp before a roll phase counts as stalled.
STALL_STEPS = 10
#: Projected-gravity thresholds.
TIPPED_GZ = -0.5  # g_z above this while tucked or standing: fallen over (again); below: belly down
LEVEL_GZ = -0.9  # g_z below this: level enough to stand up
SIDE_GY = 0.9  # d * g_y above this: lying on the side the roll goes to
STALL_GY = 0.6  # d * g_y above this when ROLL_A stalls: go on with ROLL_B
BACK_GZ = 0.9  # g_z above this when ROLL_B stalls: fell back onto the back
PITCH_GX = 0.7  # |g_x| above this: standing on the nose or the tail
#: Standing up waits until the body tilts slower than this [rad/s] (from the change of g, which
#: unlike base_angvel does not see joint chatter), or at most BELLY_WAIT steps after the tuck.
SETTLED_TILT_RATE = 1.0
TILT_RATE_SMOOTHING = 0.5
BELLY_WAIT = 15

#: Margin [rad] kept from the joint limits; the folded knee stays this much further inside.
LIMIT_MARGIN = 0.05
FOLD_MARGIN = 0.1
#: Deepest knee fold [rad] when the limits allow more (limits of ±π from a file without real ones).
MAX_FOLD = 2.7
#: The straightened knee stays this bent [rad] when its limits would let it bend backwards.
STRAIGHT_KNEE = 0.1
#: Largest hip abduction used [rad] (also capped by the joint limits).
MAX_ABDUCTION = 1.0
#: Belly tuck: hips splayed outwards by this fraction of the abduction range.
BELLY_SPLAY = 0.5
#: ROLL_B: the folded lower legs' thighs swing this much [rad] further back, under the back.
LOWER_THIGH_BACK = 0.8


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


class ScriptedPolicy:
    """Fold, roll onto the belly, tuck, stand (see the module docstring)."""

    name = "scripted"
    checkpoint = None

    def supports(self, spec: RobotSpec) -> bool:
        """Quadrupeds (12 joints, legs FL, FR, RL, RR x hip, thigh, calf)."""
        return spec.kind == "quadruped" and spec.n_joints == 3 * len(QUADRUPED_LEGS)

    # ------------------------------------------------------------------ poses
    def _build_poses(self, spec: RobotSpec) -> None:
        """Every pose from the spec's limits and default pose (all (n_joints,) arrays), in canonical leg angles."""
        frame = joint_frame(spec, turn=False)  # its poses mirror each forward knee
        self.sign, self.offset = np.asarray(frame.sign), np.asarray(frame.offset)
        default = self.to_canonical(np.asarray(spec.default_pose, dtype=float))
        lower = self.to_canonical(np.asarray(spec.joint_lower, dtype=float))
        upper = self.to_canonical(np.asarray(spec.joint_upper, dtype=float))
        self.default = default
        self.lo = np.minimum(lower, upper) + LIMIT_MARGIN
        self.hi = np.maximum(lower, upper) - LIMIT_MARGIN
        n = spec.n_joints
        self.hip, self.thigh, self.calf = (np.arange(j, n, 3) for j in range(3))
        self._is_calf = np.zeros(n, dtype=bool)
        self._is_calf[self.calf] = True
        self.left = np.array([leg[1] == "L" for leg in QUADRUPED_LEGS])
        # +hip moves a foot towards +y: outwards for left legs, inwards for right legs.
        self.side = np.where(self.left, 1.0, -1.0)
        hip_lo, hip_hi = self.lo[self.hip], self.hi[self.hip]
        self.abduct_out = np.minimum(np.where(self.left, hip_hi, -hip_lo), MAX_ABDUCTION)  # magnitudes
        self.abduct_in = np.minimum(np.where(self.left, -hip_lo, hip_hi), MAX_ABDUCTION)

        fold = self.default.copy()
        fold[self.calf] = np.maximum(self.lo[self.calf] + FOLD_MARGIN, -MAX_FOLD)  # knees folded
        fold[self.thigh] = -fold[self.calf] / 2.0  # feet (about) under the hips
        fold[self.hip] = 0.0
        self.fold = self._clip(fold)

        belly = self.fold.copy()
        belly[self.hip] = self.default[self.hip] + BELLY_SPLAY * self.side * self.abduct_out
        self.belly = self._clip(belly)

        # A straightened leg pointing out of the back: thigh ~ pi - calf / 2, as far as the limit allows.
        self.push_calf = np.minimum(self.hi[self.calf], -STRAIGHT_KNEE)  # the straightest knee, never bent backwards
        self.push_thigh = np.minimum(self.hi[self.thigh], np.pi - self.push_calf / 2.0)

    def to_canonical(self, q: np.ndarray) -> np.ndarray:
        """The robot's joint angles [rad] (..., n_joints) as canonical leg angles (see `frbench.robots.joint_frame`)."""
        return self.sign * q + self.offset if self.offset.any() else self.sign * q

    def to_joints(self, canonical: np.ndarray) -> np.ndarray:
        """Canonical leg angles [rad] (..., n_joints) as the robot's joint angles (inverse of `to_canonical`)."""
        return self.sign * (canonical - self.offset) if self.offset.any() else self.sign * canonical

    def topple_pose(self, nose_down: bool) -> np.ndarray:
        """Pose tipping over a robot standing on its nose (or tail): the legs at that end straighten and
        point along the body towards the ground, pushing that end away; the others fold."""
        q = self.fold.copy()
        end = np.array([leg[0] == ("F" if nose_down else "R") for leg in QUADRUPED_LEGS])
        for k in np.flatnonzero(end):
            t, c = self.thigh[k], self.calf[k]
            q[c] = self.push_calf[k]
            q[t] = (-np.pi / 2.0 if nose_down else np.pi / 2.0) - q[c] / 2.0
        return self._clip(q)

    def _clip(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lo, self.hi)

    def roll_pose(self, direction: int, stage: int) -> np.ndarray:
        """Pose rolling towards ``direction`` (+1: the left side goes down): stage 0 = ROLL_A, 1 = ROLL_B."""
        q = self.fold.copy()
        levers = ~self.left if direction > 0 else self.left  # the legs of the side that goes up
        for k in range(len(QUADRUPED_LEGS)):
            h, t, c = self.hip[k], self.thigh[k], self.calf[k]
            if levers[k]:
                q[t], q[c] = self.push_thigh[k], self.push_calf[k]
                q[h] = 0.0 if stage == 0 else self.side[k] * self.abduct_out[k]
            elif stage == 0:
                q[h] = -self.side[k] * self.abduct_in[k]  # folded, over the belly
            else:
                q[h] = self.side[k] * self.abduct_out[k]  # folded, out and back under the back
                q[t] = self.fold[t] + LOWER_THIGH_BACK
        return self._clip(q)

    # ------------------------------------------------------------- interface
    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """Start ``num_envs`` episodes; each begins in ``FOLD`` from its measured joint angles."""
        self.num_envs = num_envs
        self._build_poses(spec)
        n = num_envs
        self.phase = np.full(n, FOLD, dtype=int)
        self.steps = np.zeros(n, dtype=int)  # steps since the phase began
        self.direction = np.ones(n, dtype=int)
        self.tries = np.zeros(n, dtype=int)  # abandoned rolls
        self.goal = np.tile(self.fold, (n, 1))
        self.start = None  # targets when the phase began, set on the first act()
        self.target = None
        self._prev_g = None
        self._tilt_rate = np.zeros(n)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, n_joints) [rad]."""
        g = np.asarray(obs["projected_gravity"], dtype=float)
        if self.target is None:  # first step: interpolate from where the joints are
            self.target = self._clip(self.to_canonical(np.asarray(obs["joint_pos"], dtype=float)))
            self.start = self.target.copy()
            self.goal[g[:, 2] < TIPPED_GZ] = self.belly
            self._prev_g = g.copy()
        rate = np.linalg.norm(g - self._prev_g, axis=1) / CONTROL_DT
        self._tilt_rate = TILT_RATE_SMOOTHING * self._tilt_rate + (1.0 - TILT_RATE_SMOOTHING) * rate
        self._prev_g = g.copy()
        for i in range(self.num_envs):
            self._transition(i, g[i])
        self.steps += 1
        progress = (self.steps / RAMP_STEPS[self.phase])[:, None]  # (N, 1)
        calf = self._is_calf[None, :]
        begin = np.where(calf, CALF_WINDOW[self.phase, :1], OTHER_WINDOW[self.phase, :1])  # (N, n_joints)
        end = np.where(calf, CALF_WINDOW[self.phase, 1:], OTHER_WINDOW[self.phase, 1:])
        w = _smoothstep((progress - begin) / (end - begin))
        self.target = self._clip(self.start + w * (self.goal - self.start))
        return self.to_joints(self.target)

    # ------------------------------------------------------------ the machine
    def _enter(self, i: int, phase: int, goal: np.ndarray) -> None:
        self.phase[i] = phase
        self.steps[i] = 0
        self.start[i] = self.target[i]
        self.goal[i] = goal

    def _retry(self, i: int) -> None:
        """Give up the current roll: fold, then roll the other way."""
        self.tries[i] += 1
        self.direction[i] = -self.direction[i]
        self._enter(i, FOLD, self.fold)

    @staticmethod
    def _on_side(d: int, gy: float, gz: float) -> bool:
        """Lying on the side the roll ``d`` goes to."""
        return d * gy > SIDE_GY or (d * gy > 0.5 and gz < 0.2)

    def _transition(self, i: int, g: np.ndarray) -> None:
        phase, steps = self.phase[i], self.steps[i]
        ramp_done = steps >= RAMP_STEPS[phase]
        stalled = steps > RAMP_STEPS[phase] + STALL_STEPS
        gy, gz = g[1], g[2]
        d = self.direction[i]
        if phase == FOLD:
            if not ramp_done:
                return
            if gz < TIPPED_GZ:
                self._enter(i, BELLY, self.belly)
                return
            if abs(g[0]) > PITCH_GX:
                self._enter(i, TOPPLE, self.topple_pose(g[0] > 0))
                return
            if self.tries[i] == 0 and abs(gy) > 0.1:  # first roll: towards the lower side
                self.direction[i] = d = 1 if gy > 0 else -1
            if self._on_side(d, gy, gz):
                self._enter(i, ROLL_B, self.roll_pose(d, 1))
            else:
                self._enter(i, ROLL_A, self.roll_pose(d, 0))
        elif phase == ROLL_A:
            if gz < TIPPED_GZ:
                self._enter(i, BELLY, self.belly)
            elif self._on_side(d, gy, gz) or (stalled and d * gy > STALL_GY):
                self._enter(i, ROLL_B, self.roll_pose(d, 1))
            elif steps > ROLL_TIMEOUT:
                self._retry(i)
        elif phase == ROLL_B:
            if gz < TIPPED_GZ:
                self._enter(i, BELLY, self.belly)
            elif steps > ROLL_TIMEOUT or (stalled and gz > BACK_GZ):
                self._retry(i)
        elif phase == TOPPLE:
            if abs(g[0]) < PITCH_GX - 0.2 or steps > ROLL_TIMEOUT:
                self._enter(i, FOLD, self.fold)
        elif phase == BELLY:
            settled = self._tilt_rate[i] < SETTLED_TILT_RATE or steps > RAMP_STEPS[BELLY] + BELLY_WAIT
            if ramp_done and gz < LEVEL_GZ and settled:
                self._enter(i, STAND, self.default)
            elif gz > 0.2 or steps > ROLL_TIMEOUT:
                self._enter(i, FOLD, self.fold)
        elif gz > TIPPED_GZ:  # STAND or HOLD, fallen over
            self._enter(i, FOLD, self.fold)
        elif phase == STAND and ramp_done:
            self._enter(i, HOLD, self.default)
