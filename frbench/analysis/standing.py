"""How a policy stands once it is up: which body parts touch the ground, and how much it fidgets.

The quadruped success test (`frbench.tasks.success`) needs 0.5 s of *stable*
standing: tilt ≤ 30°, base ≥ 75 % of its standing height, and no body part but
the feet touching anything. A policy that gets up but fidgets can meet the tilt
and height conditions for most of an episode and still fail on contacts; this
analysis measures that. For each backend it runs a cell of episodes (the same
starts as ``frbench evaluate``) and, over the control steps at which the robot
is *up* (tilt and height conditions met), reports:

* the share of those steps with any body contact, and per contact group;
* the mean |Δq*| between consecutive joint targets [rad per joint per step].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from frbench.evaluation.episodes import run_episodes
from frbench.policies.registry import load_policy
from frbench.robot_checks.lookup import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.terrains import make_terrain


@dataclass
class StandingTally:
    """Counts over the control steps at which the robot is up (see the module docstring)."""

    group_names: tuple[str, ...]
    episodes: int = 0
    successes: int = 0
    up_steps: int = 0
    body_contact_steps: int = 0
    group_steps: np.ndarray = field(default=None)  # (n_groups,) up steps at which each group touches
    target_change_sum: float = 0.0  # Σ over up steps of the mean |Δq*| per joint [rad]
    target_change_steps: int = 0

    def __post_init__(self):
        if self.group_steps is None:
            self.group_steps = np.zeros(len(self.group_names), dtype=int)

    def add_step(self, up: np.ndarray, group_contact: np.ndarray, target_change: np.ndarray | None) -> None:
        """One control step of N episodes: ``up`` (N,) bool, ``group_contact`` (N, G) bool, ``target_change``
        (N,) mean |Δq*| per joint [rad] (None at the first step)."""
        self.up_steps += int(up.sum())
        self.body_contact_steps += int((up & group_contact.any(axis=1)).sum())
        self.group_steps += (up[:, None] & group_contact).sum(axis=0)
        if target_change is not None:
            self.target_change_sum += float(target_change[up].sum())
            self.target_change_steps += int(up.sum())

    def summary(self) -> dict:
        """JSON-able shares (None when the robot was never up)."""
        share = (lambda k: k / self.up_steps) if self.up_steps else (lambda k: None)
        return {
            "episodes": self.episodes,
            "successes": self.successes,
            "up_steps": self.up_steps,
            "body_contact_share": share(self.body_contact_steps),
            "group_contact_share": {n: share(int(k)) for n, k in zip(self.group_names, self.group_steps)},
            "mean_target_change_rad": (self.target_change_sum / self.target_change_steps
                                       if self.target_change_steps else None),
        }


def standing_analysis(policy_reference: str, robot: str, backends=("mujoco", "pybullet"), terrain: str = "flat",
                      level: int = 1, seeds=(0, 1), episodes: int = 8) -> dict[str, dict]:
    """Per backend, the `StandingTally` summary of ``episodes`` × ``seeds`` episodes of one cell."""
    spec = get_robot(robot)
    policy = load_policy(policy_reference)
    names = tuple(g.name for g in spec.contact_groups)
    report = {}
    for backend in backends:
        tally = StandingTally(names)
        for seed in seeds:
            world = make_terrain(terrain, level, seed)
            starts = draw_starts(spec, world, terrain, level, seed, range(episodes))
            previous = None

            def record(task, targets):
                nonlocal previous
                change = None if previous is None else np.abs(targets - previous).mean(axis=1)
                tally.add_step(task.success.up_pose(task.signals), task.contacts.group_contact, change)
                previous = targets

            task = run_episodes(spec, backend, world, starts, policy, seed=seed, on_step=record)
            tally.episodes += episodes
            tally.successes += int(task.success.success.sum())
        report[backend] = tally.summary()
    return report


def format_report(report: dict[str, dict], top: int = 4) -> str:
    """A plain-text table: one line per backend."""
    lines = []
    for backend, row in report.items():
        if row["up_steps"] == 0:
            lines.append(f"{backend:<9} success {row['successes']}/{row['episodes']}; never up")
            continue
        groups = sorted(row["group_contact_share"].items(), key=lambda kv: -kv[1])[:top]
        touching = ", ".join(f"{n} {v:.2f}" for n, v in groups if v > 0) or "none"
        lines.append(f"{backend:<9} success {row['successes']}/{row['episodes']}; up {row['up_steps']} steps: "
                     f"body contact {row['body_contact_share']:.2f} (most: {touching}); "
                     f"mean |Δq*| {row['mean_target_change_rad']:.3f} rad/step")
    return "\n".join(lines)
