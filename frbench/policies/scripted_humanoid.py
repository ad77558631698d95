"""``scripted-humanoid``: a model-based key-frame getting-up controller for the Unitree G1 (no training).

It drives other humanoids through their G1 joint frame (`frbench.robots.humanoid_frame`): the state machine and
its key poses stay in G1 joint angles (``target``, `g1_act`), measured angles come in and targets go out through
the frame (`act`); the G1's own frame is the identity.

A per-environment state machine driven by proprioception only: the projected
gravity g (body frame; (0, 0, -1) upright, (+1, 0, 0) face down, (-1, 0, 0)
face up, g_y > 0 lying on the left side), the measured joint angles (only to
start from where the joints are) and the control steps spent in the current
phase. Every key pose is built from named joints of the spec (``knee``,
``waist_yaw`` ...; roll and yaw angles mirrored for the right side) and clipped
`LIMIT_MARGIN` inside the joint limits. Targets move from the previous
targets to each phase's pose by smoothstep interpolation over the phase's
ramp. Sign conventions, checked on the G1's kinematic tree: negative hip
pitch swings the thigh forward, positive knee flexes, negative ankle pitch
lifts the toes, negative shoulder pitch raises the arm forward, elbow 0 is a
right angle (about +1.5 is a straight arm), positive waist pitch bends the
torso forward, positive hip/shoulder roll moves the left limb outwards.
Phases:

``LIE``     legs straight, arms along the body; then choose from g: face
            down -> ``PUSH_A``; face up -> ``TUCK`` while sit-up tries
            (``situp_tries``, 0 here) are left; face up or on a side ->
            ``ROLL``, towards the side that is already lower; upright ->
            ``CROUCH``.
``TUCK``,   the sit-up from the back (`SITUP_PHASES`, each after its ramp):
``PROP``,   the legs tuck with the feet near the buttocks while the arms press
``ROCK``    down behind the body; the arms straighten, propping the torso up;
            the arms swing forward and the hips fold, rocking the body over
            the feet -> ``CROUCH``. Tipping onto the belly or a side -> ``LIE``.
``ROLL``    face up / side -> face down, in two stages. Back -> side: the chest
            twists towards the lower side (waist yaw), the upper arm reaches
            across the chest, the upper leg flexes and crosses over, the lower
            arm goes overhead out of the way. Once on the side (d g_y >
            `SIDE_GY`), side -> belly: the upper leg and arm reach forward so
            their weight tips the body over its front, the lower leg extends
            back. Face down (g_x > `ROLLED_GX`) -> ``PUSH_A``; timeout ->
            ``LIE`` and roll the other way.
``PUSH_A``  hands beside the chest (upper arms back, elbows bent).
``PUSH_B``  push-up: the arms straighten under the shoulders, lifting the chest.
``LIFT``    from the push-up the hips start to flex with straight knees, legs
            apart, the arms reaching overhead in line with the torso.
``PIKE``    downward dog: hips fully flexed, knees straight, on the toes, hands
            and feet on the ground, pelvis high (about 0.6 m in MuJoCo).
``SQUAT``   the knees bend and the ankles dorsiflex (feet flat) with the hips
            still flexed, so the pelvis should come down and back over the feet
            into a deep squat, hands still down.
``CROUCH``  the torso rises (hips extend) with the knees still bent, keeping
            the centre of mass over the feet; arms forward as counterweight.
``RISE``    interpolate to the default standing pose.
``HOLD``    hold the default pose.

Falling over again (face up while pushing, piking or squatting, or tilted
more than `FALLEN_GZ` while rising or holding) restarts from ``LIE``.

Status (flat ground): it does not stand up. ``frbench evaluate --policy
scripted-humanoid --robots g1 --terrains flat --levels 1 --seeds 0,1
--episodes 8``: 0/32 episodes, 0/16 in MuJoCo and 0/16 in PyBullet (per start
kind, in each backend: prone 0/2, supine 0/5, left side 0/3, right side 0/4,
random 0/2). Highest pelvis per episode 0.15-0.51 m in both backends; the one
exception, seed 0 episode 6 (supine), is above 0.70 m at step ~20 only while
still falling from its drawn start (0.72 m MuJoCo, 0.75 m PyBullet) and
does not count. Where it fails (all measured, flat ground):

* Prone starts of that grid never reach the pike: seed 0 episode 4 is rolled
  onto its left side within the first 10 steps by the ``LIE`` interpolation
  from the random start angles (and on onto its back in MuJoCo); seed 1 episode 0
  tips onto its left side during ``PUSH_B`` (MuJoCo, pelvis at most 0.25 m)
  or ``LIFT`` (PyBullet, 0.33 m). With ``LIE`` lengthened to 20 + 20 steps
  the same MuJoCo start reaches ``PIKE`` (pelvis 0.41 m) instead; the earlier
  version of this note saw the pike from 2 of 5 other prone starts in MuJoCo.
* Hip lock (MuJoCo; robot spawned standing flat-footed in a squat, knees 2.6,
  full gains): with the hips flexed to about -2.47 rad both hip-pitch motors
  saturate at their 88 N·m limit and the hips do not extend at all when asked
  for -1.5 rad; from -2.0 rad they extend. ``PIKE`` (-2.48) and ``SQUAT``
  (-2.45) ask for that region (see ``test_hip_pitch_lock_in_a_deep_squat``).
* A deep squat (hips -2.2 to -2.4, knees 2.7, ankles -0.8, waist pitch 0.45,
  arms forward) holds statically in MuJoCo, pelvis pitched about 0.55 rad.
  Rising from it through key poses chosen with a static centre-of-mass model
  (CoM 3-7 cm ahead of the ankles, feet flat), open loop or with the foot tilt
  (measured pelvis pitch minus -(hip + knee + ankle pitch)) fed back onto hip
  pitch, tipped forward onto the hands (pelvis 0.5-0.6 m) or back onto the
  buttocks; none reached 0.7 m. A fast rise does pass 0.7 m but does not
  stay up: interpolating from that squat (hips -2.3) to a slightly flexed
  standing pose (hips -0.5, knees 0.4, arms forward) in 12 control steps
  lifts the pelvis to 0.77 m, then the robot falls on its back (0.09 m), even
  with a crouched catch pose commanded right after; in 16 steps it peaks at
  0.62-0.69 m and tips forward (pelvis 0.5 m). So the missing pieces are a balance
  controller for the squat-to-stand rise and a reliable way from the push-up
  into a squat with the hips above about -2.2 rad.
* Rolls from the back reach the side but mostly stall there.
"""

from __future__ import annotations

import numpy as np

from frbench.robots.humanoid_frame import G1_JOINTS, HumanoidFrameError, humanoid_frame, reference_spec
from frbench.robots.humanoid_frame import WAIST_ROLES as WAIST_JOINTS
from frbench.robots.spec import RobotSpec

LIE, ROLL, PUSH_A, PUSH_B, LIFT, PIKE, SQUAT, CROUCH, RISE, HOLD, TUCK, PROP, ROCK = range(13)
PHASE_NAMES = ("lie", "roll", "push_a", "push_b", "lift", "pike", "squat", "crouch", "rise", "hold", "tuck", "prop",
               "rock")
#: The sit-up from the back, in order (then ``CROUCH``); used only by controllers with ``situp_tries`` > 0.
SITUP_PHASES = (TUCK, PROP, ROCK)
#: Phases in which a gated residual policy may change the targets (`residual_gate`): the rise onto the feet.
RESIDUAL_PHASES = (CROUCH, RISE, HOLD)
#: The same by name, the training's default gate (`frbench train --gate-phases`).
DEFAULT_GATE_PHASES = tuple(PHASE_NAMES[p] for p in RESIDUAL_PHASES)


def gate_phase_ids(names) -> tuple[int, ...]:
    """Phase ids of the phase ``names`` (e.g. ``("prop", "rock", "crouch")``); ValueError naming an unknown one."""
    unknown = [n for n in names if n not in PHASE_NAMES]
    if unknown or not len(names):
        raise ValueError(f"gate phases {list(names)}: expected one or more of {', '.join(PHASE_NAMES)}")
    return tuple(PHASE_NAMES.index(n) for n in names)

#: Interpolation time [control steps of 0.02 s] from the previous targets to each phase's pose.
RAMP_STEPS = np.array([10, 30, 10, 20, 35, 40, 45, 30, 40, 1, 20, 25, 25])
#: Steps [control steps] each phase holds its reached pose before the next phase starts.
HOLD_STEPS = np.array([0, 0, 0, 5, 0, 0, 5, 5, 0, 0, 0, 0, 0])
#: Steps [control steps] a roll may last before it is retried the other way.
ROLL_TIMEOUT = 60

#: Projected-gravity thresholds (unitless components of the unit gravity vector in the body frame).
PRONE_GX = 0.6  # g_x above this: face down
ROLLED_GX = 0.45  # g_x above this while rolling: (nearly) face down, start pushing up
SIDE_GY = 0.8  # d * g_y above this while rolling in direction d: on the side, roll on onto the belly
SUPINE_GX = -0.6  # g_x below this: face up
UPRIGHT_GZ = -0.7  # g_z below this at the start: (nearly) on the feet already
FALLEN_GZ = -0.5  # g_z above this while rising or holding: fallen over again

#: Margin [rad] kept from the joint limits.
LIMIT_MARGIN = 0.05

#: Joints whose sign is mirrored between the left and the right side (roll and yaw axes).
MIRRORED = ("hip_roll", "hip_yaw", "ankle_roll", "shoulder_roll", "shoulder_yaw", "wrist_roll", "wrist_yaw")

#: Key poses [rad]: joint name without side -> angle of the left joint (the right one mirrors roll and
#: yaw); joints not named keep their default angle.
LIE_POSE = {
    "hip_pitch": 0.0, "knee": 0.2, "ankle_pitch": 0.0, "shoulder_pitch": 0.0, "shoulder_roll": 0.2,
    "elbow": 1.5,
}
PUSH_A_POSE = {**LIE_POSE, "shoulder_pitch": 0.3, "elbow": 0.0}
PUSH_B_POSE = {**LIE_POSE, "shoulder_pitch": -1.4, "elbow": 1.5}
LIFT_POSE = {
    "hip_pitch": -1.17, "hip_roll": 0.46, "knee": 0.1, "ankle_pitch": -0.08, "waist_pitch": 0.21,
    "shoulder_pitch": -2.66, "shoulder_roll": 0.2, "elbow": 1.57,
}
PIKE_POSE = {
    "hip_pitch": -2.48, "hip_roll": 0.2, "knee": 0.0, "ankle_pitch": 0.47, "waist_pitch": 0.47,
    "shoulder_pitch": -2.39, "shoulder_roll": 0.2, "elbow": 1.56,
}
SQUAT_POSE = {
    "hip_pitch": -2.45, "hip_roll": 0.25, "knee": 2.0, "ankle_pitch": -0.8, "waist_pitch": 0.3,
    "shoulder_pitch": -2.39, "shoulder_roll": 0.2, "elbow": 1.5,
}
CROUCH_POSE = {
    "hip_pitch": -1.8, "hip_roll": 0.1, "knee": 2.0, "ankle_pitch": -0.8, "waist_pitch": 0.3,
    "shoulder_pitch": -1.0, "shoulder_roll": 0.2, "elbow": 1.5,
}
#: Sit-up from the back (`SITUP_PHASES`): the legs tuck (feet flat near the buttocks) while the arms press
#: down behind the body ...
TUCK_POSE = {
    "hip_pitch": -1.5, "hip_roll": 0.2, "knee": 2.4, "ankle_pitch": -0.4, "waist_pitch": 0.3,
    "shoulder_pitch": 0.8, "shoulder_roll": 0.3, "elbow": 0.3,
}
#: ... the arms straighten, propping the torso up on the hands behind it, the hips flex further ...
PROP_POSE = {
    "hip_pitch": -1.8, "hip_roll": 0.2, "knee": 2.5, "ankle_pitch": -0.7, "waist_pitch": 0.5,
    "shoulder_pitch": 1.5, "shoulder_roll": 0.3, "elbow": 1.5,
}
#: ... and the arms swing forward while the hips fold fully, rocking the body forward over the feet into a squat.
ROCK_POSE = {
    "hip_pitch": -2.3, "hip_roll": 0.2, "knee": 2.6, "ankle_pitch": -0.8, "waist_pitch": 0.5,
    "shoulder_pitch": -1.5, "shoulder_roll": 0.2, "elbow": 1.5,
}
#: Roll towards one side: the arm of the side going down goes overhead, out of the way ...
ROLL_DOWN_SIDE = {"shoulder_pitch": -2.6, "shoulder_roll": 0.3, "elbow": 1.5}
#: ... the leg of the side going up flexes and crosses over (hip adducted), its arm reaches across the chest ...
ROLL_UP_SIDE = {
    "hip_pitch": -1.2, "hip_roll": -0.4, "knee": 1.0, "shoulder_pitch": -1.5, "shoulder_roll": -1.0,
    "elbow": 0.5,
}
#: ... and the chest twists towards the lower side by this waist yaw [rad].
ROLL_WAIST_YAW = 1.2
#: From the side onto the belly: the upper leg and arm reach forward (their weight tips the body over
#: its front), the lower leg extends back.
ROLL_B_UP_SIDE = {"hip_pitch": -1.6, "knee": 1.2, "shoulder_pitch": -1.6, "shoulder_roll": 0.0, "elbow": 1.5}
ROLL_B_DOWN_SIDE = {"hip_pitch": 0.3, "shoulder_pitch": -2.6, "shoulder_roll": 0.3, "elbow": 1.5}


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _mirror(values: dict) -> dict:
    """Left-side angles as the right side's (roll and yaw change sign)."""
    return {k: (-v if k in MIRRORED else v) for k, v in values.items()}


class HumanoidScriptedPolicy:
    """Lie flat, roll onto the belly, push up, pike, squat, rise (see the module docstring)."""

    name = "scripted-humanoid"
    checkpoint = None
    #: Sit-up attempts (`SITUP_PHASES`) an episode makes from the back before it rolls onto the belly instead.
    situp_tries = 0

    def supports(self, spec: RobotSpec) -> bool:
        """Humanoids whose legs map onto the G1's (`frbench.robots.humanoid_frame`: the G1 itself, iCub, Talos)."""
        if spec.kind != "humanoid":
            return False
        try:
            humanoid_frame(spec)
        except HumanoidFrameError:
            return False
        return True

    # ------------------------------------------------------------------ poses
    def _pose(self, left: dict, right: dict | None = None) -> np.ndarray:
        """A pose from named angles: ``left`` for the left side and the waist, ``right`` for the right
        side (default: the mirror image of ``left``); other joints keep their default angle."""
        q = self.default.copy()
        right = _mirror(left) if right is None else right
        for side, values in (("left", left), ("right", right)):
            for joint, value in values.items():
                name = f"{joint}_joint" if joint in WAIST_JOINTS else f"{side}_{joint}_joint"
                q[self.index[name]] = value
        return self._clip(q)

    def _clip(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lo, self.hi)

    def _build_poses(self, spec: RobotSpec) -> None:
        """The key poses in G1 joint angles (`G1_JOINTS` order) for ``spec`` seen through its G1 joint frame:
        its default pose and limits in G1 angles (the G1's own for a joint it lacks)."""
        self.frame = humanoid_frame(spec)
        reference = reference_spec()
        self.robot_default = np.asarray(spec.default_pose, dtype=float)
        self.index = {name: i for i, name in enumerate(G1_JOINTS)}
        self.default = self.frame.to_g1(self.robot_default, np.asarray(reference.default_pose, dtype=float))
        lower, upper = self.frame.g1_limits(spec, reference)
        self.lo = lower + LIMIT_MARGIN
        self.hi = upper - LIMIT_MARGIN
        self.poses = {
            LIE: self._pose(LIE_POSE),
            PUSH_A: self._pose(PUSH_A_POSE),
            PUSH_B: self._pose(PUSH_B_POSE),
            LIFT: self._pose(LIFT_POSE),
            PIKE: self._pose(PIKE_POSE),
            SQUAT: self._pose(SQUAT_POSE),
            CROUCH: self._pose(CROUCH_POSE),
            RISE: self._clip(self.default.copy()),
            HOLD: self._clip(self.default.copy()),
            TUCK: self._pose(TUCK_POSE),
            PROP: self._pose(PROP_POSE),
            ROCK: self._pose(ROCK_POSE),
        }

    def key_poses(self) -> dict[str, np.ndarray]:
        """Every fixed key pose by phase name (after ``reset``), in G1 joint angles (29,) [rad]."""
        return {PHASE_NAMES[phase]: q.copy() for phase, q in self.poses.items()}

    def roll_pose(self, direction: int, stage: int = 0, down_side: dict | None = None, up_side: dict | None = None,
                  waist_yaw: float = ROLL_WAIST_YAW) -> np.ndarray:
        """Pose rolling towards ``direction`` (+1: the left side goes down, g_y grows); stage 0 rolls from the
        back onto the side, stage 1 from the side onto the belly. ``down_side``/``up_side`` replace the stage's
        key angles of the limbs going down/up (default: ``ROLL_DOWN_SIDE``/``ROLL_UP_SIDE`` for stage 0,
        ``ROLL_B_DOWN_SIDE``/``ROLL_B_UP_SIDE`` for stage 1); ``waist_yaw`` [rad] twists the chest."""
        down_side = (ROLL_DOWN_SIDE, ROLL_B_DOWN_SIDE)[stage] if down_side is None else down_side
        up_side = (ROLL_UP_SIDE, ROLL_B_UP_SIDE)[stage] if up_side is None else up_side
        down = {**LIE_POSE, **down_side, "waist_yaw": direction * waist_yaw}
        up = {**LIE_POSE, **up_side, "waist_yaw": direction * waist_yaw}
        if direction > 0:
            return self._pose(down, _mirror(up))
        return self._pose(up, _mirror(down))

    def _roll_goal(self, i: int, stage: int) -> np.ndarray:
        """Environment ``i``'s roll pose for ``stage`` in its chosen direction (subclasses tune it per environment)."""
        return self.roll_pose(self.direction[i], stage)

    # ------------------------------------------------------------- interface
    def reset(self, spec: RobotSpec, num_envs: int) -> None:
        """Start ``num_envs`` episodes; each begins in ``LIE`` from its measured joint angles."""
        self.num_envs = num_envs
        self._build_poses(spec)
        n = num_envs
        self.phase = np.full(n, LIE, dtype=int)
        self.steps = np.zeros(n, dtype=int)  # steps since the phase began
        self.direction = np.zeros(n, dtype=int)  # roll direction, 0 until chosen
        self.roll_stage = np.zeros(n, dtype=int)  # 0: back -> side, 1: side -> belly
        self.situps = np.zeros(n, dtype=int)  # sit-up attempts begun
        self.goal = np.tile(self.poses[LIE], (n, 1))
        self.ramp = np.tile(RAMP_STEPS, (n, 1))  # per environment and phase
        self.start = None  # targets when the phase began, set on the first act()
        self.target = None

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, J) [rad] of the robot (`g1_act` through the robot's G1 joint frame)."""
        return self.frame.to_joints(self.g1_act(obs), self.robot_default)

    def _measured(self, joint_pos: np.ndarray) -> np.ndarray:
        """The robot's measured joint angles (N, J) [rad] in G1 angles (N, 29), clipped to the limits."""
        return self._clip(self.frame.to_g1(np.asarray(joint_pos, dtype=float), self.default))

    def g1_act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets (N, 29) [rad] in G1 joint angles (``target``, a copy)."""
        g = np.asarray(obs["projected_gravity"], dtype=float)
        if self.target is None:  # first step: interpolate from where the joints are
            self.target = self._measured(obs["joint_pos"])
            self.start = self.target.copy()
        for i in range(self.num_envs):
            self._transition(i, g[i])
        self.steps += 1
        ramp = self.ramp[np.arange(self.num_envs), self.phase]
        w = _smoothstep(self.steps / ramp)[:, None]
        self.target = self._clip(self.start + w * (self.goal - self.start))
        return self.target.copy()

    def residual_gate(self, phases: tuple[str, ...] = DEFAULT_GATE_PHASES) -> np.ndarray:
        """(N,) 1.0 where a gated residual policy acts on the targets of the last `act` (the phases named by
        ``phases``, by default `RESIDUAL_PHASES`), else 0.0 (the motion before stays the controller's alone)."""
        return np.isin(self.phase, gate_phase_ids(phases)).astype(float)

    def gate_paths(self) -> np.ndarray:
        """(N,) int: which way each environment came to the crouch (0 here: this controller has one way; see
        `KeyframeHumanoidPolicy`), recorded with the crouch so that `enter_gate` can restore it."""
        return np.zeros(self.num_envs, dtype=int)

    def enter_gate(self, ids: np.ndarray, targets: np.ndarray, joint_pos: np.ndarray,
                   paths: np.ndarray | None = None) -> None:
        """Put environments ``ids`` at the start of the first gated phase (``CROUCH``), ramping from ``targets``
        (len(ids), 29) [rad] (this controller's ``target``, in G1 joint angles, when its gate opened in a recorded
        run) — for episodes that start where the rise begins. ``joint_pos`` (N, J) [rad]: every environment's
        measured angles (the robot's), the other environments' starting targets if no `act` has run yet.
        ``paths`` (len(ids),): their `gate_paths` when recorded (ignored here)."""
        if self.target is None:  # as the first act() would: every environment starts from its measured angles
            self.target = self._measured(joint_pos)
            self.start = self.target.copy()
        for i, target in zip(np.asarray(ids, dtype=int), np.asarray(targets, dtype=float)):
            self.target[i] = self._clip(target)
            self._enter(i, RESIDUAL_PHASES[0])

    # ------------------------------------------------------------ the machine
    def _enter(self, i: int, phase: int, goal: np.ndarray | None = None) -> None:
        self.phase[i] = phase
        self.steps[i] = 0
        self.start[i] = self.target[i]
        self.goal[i] = self.poses[phase] if goal is None else goal

    def _situp_tries(self, i: int) -> int:
        """Sit-up attempts environment ``i`` makes from the back (subclasses set it per environment)."""
        return self.situp_tries

    def _roll(self, i: int, gy: float) -> None:
        """Start a roll: towards the lower side first, the other way on a retry."""
        if self.direction[i] == 0:
            self.direction[i] = 1 if gy >= 0 else -1
        else:
            self.direction[i] = -self.direction[i]
        self.roll_stage[i] = 0
        self._enter(i, ROLL, self._roll_goal(i, 0))

    def _transition(self, i: int, g: np.ndarray) -> None:
        phase, steps = self.phase[i], self.steps[i]
        gx, gy, gz = g
        done = steps >= self.ramp[i, phase] + HOLD_STEPS[phase]
        if phase in (RISE, HOLD) and gz > FALLEN_GZ:  # fell over again
            self._enter(i, LIE)
            return
        if phase in (PUSH_A, PUSH_B, LIFT, PIKE, SQUAT, CROUCH) and gx < SUPINE_GX:  # tipped onto the back
            self._enter(i, LIE)
            return
        if phase in SITUP_PHASES and (gx > PRONE_GX or abs(gy) > SIDE_GY):  # tipped onto the belly or a side
            self._enter(i, LIE)
            return
        if phase == ROLL:
            if gx > ROLLED_GX:
                self._enter(i, PUSH_A)
            elif self.direction[i] * gy > SIDE_GY and not self.roll_stage[i]:
                self.roll_stage[i] = 1
                self._enter(i, ROLL, self._roll_goal(i, 1))
            elif steps > ROLL_TIMEOUT:
                self._enter(i, LIE)
            return
        if not done:
            return
        if phase == LIE:
            if gx > PRONE_GX:
                self._enter(i, PUSH_A)
            elif gz < UPRIGHT_GZ:
                self._enter(i, CROUCH)
            elif gx < SUPINE_GX and self.situps[i] < self._situp_tries(i):
                self.situps[i] += 1
                self._enter(i, TUCK)
            else:
                self._roll(i, gy)
        elif phase == RISE:
            self._enter(i, HOLD)
        elif phase in SITUP_PHASES:
            self._enter(i, (*SITUP_PHASES, CROUCH)[SITUP_PHASES.index(phase) + 1])  # TUCK -> PROP -> ROCK -> CROUCH
        elif phase != HOLD:
            self._enter(i, phase + 1)  # PUSH_A -> PUSH_B -> LIFT -> PIKE -> SQUAT -> CROUCH -> RISE
