"""``scripted``: a model-based fall-recovery controller for quadrupeds (no training).

The controller is a per-environment state machine driven by proprioception
only: the projected gravity g (body frame; (0, 0, -1) upright, (0, 0, +1) on
the back), the joint angles and the steps elapsed in the current phase. Every
pose is computed from the robot spec (joint limits, default pose), so the same
code drives Go2, Go1, Aliengo, Spot-like and Lite3-like. Phases:

``FOLD``   fold all legs against the body (calves at their folded limit, feet
           under the hips), then pick the next phase from g: belly down ->
           ``STAND``, anything else -> ``ROLL_A`` rolling towards the side that
           is already lower (sign of g_y).
``ROLL_A`` back -> side. The legs of the upper side swing back past
           vertical so that their straightened legs point out of the robot's
           back, into the ground, and lever that side up; the legs of the lower
           side stay folded and swing inwards (over the belly) out of the way.
``ROLL_B`` side -> belly. The pushing legs abduct outwards, turning like the
           spokes of a wheel, which lifts the back off the ground, and the lower
           legs swing out under the back so the body tips over onto its belly.
``BELLY``  belly down: fold the legs under the body again.
``STAND``  interpolate smoothly from the folded pose to the default pose.
``HOLD``   hold the default pose.

A roll that makes no progress within `ROLL_TIMEOUT` steps is abandoned and
retried in the other direction; a robot that tips over while standing or
holding starts again from ``FOLD``. Targets always move by smoothstep
interpolation between poses and stay inside the joint limits.
"""

from __future__ import annotations

import numpy as np

from frbench.robots.spec import RobotSpec

FOLD, ROLL_A, ROLL_B, BELLY, STAND, HOLD = range(6)
PHASE_NAMES = ("fold", "roll_a", "roll_b", "belly", "stand", "hold")

#: Interpolation time [control steps] into each phase's pose.
RAMP_STEPS = {FOLD: 15, ROLL_A: 20, ROLL_B: 15, BELLY: 15, STAND: 40, HOLD: 1}
#: Steps a roll phase may take before the roll is retried the other way.
ROLL_TIMEOUT = 60
#: Projected-gravity thresholds.
BELLY_GZ = -0.8       # g_z below this: lying on the belly (or standing)
TIPPED_GZ = -0.5      # g_z above this while standing: fallen again
SIDE_GY = 0.9         # |g_y| above this: lying on a side
STALL_GY = 0.6        # |g_y| above this once ROLL_A has stalled: go on with ROLL_B
STALL_STEPS = 10
#: Per phase, the (begin, end) fractions of the ramp over which calves and the other joints move.
CALF_WINDOW = np.array([(0.0, 0.5), (0.4, 1.0), (0.4, 1.0), (0.0, 0.5), (0.0, 1.0), (0.0, 1.0)])
OTHER_WINDOW = np.array([(0.3, 1.0), (0.0, 0.6), (0.0, 0.6), (0.3, 1.0), (0.0, 1.0), (0.0, 1.0)])
BELLY_CALF = 0.0
PRONE_DIRECT = False
PUSH_CALF_BEND = 0.0
LEVEL_GZ = -0.9       # g_z below this: level enough to stand up
#: Standing up waits for the body to come to rest: angular speed [rad/s] and joint tracking error [rad] below these.
SETTLED_RATE = 100.0
SETTLED_LAG = 100.0
#: Margin [rad] kept from the joint limits.
LIMIT_MARGIN = 0.05
#: Largest hip abduction used [rad] (also capped by the joint limits).
MAX_ABDUCTION = 1.0


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


class ScriptedPolicy:
    """Fold, roll onto the belly, tuck, stand (see the module docstring)."""

    name = "scripted"
    checkpoint = None
    LOWER_B = 'out'
    LOWER_FRAC = 0.7

    def supports(self, spec: RobotSpec) -> bool:
        """Quadrupeds only."""
        return spec.kind == "quadruped"

    # ------------------------------------------------------------------ poses
    def _build_poses(self, spec: RobotSpec) -> None:
        lower = np.asarray(spec.joint_lower, dtype=float)
        upper = np.asarray(spec.joint_upper, dtype=float)
        self.default = np.asarray(spec.default_pose, dtype=float)
        self.lo, self.hi = lower + LIMIT_MARGIN, upper - LIMIT_MARGIN
        hip, thigh, calf = (np.arange(j, spec.n_joints, 3) for j in range(3))
        self.hip, self.thigh, self.calf = hip, thigh, calf
        self._is_calf = np.zeros(spec.n_joints, dtype=bool)
        self._is_calf[calf] = True
        left = np.array([name[1] == "L" for name in ("FL", "FR", "RL", "RR")])
        self.left = left
        # Outward abduction is +hip for left legs, -hip for right legs.
        side = np.where(left, 1.0, -1.0)
        out_limit = np.where(left, self.hi[hip], -self.lo[hip])
        in_limit = np.where(left, -self.lo[hip], self.hi[hip])
        self.abduct_out = np.minimum(out_limit, MAX_ABDUCTION)  # magnitudes
        self.abduct_in = np.minimum(in_limit, MAX_ABDUCTION)
        self.side = side

        fold = self.default.copy()
        fold[calf] = self.lo[calf] + 0.1  # knees fully folded
        fold[thigh] = -fold[calf] / 2.0  # feet (about) under the hips
        fold[hip] = 0.0
        self.fold = self._clip(fold)

        belly = self.fold.copy()
        belly[hip] = self.default[hip]
        belly[calf] = self.fold[calf] + BELLY_CALF * (self.default[calf] - self.fold[calf])
        belly[thigh] = -belly[calf] / 2.0
        self.belly = self._clip(belly)

        # A straightened leg pointing out of the back (thigh ~ pi - calf / 2).
        push_calf = self.hi[calf] - PUSH_CALF_BEND
        push_thigh = np.minimum(self.hi[thigh], np.pi - push_calf / 2.0)
        self.push_calf, self.push_thigh = push_calf, push_thigh

    def _clip(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lo, self.hi)

    def roll_pose(self, direction: int, stage: int) -> np.ndarray:
        """Pose of a roll towards ``direction`` (+1: left side goes down) in stage 0 (ROLL_A) or 1 (ROLL_B)."""
        q = self.fold.copy()
        pushers = ~self.left if direction > 0 else self.left  # the legs of the side that goes up
        for k in range(4):
            h, t, c = self.hip[k], self.thigh[k], self.calf[k]
            if pushers[k]:
                q[t], q[c] = self.push_thigh[k], self.push_calf[k]
                # stage 1: abduct outwards (a leg pointing out of the back then also points to the lower side)
                q[h] = 0.0 if stage == 0 else self.side[k] * self.abduct_out[k]
            else:
                # lower legs: folded; inwards (over the belly) while rolling onto the side, then out under the back
                if stage == 0 or self.LOWER_B == 'in':
                    q[h] = -self.side[k] * self.abduct_in[k]
                elif self.LOWER_B == 'out':
                    q[h] = self.side[k] * self.abduct_out[k]
                elif self.LOWER_B == 'push':
                    q[t], q[c] = self.push_thigh[k], self.push_calf[k]
                    q[h] = -self.side[k] * self.abduct_in[k] * self.LOWER_FRAC
                else:
                    q[h] = 0.0
        return self._clip(q)

    # ------------------------------------------------------------ interface
    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """Start ``num_envs`` episodes: every environment begins by folding its legs."""
        self.spec = spec
        self.num_envs = num_envs
        self._build_poses(spec)
        n = num_envs
        self.phase = np.full(n, FOLD, dtype=int)
        self.steps = np.zeros(n, dtype=int)  # steps since the phase began
        self.direction = np.ones(n, dtype=int)
        self.start = None  # (n, J) targets at phase entry
        self.goal = np.tile(self.fold, (n, 1))
        self.target = None

    def _enter(self, i: int, phase: int, goal: np.ndarray) -> None:
        self.phase[i] = phase
        self.steps[i] = 0
        self.start[i] = self.target[i]
        self.goal[i] = goal

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, n_joints) [rad]."""
        g = np.asarray(obs["projected_gravity"], dtype=float)
        if self.target is None:  # first step: start from the measured joint angles
            self.target = self._clip(np.asarray(obs["joint_pos"], dtype=float).copy())
            self.start = self.target.copy()
            belly_down = g[:, 2] < TIPPED_GZ
            self.goal[belly_down] = self.belly
            if PRONE_DIRECT:
                for i in np.flatnonzero(belly_down):
                    self._enter(i, STAND, self.default)
        rate = np.linalg.norm(np.asarray(obs["base_angvel"], dtype=float), axis=1)
        lag = np.abs(np.asarray(obs["joint_pos"], dtype=float) - self.target).max(axis=1)
        self._settled = (rate < SETTLED_RATE) & (lag < SETTLED_LAG)
        for i in range(self.num_envs):
            self._transition(i, g[i])
        self.steps += 1
        ramp = np.array([RAMP_STEPS[p] for p in self.phase], dtype=float)[:, None]
        progress = self.steps[:, None] / ramp
        # Folding phases fold the knees first and rolls swing the folded legs before extending them,
        # so legs never sweep through the ground at full length.
        begin = np.where(self._is_calf, CALF_WINDOW[self.phase, 0][:, None], OTHER_WINDOW[self.phase, 0][:, None])
        end = np.where(self._is_calf, CALF_WINDOW[self.phase, 1][:, None], OTHER_WINDOW[self.phase, 1][:, None])
        w = _smoothstep((progress - begin) / (end - begin))
        self.target = self._clip(self.start + w * (self.goal - self.start))
        return self.target.copy()

    def _transition(self, i: int, g: np.ndarray) -> None:
        phase, steps = self.phase[i], self.steps[i]
        ramp_done = steps >= RAMP_STEPS[phase]
        gy, gz = g[1], g[2]
        d = self.direction[i]
        if phase == FOLD:
            if not ramp_done:
                return
            if gz < TIPPED_GZ:
                self._enter(i, BELLY, self.belly)
                return
            if abs(gy) > 0.1:
                self.direction[i] = d = 1 if gy > 0 else -1
            if self._on_side(d, gy, gz):
                self._enter(i, ROLL_B, self.roll_pose(d, 1))
            else:
                self._enter(i, ROLL_A, self.roll_pose(d, 0))
        elif phase == ROLL_A:
            if gz < TIPPED_GZ:
                self._enter(i, BELLY, self.belly)
            elif self._on_side(d, gy, gz) or (d * gy > STALL_GY and steps > RAMP_STEPS[ROLL_A] + STALL_STEPS):
                self._enter(i, ROLL_B, self.roll_pose(d, 1))
            elif steps > ROLL_TIMEOUT:
                self.direction[i] = -d
                self._enter(i, FOLD, self.fold)
        elif phase == ROLL_B:
            if gz < TIPPED_GZ:
                self._enter(i, BELLY, self.belly)
            elif steps > ROLL_TIMEOUT or (gz > 0.9 and steps > RAMP_STEPS[ROLL_B] + STALL_STEPS):
                self.direction[i] = -d
                self._enter(i, FOLD, self.fold)
        elif phase == BELLY:
            if ramp_done and gz < LEVEL_GZ and self._settled[i]:
                self._enter(i, STAND, self.default)
            elif gz > 0.2 or steps > ROLL_TIMEOUT:
                self._enter(i, FOLD, self.fold)
        elif phase in (STAND, HOLD):
            if gz > TIPPED_GZ:
                self._enter(i, FOLD, self.fold)
            elif phase == STAND and ramp_done:
                self._enter(i, HOLD, self.default)

    @staticmethod
    def _on_side(d: int, gy: float, gz: float) -> bool:
        """Lying on the side towards which the roll ``d`` goes."""
        return d * gy > SIDE_GY or (d * gy > 0.5 and gz < 0.2)
