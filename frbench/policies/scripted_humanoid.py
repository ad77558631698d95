"""``scripted-humanoid``: a model-based key-frame getting-up controller for the Unitree G1 (no training).

draft
"""

from __future__ import annotations

import numpy as np

from frbench.robots.spec import RobotSpec

LIE, ROLL, PUSH_A, PUSH_B, TUCK, SIT, SQUAT, RISE, HOLD = range(9)
PHASE_NAMES = ("lie", "roll", "push_a", "push_b", "tuck", "sit", "squat", "rise", "hold")

#: Interpolation time [control steps] from the previous targets to each phase's pose.
RAMP_STEPS = np.array([10, 30, 10, 20, 25, 30, 25, 50, 1])
#: Steps each phase holds its pose after the ramp before moving on.
HOLD_STEPS = np.array([0, 0, 0, 5, 10, 10, 5, 0, 0])

LEG_JOINTS = ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")
ARM_JOINTS = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll", "wrist_pitch", "wrist_yaw")
WAIST_JOINTS = ("waist_yaw", "waist_roll", "waist_pitch")
#: Joints whose sign is mirrored between the left and the right side (roll and yaw axes).
MIRRORED = ("hip_roll", "hip_yaw", "ankle_roll", "shoulder_roll", "shoulder_yaw", "wrist_roll", "wrist_yaw")
SIDES = ("left", "right")
G1_JOINTS = tuple(f"{s}_{j}_joint" for s in SIDES for j in LEG_JOINTS) + tuple(f"{j}_joint" for j in WAIST_JOINTS) + tuple(
    f"{s}_{j}_joint" for s in SIDES for j in ARM_JOINTS
)

LIMIT_MARGIN = 0.05

#: Key poses: joint (without side) -> angle [rad] for the left side; the right mirrors roll/yaw.
LIE_POSE = {"hip_pitch": 0.0, "knee": 0.2, "ankle_pitch": 0.0, "shoulder_pitch": 0.0, "shoulder_roll": 0.2, "elbow": 1.5}
PUSH_A_POSE = {"hip_pitch": 0.0, "knee": 0.2, "ankle_pitch": 0.0, "shoulder_pitch": 0.3, "shoulder_roll": 0.2, "elbow": 0.0}
PUSH_B_POSE = {"hip_pitch": 0.0, "knee": 0.2, "ankle_pitch": 0.0, "shoulder_pitch": -1.4, "shoulder_roll": 0.2, "elbow": 1.5}
TUCK_POSE = {"hip_pitch": -1.8, "hip_roll": 0.15, "knee": 2.4, "ankle_pitch": 0.0, "shoulder_pitch": -1.6, "shoulder_roll": 0.2, "elbow": 1.5}
SIT_POSE = {"hip_pitch": -1.0, "hip_roll": 0.15, "knee": 0.8, "ankle_pitch": 0.4, "shoulder_pitch": -1.2, "shoulder_roll": 0.2, "elbow": 1.5}
SQUAT_POSE = {"hip_pitch": -2.4, "hip_roll": 0.15, "knee": 0.3, "ankle_pitch": -0.3, "waist_pitch": 0.3, "shoulder_pitch": -2.0, "shoulder_roll": 0.2, "elbow": 1.5}
ROLL_POSE_DOWN = {"shoulder_pitch": -2.6, "shoulder_roll": 0.3, "elbow": 1.5}  # the arm of the side going down: overhead
ROLL_POSE_UP = {"hip_pitch": -1.2, "hip_roll": -0.4, "knee": 1.0, "shoulder_pitch": -1.5, "shoulder_roll": -1.0, "elbow": 0.5}


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


class HumanoidScriptedPolicy:
    """Lie flat, roll onto the belly, push up, tuck, squat, rise (see the module docstring)."""

    name = "scripted-humanoid"
    checkpoint = None

    def supports(self, spec: RobotSpec) -> bool:
        """Humanoids with the Unitree G1's 29 joints (matched by name)."""
        return spec.kind == "humanoid" and set(spec.joint_names) == set(G1_JOINTS)

    # ------------------------------------------------------------------ poses
    def _pose(self, left: dict, right: dict | None = None, base: np.ndarray | None = None) -> np.ndarray:
        """A pose from named joint angles (``right`` defaults to the mirror image of ``left``)."""
        q = (self.default if base is None else base).copy()
        for side, values in (("left", left), ("right", right)):
            mirror = side == "right" and right is None
            values = left if values is None else values
            for joint, value in values.items():
                if joint in WAIST_JOINTS:
                    q[self.index[f"{joint}_joint"]] = value
                    continue
                q[self.index[f"{side}_{joint}_joint"]] = -value if (mirror and joint in MIRRORED) else value
        return self._clip(q)

    def _clip(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lo, self.hi)

    def _build_poses(self, spec: RobotSpec) -> None:
        self.index = {name: i for i, name in enumerate(spec.joint_names)}
        self.default = np.asarray(spec.default_pose, dtype=float)
        self.lo = np.asarray(spec.joint_lower, dtype=float) + LIMIT_MARGIN
        self.hi = np.asarray(spec.joint_upper, dtype=float) - LIMIT_MARGIN
        self.lie = self._pose(LIE_POSE)
        self.push_a = self._pose(PUSH_A_POSE)
        self.push_b = self._pose(PUSH_B_POSE)
        self.tuck = self._pose(TUCK_POSE)
        self.sit = self._pose(SIT_POSE)
        self.squat = self._pose(SQUAT_POSE)
        self.stand = self._clip(self.default.copy())

    def roll_pose(self, direction: int) -> np.ndarray:
        """Roll towards ``direction`` (+1: the left side goes down)."""
        down, up = (ROLL_POSE_DOWN, ROLL_POSE_UP)
        if direction > 0:
            return self._pose({**LIE_POSE, **down}, self._mirror({**LIE_POSE, **up}))
        return self._pose({**LIE_POSE, **up}, self._mirror({**LIE_POSE, **down}))

    @staticmethod
    def _mirror(values: dict) -> dict:
        return {k: (-v if k in MIRRORED else v) for k, v in values.items()}

    # ------------------------------------------------------------- interface
    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        self.num_envs = num_envs
        self._build_poses(spec)
        n = num_envs
        self.phase = np.full(n, LIE, dtype=int)
        self.steps = np.zeros(n, dtype=int)
        self.direction = np.ones(n, dtype=int)
        self.goal = np.tile(self.lie, (n, 1))
        self.ramp = np.tile(RAMP_STEPS, (n, 1))  # per environment, so that a search can vary them
        self.start = None
        self.target = None

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        g = np.asarray(obs["projected_gravity"], dtype=float)
        if self.target is None:
            self.target = self._clip(np.asarray(obs["joint_pos"], dtype=float).copy())
            self.start = self.target.copy()
        for i in range(self.num_envs):
            self._transition(i, g[i])
        self.steps += 1
        w = _smoothstep(self.steps / self.ramp[np.arange(self.num_envs), self.phase])[:, None]
        self.target = self._clip(self.start + w * (self.goal - self.start))
        return self.target.copy()

    def _enter(self, i: int, phase: int, goal: np.ndarray) -> None:
        self.phase[i] = phase
        self.steps[i] = 0
        self.start[i] = self.target[i]
        self.goal[i] = self._goal(i, phase, goal)

    def _goal(self, i: int, phase: int, goal: np.ndarray) -> np.ndarray:
        return goal

    def _transition(self, i: int, g: np.ndarray) -> None:
        phase, steps = self.phase[i], self.steps[i]
        done = steps >= self.ramp[i, phase] + HOLD_STEPS[phase]
        if not done:
            return
        if phase == LIE:
            if g[0] > 0.6:
                self._enter(i, PUSH_A, self.push_a)
            else:
                self.direction[i] = 1 if g[1] >= 0 else -1
                self._enter(i, ROLL, self.roll_pose(self.direction[i]))
        elif phase == ROLL:
            if g[0] > 0.6:
                self._enter(i, PUSH_A, self.push_a)
            elif steps > 60:
                self._enter(i, LIE, self.lie)
        elif phase == PUSH_A:
            self._enter(i, PUSH_B, self.push_b)
        elif phase == PUSH_B:
            self._enter(i, TUCK, self.tuck)
        elif phase == TUCK:
            self._enter(i, SIT, self.sit)
        elif phase == SIT:
            self._enter(i, SQUAT, self.squat)
        elif phase == SQUAT:
            self._enter(i, RISE, self.stand)
        elif phase == RISE:
            self._enter(i, HOLD, self.stand)
