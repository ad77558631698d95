"""Named training setups for ``frbench train --preset NAME``: the experiments of docs/results.md by name.

A preset fixes env-config fields (`TrainEnvConfig`), reward changes and the actor's initial exploration;
the command line's own flags and ``--set FIELD=VALUE`` apply on top of it. Budgets are not part of a preset
(``--steps``); a schedule left at 0 (``demo_start_until``, ``assist_until``) becomes half the budget.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Mapping

from frbench.training.rewards import STABILITY_TERMS

#: The ``algorithm.symmetry_cfg`` of a run trained with mirrored samples (rsl-rl's keys; the mirror is
#: `frbench.training.symmetry.mirror_quadruped`, imported by rsl-rl when training starts).
SYMMETRY_AUGMENTATION = MappingProxyType({
    "use_data_augmentation": True, "use_mirror_loss": False, "mirror_loss_coeff": 0.0,
    "data_augmentation_func": "frbench.training.symmetry:mirror_quadruped"})
#: Scale of the motion penalties in the G1 residual runs, relative to the paper's weights.
G1_MOTION_PENALTY_SCALE = 0.01


@dataclass(frozen=True)
class Preset:
    """One named setup.

    Attributes:
        description: one line for ``frbench train --help``.
        env: `TrainEnvConfig` field → value.
        motion_penalties: the joint velocity/acceleration/torque penalties at this scale of the paper's weights
            (None: the robot's table as it is).
        reward_weights: reward term → weight.
        drop_terms: reward terms left out (ablations).
        init_std: the Gaussian actions' initial std (None: the method's).
        symmetry: train with rsl-rl's symmetry augmentation: every PPO mini-batch also holds its left/right
            mirror image (`frbench.training.symmetry`; quadrupeds in frbench's canonical joint order).
        algorithm: rsl-rl ``algorithm`` config key → value, over the method's (e.g. ``entropy_coef``).
    """

    description: str
    env: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))
    motion_penalties: float | None = None
    reward_weights: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    drop_terms: tuple[str, ...] = ()
    init_std: float | None = None
    symmetry: bool = False
    algorithm: Mapping[str, object] = field(default_factory=lambda: MappingProxyType({}))

    def train_overrides(self) -> dict | None:
        """The changes to the method's rsl-rl config (None: none)."""
        overrides: dict = {}
        if self.init_std is not None:
            overrides["actor"] = {"distribution_cfg": {"init_std": self.init_std}}
        algorithm = dict(self.algorithm)
        if self.symmetry:
            algorithm["symmetry_cfg"] = dict(SYMMETRY_AUGMENTATION)
        if algorithm:
            overrides["algorithm"] = algorithm
        return overrides or None


#: The shipped frnet's starts: half the episodes along the scripted getting-up motion.
_DEMO_STARTS = MappingProxyType({"demo_start_fraction": 0.5})
#: ``symmetry-entropy``, which ``symmetry-assist`` extends.
_SYMMETRY_ENTROPY = Preset(
    "symmetry with entropy coefficient 0.01 (rsl-rl's and MuJoCo Playground's getup value) instead of 0.005",
    env=_DEMO_STARTS, symmetry=True, algorithm=MappingProxyType({"entropy_coef": 0.01}))

#: ``symmetry-assist``, which ``symmetry-assist-cover`` extends.
_SYMMETRY_ASSIST = replace(
    _SYMMETRY_ENTROPY,
    description="symmetry-entropy with HoST's assist force on quadrupeds: 0.4 x the weight, falling to 0 at "
                "2.5 M env steps",
    env=MappingProxyType({**_SYMMETRY_ENTROPY.env, "assist_force": 0.4, "assist_until": 2.5e6}))
#: Rows of the paper's morphology table widened towards the benchmark's five quadrupeds, as
#: `frbench.robots.morphology_fit.measure_morphology` measures them (`benchmarks/morphology_coverage.py`;
#: field → (low, high) [kg or m]; Go2's limb sizes are its meshes' bounds). All five have a hip → thigh offset
#: of 0.08-0.11 m (the table: 0.03-0.05). Two rows stop short of Spot-like: thigh width at 0.08 m (0.12 m),
#: because wider thighs on short hip offsets overlap the trunk at the standing pose and change the robot's
#: self-collision exclusions, which the batched MuJoCo variants must share; calf height at 0.045 m (0.074 m),
#: because wider, three in four sampled robots could not stand at the lowest training gains.
COVERING_MORPHOLOGY_RANGES = MappingProxyType({
    "trunk_length": (0.37, 0.90), "trunk_height": (0.11, 0.21), "hip_mass": (0.30, 2.0), "hip_length": (0.05, 0.115),
    "thigh_length": (0.20, 0.35), "thigh_width": (0.02, 0.08), "thigh_height": (0.03, 0.10),
    "calf_width": (0.016, 0.046), "calf_height": (0.013, 0.045)})

#: The mass rows of the paper's morphology table narrowed to the benchmark's quadrupeds ([kg]). With the paper's
#: rows the robots that can stand at the lowest training gains weigh 12-32 kg (median 22 kg; 90 of 122 draws
#: rejected for seed 0), all with Go2's effort limits, while Go1, Lite3-like, Go2 and Aliengo weigh 12-21 kg.
#: With these rows the draws weigh 10-23 kg (200 draws).
LIGHT_MORPHOLOGY_RANGES = MappingProxyType({"trunk_mass": (4.0, 14.0), "thigh_mass": (0.6, 1.6), "calf_mass": (0.1, 0.3)})
#: ``symmetry-assist-steady``, which ``symmetry-assist-steady-light`` extends.
_SYMMETRY_ASSIST_STEADY = replace(
    _SYMMETRY_ASSIST,
    description="symmetry-assist at the old entropy coefficient 0.005: the assist force without the entropy "
                "change, under which the mean action chatters on Go2 (docs/training.md)",
    algorithm=MappingProxyType({"entropy_coef": 0.005}))

#: ``kickstart-scripted``'s timetable (`frbench.training.dagger.ImitationSchedule`, env steps): 2 M env steps of
#: behaviour cloning from ``scripted`` acting with Gaussian noise of 0.2 rad (DART: without it the actor learns to
#: copy its previous action), then PPO with an imitation term whose weight falls from 1 to 0 at 12 M env steps,
#: weighing only the episodes the teacher goes on acting in (a quarter of them, with the noise), where its label
#: is its own next action (docs/training.md, "Why the first recipe stalled"; the first recipe was 3 DAgger rounds
#: with beta 0.25, no noise, the imitation term on every row).
KICKSTART_SCRIPTED = MappingProxyType({
    "teacher": "scripted", "dagger_steps": 2e6, "dagger_rounds": 1, "dagger_beta": 0.0, "imitation_weight": 1.0,
    "imitation_until": 12e6, "dagger_noise": 0.2, "kickstart_beta": 0.25, "imitate_rows": "teacher"})

#: ``kickstart-scripted``, which ``kickstart-scripted-wide`` extends.
_KICKSTART_SCRIPTED = Preset(
    "DAgger from the scripted controller into FR-Net's actor, then PPO with an imitation term toward scripted's "
    "action that decays to 0 (kickstarting; presets.KICKSTART_SCRIPTED, docs/training.md)",
    env=KICKSTART_SCRIPTED, init_std=0.2,
    algorithm=MappingProxyType({"class_name": "frbench.training.imitation:KickstartPPO"}))

PRESETS: Mapping[str, Preset] = MappingProxyType({
    "paper": Preset("random morphologies on all terrains, the paper's setup (the defaults)"),
    "demo-starts": Preset(
        "paper setup, half the episodes starting along the scripted getting-up motion, annealed to 0 "
        "(the shipped frnet and the 3.07 M budget runs)",
        env=_DEMO_STARTS),
    "symmetry": Preset(
        "demo-starts with rsl-rl's symmetry augmentation: each PPO mini-batch also holds its left/right mirror",
        env=_DEMO_STARTS, symmetry=True),
    "symmetry-entropy": _SYMMETRY_ENTROPY,
    "symmetry-assist": _SYMMETRY_ASSIST,
    "symmetry-assist-steady": _SYMMETRY_ASSIST_STEADY,
    "symmetry-assist-steady-light": replace(
        _SYMMETRY_ASSIST_STEADY,
        description="symmetry-assist-steady with the table's trunk, thigh and calf masses narrowed to the "
                    "benchmark's 12-21 kg quadrupeds (presets.LIGHT_MORPHOLOGY_RANGES)",
        env=MappingProxyType({**_SYMMETRY_ASSIST.env, "morphology_ranges": LIGHT_MORPHOLOGY_RANGES})),
    "symmetry-assist-cover": replace(
        _SYMMETRY_ASSIST,
        description="symmetry-assist with the morphology table widened to hold the benchmark's quadrupeds "
                    "(benchmarks/morphology_coverage.py)",
        env=MappingProxyType({**_SYMMETRY_ASSIST.env, "morphology_ranges": COVERING_MORPHOLOGY_RANGES})),
    "kickstart-scripted": _KICKSTART_SCRIPTED,
    "kickstart-scripted-wide": replace(
        _KICKSTART_SCRIPTED,
        description="kickstart-scripted on the wide bodies: 2-60 kg, knees backward, forward or forward on one "
                    "pair, flipped joint axes and legs folded at joint zero (bodies=wide; training.bodies, "
                    "docs/training.md)",
        env=MappingProxyType({**KICKSTART_SCRIPTED, "bodies": "wide"})),
    "kickstart-scripted-wide-floor": replace(
        _KICKSTART_SCRIPTED,
        description="kickstart-scripted-wide whose imitation weight stops at 0.1 instead of 0: the teacher goes on "
                    "acting in its quarter of the episodes to the end (imitation_floor=0.1; docs/training.md)",
        env=MappingProxyType({**KICKSTART_SCRIPTED, "bodies": "wide", "imitation_floor": 0.1})),
    "no-stability": Preset(
        "demo-starts without the stability reward terms (the frnet-no-stability ablation)",
        env=_DEMO_STARTS, drop_terms=STABILITY_TERMS),
    "g1-residual": Preset(
        "G1 on flat ground: a gated residual over the keyframe-humanoid key frames, actions held 10 steps",
        env=MappingProxyType({
            "robot": "g1", "families": ("flat",), "base_controller": "keyframe-humanoid", "residual_gate": True,
            "gate_phases": ("tuck", "prop", "rock", "crouch", "rise", "hold"), "action_hold": 10,
            "action_scale": 0.1, "randomize": False, "episode_steps": 250, "settle_steps": 50}),
        motion_penalties=G1_MOTION_PENALTY_SCALE, reward_weights=MappingProxyType({"velocity_limit": -0.01}),
        init_std=0.25),
    "g1-assist": Preset(
        "G1 on flat ground: a residual over scripted-humanoid with HoST's assist force and demo starts",
        env=MappingProxyType({
            "robot": "g1", "families": ("flat",), "base_controller": "scripted-humanoid", "action_scale": 0.5,
            "assist_force": 0.6, "demo_start_fraction": 0.3})),
})
