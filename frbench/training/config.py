"""`TrainEnvConfig`: the training environment's settings, frozen, validated, saved in every run.

A config is built once (by `frbench train`, a preset, a test) and never
changed: ``dataclasses.replace`` makes a new one, validated again. It checks
itself in ``__post_init__`` (ValueError naming the field and what was
expected), so a bad value fails before a simulator starts, whoever builds it.
The reward table defaults to the robot kind's (`reward_tables.reward_table`): a G1
trains on the humanoid table without anyone asking for it.

``to_dict``/``from_dict`` are its JSON form in a run's ``config.json`` and in
every policy checkpoint; ``from_dict`` reads the files of older runs too
(every field kept its name; fields added since take their defaults, and the
reward table is the one the run recorded).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

from frbench.backends import training_backend_names
from frbench.policies.scripted_humanoid import DEFAULT_GATE_PHASES, gate_phase_ids
from frbench.robots import get_robot
from frbench.robots.morphology import morphology_ranges
from frbench.terrains import FAMILIES
from frbench.training.bodies import BODIES
from frbench.training.dagger import ImitationSchedule
from frbench.training.reward_tables import reward_table
from frbench.training.teacher import ENV_TEACHERS

#: The rows the imitation term can weigh (``TrainEnvConfig.imitate_rows``).
IMITATE_ROWS = ("all", "teacher")
from frbench.training.rewards import RewardConfig

#: Gain ranges of frbench's training (the paper: Kp [20, 80], Kd [0.6, 2.0]); see docs/training.md.
TRAINING_GAIN_RANGES = MappingProxyType({"kp": (50.0, 80.0), "kd": (1.0, 2.0)})
GAIN_RANGE_REASON = (
    "robots sampled from the paper's morphology table weigh 21-35 kg (6 of 6 in a check); with Kp 20 every one "
    "sinks 40-65 % below its standing height and touches the ground with its body, with Kp 80 every one stands, "
    "so Kp < 50 makes most episodes impossible to win"
)
#: The largest assist force, as a fraction of the robot's weight.
MAX_ASSIST_FRACTION = 2.0


def _frozen_ranges(ranges) -> MappingProxyType:
    return MappingProxyType({str(k): tuple(float(x) for x in v) for k, v in dict(ranges).items()})


@dataclass(frozen=True)
class TrainEnvConfig:
    """Training environment settings (saved in every checkpoint); see the module docstring."""

    num_envs: int = 256
    #: The simulator (`frbench.backends.training_backend_names`): ``mujoco``, ``pybullet``, ``mujoco-warp`` (on the
    #: device `frbench train --device` names) or ``mujoco+pybullet`` (half the batch in each simulator).
    backend: str = "mujoco"
    robot: str | None = None  # None: randomised morphologies
    num_morphologies: int = 32
    #: Episode length and the fallen start's settle on soft gains, in control steps (0.02 s).
    episode_steps: int = 350
    settle_steps: int = 25
    #: Settled fallen starts recorded per (terrain tile, robot variant) before training, every episode beginning
    #: at one of its cell's (`start_bank.StartBank`: no settle per episode, what a GPU run wants); 0: every
    #: episode's start is drawn and settled afresh.
    start_bank: int = 0
    action_scale: float = 1.0  # the paper's q* = q̊ + a
    families: tuple[str, ...] = FAMILIES
    curriculum: bool = True
    start_level: int = 1
    randomize: bool = True
    gain_ranges: Mapping[str, tuple[float, float]] = field(default_factory=lambda: TRAINING_GAIN_RANGES)
    #: Rows of the paper's morphology table replaced for this run, field → (low, high) [kg or m]
    #: (``morphology.morphology_ranges``); empty: the paper's table.
    morphology_ranges: Mapping[str, tuple[float, float]] = field(default_factory=lambda: MappingProxyType({}))
    #: The body distribution of the sampled robots (`frbench.training.bodies.BODIES`): ``"paper"``, the paper's
    #: morphology table (about 21-35 kg) in Go2's joint convention, or ``"wide"``, each paper-table draw resized
    #: to a total mass log-uniform in 2-60 kg (lengths ·s, masses ·s³, torque limits and Kp ·s⁴, Kd ·s^4.5, motor
    #: friction ·s⁴, payload ·s³, CoM shift ·s), its knees all backward, all forward, or forward on one pair, its
    #: file turning thigh and calf about −y (Mini Cheetah) in half of them and folding its legs at joint zero
    #: (Spirit 40) in half, normalised by the learner's canonical joint frame (docs/training.md, "Wider bodies").
    #: A resumed run may switch it (``frbench train --resume RUN --set bodies=wide``: a new stage).
    bodies: str = "paper"
    #: The reward table; None: the robot kind's (`reward_tables.reward_table`), filled in at construction.
    reward: RewardConfig | None = None
    history: int = 5
    #: Frames of the ``long_history`` group (RMA's adaptation module reads 50); 0: no such group.
    long_history: int = 0
    seed: int = 0
    #: The generator of the sampled robots (morphologies, their physics, their assignment to environments);
    #: None: drawn from ``seed``'s generator like everything else. Set, it separates "which robots" from PPO's
    #: and the starts' randomness (e.g. one population trained with several PPO seeds).
    population_seed: int | None = None
    #: Starting states along a getting-up motion (`start_sources.DemoStarts`): the fraction of episodes that
    #: start from a recorded ``scripted`` state, falling linearly to 0 at ``demo_start_until`` env steps (0: off).
    demo_start_fraction: float = 0.0
    demo_start_until: float = 0.0
    #: Re-record the bank every this many episodes, from ``demo_steps`` control steps, one snapshot per ``demo_stride``.
    demo_refresh_episodes: int = 10
    demo_steps: int = 300
    demo_stride: int = 5
    #: A vertical assist force on the base (`assist.AssistForce`), as a fraction of the robot's weight, falling
    #: linearly to 0 at ``assist_until`` env steps (0: off); HoST's way of making getting up cheap to learn.
    #: Never in evaluation.
    assist_force: float = 0.0
    assist_until: float = 0.0
    #: A policy name (e.g. ``"scripted-humanoid"``) whose joint targets the learned action is added to
    #: (`residual.ResidualController`): q* = base(o) + action_scale·a; None: q* = q̊ + action_scale·a.
    base_controller: str | None = None
    #: The base controller's tunable parameters at the start of the run (name → value; empty: it has none).
    base_controller_parameters: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    #: Gated residual: q* = base(o) + gate·action_scale·a with the base controller's ``residual_gate()`` (N,)
    #: (``keyframe-humanoid``: 1 in its rise, 0 before), so exploration cannot break the motion before the rise.
    residual_gate: bool = False
    #: The base controller's phases in which the gated residual acts (names, `scripted_humanoid.PHASE_NAMES`);
    #: the default is the rise (crouch, rise, hold); the sit-up's ``tuck``, ``prop``, ``rock`` may be added.
    gate_phases: tuple[str, ...] = DEFAULT_GATE_PHASES
    #: With a gated residual: this fraction of episodes starts where the base controller opened its gate in a
    #: recorded run from fresh fallen starts (`start_sources.RiseStarts`), the controller in that phase (0: off).
    #: Logged success rates count fresh fallen starts only.
    rise_start_fraction: float = 0.0
    #: The policy decides every ``action_hold`` control steps and its action is held in between
    #: (`action_hold.HeldAction`; 1: every step). Rewards are summed over the held steps; ``episode_steps``
    #: stays in control steps.
    action_hold: int = 1
    #: A teacher that labels every control step inside the env (`frbench.training.teacher`, ``"scripted"``), whose
    #: label, imitation weight and PPO weight the ``teacher`` observation group carries; None: no teacher.
    teacher: str | None = None
    #: The teacher's timetable (`frbench.training.dagger.ImitationSchedule`), in env steps: DAgger for
    #: ``dagger_steps`` in ``dagger_rounds`` rounds (round 0 the teacher acts in every episode, later rounds in a
    #: fraction ``dagger_beta``), then the imitation weight falls linearly from ``imitation_weight`` to 0 at
    #: ``imitation_until``.
    dagger_steps: float = 0.0
    dagger_rounds: int = 1
    dagger_beta: float = 0.0
    imitation_weight: float = 1.0
    imitation_until: float = 0.0
    #: Standard deviation [action units] of the Gaussian noise added to the teacher's label where it acts, drawn
    #: afresh every control step (DART; `frbench.training.teacher`); 0: the teacher acts exactly.
    dagger_noise: float = 0.0
    #: After DAgger, until ``imitation_until``, the fraction of episodes the teacher goes on acting in (its rows
    #: imitation rows, not PPO rows; `frbench.training.dagger.ImitationSchedule`).
    kickstart_beta: float = 0.0
    #: The rows the imitation term weighs: ``"all"`` or only those the ``"teacher"`` acted in.
    imitate_rows: str = "all"
    #: The weight the imitation term's decay stops at (0: it ends at ``imitation_until``); above 0 the teacher
    #: also goes on acting in ``kickstart_beta`` of the episodes to the end (`ImitationSchedule.floor`).
    imitation_floor: float = 0.0

    def __post_init__(self) -> None:
        def set_(name: str, value) -> None:
            object.__setattr__(self, name, value)

        set_("families", tuple(self.families))
        set_("gate_phases", tuple(self.gate_phases))
        set_("gain_ranges", _frozen_ranges(self.gain_ranges))
        set_("morphology_ranges", _frozen_ranges(self.morphology_ranges))
        set_("base_controller_parameters",
             MappingProxyType({str(k): v for k, v in dict(self.base_controller_parameters).items()}))
        self._validate()
        if self.reward is None:
            set_("reward", reward_table(self.robot_kind()))

    def imitation_schedule(self) -> ImitationSchedule:
        """The teacher's timetable (`ImitationSchedule`) from the ``dagger_*`` and ``imitation_*`` fields."""
        return ImitationSchedule(self.dagger_steps, self.dagger_rounds, self.dagger_beta, self.imitation_weight,
                                 self.imitation_until, self.seed, self.kickstart_beta, self.imitate_rows == "teacher",
                                 self.imitation_floor)

    def robot_kind(self) -> str:
        """``"quadruped"`` (randomised morphologies, or a named quadruped) or ``"humanoid"``."""
        if not self.robot:
            return "quadruped"
        return get_robot(self.robot).kind

    def _validate(self) -> None:
        def need(ok: bool, name: str, expected: str) -> None:
            if not ok:
                raise ValueError(f"{name} {getattr(self, name)!r}: expected {expected}")

        need(self.num_envs >= 1, "num_envs", "at least 1 environment")
        need(self.backend in training_backend_names(), "backend", f"one of {', '.join(training_backend_names())}")
        need(self.num_morphologies >= 1, "num_morphologies", "at least 1 robot")
        need(self.bodies in BODIES, "bodies", f"one of {', '.join(BODIES)}")
        if self.bodies != "paper":
            need(not self.robot, "bodies", "'paper' with a named robot (the bodies are those sampled)")
            for name in ("demo_start_fraction", "rise_start_fraction"):  # one controller for the whole batch
                need(getattr(self, name) == 0.0, name, f"0 with bodies {self.bodies!r} (their joint conventions differ)")
            need(not self.base_controller, "base_controller", f"none with bodies {self.bodies!r}")
        need(self.episode_steps >= 1, "episode_steps", "at least 1 control step")
        need(self.settle_steps >= 0, "settle_steps", "at least 0 control steps")
        need(self.start_bank >= 0, "start_bank", "at least 0 settled starts per tile and robot (0: none)")
        need(self.action_scale > 0, "action_scale", "a positive number")
        need(len(self.families) > 0 and all(f in FAMILIES for f in self.families), "families",
             f"terrain families among {', '.join(FAMILIES)}")
        need(1 <= self.start_level <= 10, "start_level", "a level in 1-10")
        need(self.history >= 1, "history", "at least 1 frame")
        need(self.long_history >= 0, "long_history", "at least 0 frames")
        need(0.0 <= self.demo_start_fraction <= 1.0, "demo_start_fraction", "a fraction in [0, 1]")
        need(self.demo_refresh_episodes >= 1, "demo_refresh_episodes", "at least 1 episode")
        need(1 <= self.demo_stride <= max(1, self.demo_steps), "demo_stride", "1 to demo_steps control steps")
        need(0.0 <= self.assist_force <= MAX_ASSIST_FRACTION, "assist_force",
             f"a fraction of the weight in [0, {MAX_ASSIST_FRACTION:g}]")
        need(self.action_hold >= 1, "action_hold", "at least 1 control step per decision")
        need(0.0 <= self.rise_start_fraction <= 1.0, "rise_start_fraction", "a fraction in [0, 1]")
        need(not self.residual_gate or bool(self.base_controller), "residual_gate",
             "a base_controller (the gate is the base controller's)")
        need(self.rise_start_fraction == 0.0 or self.residual_gate, "rise_start_fraction",
             "residual_gate (the rise starts where the gate opens)")
        need(self.gate_phases == DEFAULT_GATE_PHASES or self.residual_gate, "gate_phases",
             "residual_gate (the phases name where the gate opens)")
        if self.residual_gate:
            try:
                gate_phase_ids(self.gate_phases)
            except ValueError as exc:
                raise ValueError(f"gate_phases {self.gate_phases!r}: {exc}") from None
        need(self.teacher is None or self.teacher in ENV_TEACHERS, "teacher", f"one of {', '.join(ENV_TEACHERS)} or none")
        if self.teacher is not None:
            need(self.action_hold == 1, "action_hold", "1 with a teacher (it labels every control step)")
            need(not self.base_controller, "base_controller", "none with a teacher (it labels the plain policy)")
            need(self.robot_kind() == "quadruped", "teacher", "a quadruped batch (scripted drives quadrupeds)")
        need(self.imitate_rows in IMITATE_ROWS, "imitate_rows", f"one of {', '.join(IMITATE_ROWS)}")
        need(self.dagger_noise >= 0, "dagger_noise", "a standard deviation >= 0 [action units]")
        self.imitation_schedule()  # ValueError naming a bad dagger_* or imitation_* value
        for name in ("gain_ranges", "morphology_ranges"):
            for key, (low, high) in getattr(self, name).items():
                if not low <= high:
                    raise ValueError(f"{name}[{key!r}] ({low}, {high}): expected low <= high")
        if self.morphology_ranges:
            morphology_ranges(dict(self.morphology_ranges))  # ValueError naming an unknown field or a bad range

    # ------------------------------------------------------------------ JSON form
    def to_dict(self) -> dict:
        """The JSON form (lists for tuples, plain dicts for mappings, the reward table's fields)."""
        out = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, tuple):
                value = list(value)
            elif isinstance(value, Mapping):
                value = {k: (list(v) if isinstance(v, tuple) else v) for k, v in value.items()}
            out[f.name] = value
        reward = self.reward
        out["reward"] = {"weights": dict(reward.weights), "epsilon": reward.epsilon,
                         "posture_sigma2": reward.posture_sigma2, "scale_by_dt": reward.scale_by_dt,
                         "overrides_reason": dict(reward.overrides_reason)}
        return out

    @classmethod
    def from_dict(cls, data: Mapping) -> "TrainEnvConfig":
        """A config from its JSON form (`to_dict`), including those of older runs (see the module docstring)."""
        data = dict(data)
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"training env config: unknown fields {unknown}")
        if data.get("reward") is not None:
            data["reward"] = RewardConfig(**data["reward"])
        return cls(**data)


#: Fields that ``--set`` cannot write: the reward table and the mappings have flags or presets of their own.
UNSETTABLE_FIELDS = ("reward", "gain_ranges", "morphology_ranges", "base_controller_parameters")
#: Fields that ``--set`` may change when a run resumes (``frbench train --resume RUN --set FIELD=VALUE``: a new
#: stage, recorded in the run's config.json): the robots are redrawn, the policy goes on.
STAGE_FIELDS = ("bodies", "imitation_floor")


def field_types() -> dict[str, object]:
    """Config field → its type, resolved from the annotations (``typing.get_type_hints``), not their text."""
    return typing.get_type_hints(TrainEnvConfig)


def parse_field(name: str, text: str):
    """The value of config field ``name`` written as ``text`` on a command line (``--set NAME=TEXT``), parsed by the
    field's type: ``int``, ``float``, ``bool`` (``true``/``false``/``1``/``0``), ``str``, ``X | None`` (``none`` or
    empty: None), ``tuple[str, ...]`` (comma-separated names). A ValueError names the field and what was expected."""
    hints = field_types()
    settable = sorted(set(hints) - set(UNSETTABLE_FIELDS))
    if name not in settable:
        raise ValueError(f"--set {name}: not a settable field; expected one of {', '.join(settable)}")
    kind, text = hints[name], text.strip()
    args = typing.get_args(kind)
    if typing.get_origin(kind) in (typing.Union, types.UnionType) and type(None) in args:
        if text.lower() in ("none", ""):
            return None
        kind = next(a for a in args if a is not type(None))
    if typing.get_origin(kind) is tuple:
        return tuple(part.strip() for part in text.split(",") if part.strip())
    if kind is bool:
        if text.lower() not in ("true", "false", "1", "0"):
            raise ValueError(f"--set {name}={text}: expected true or false")
        return text.lower() in ("true", "1")
    if kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            raise ValueError(f"--set {name}={text}: expected a number ({kind.__name__})") from None
    return text
