"""How closely a policy trained to imitate ``scripted`` reproduces it, on the teacher's own episodes and on its own.

``scripted`` drives the robot (Go2 by default, flat level 1, MuJoCo, the evaluation's starts of seed 0) while
the learned policy, a `frbench.policies.learned.LearnedPolicy` checkpoint, is asked for its joint targets on
the same observations at every control step ("shadowing"). Its observation's previous action is either

* ``fed``: the action the env really executed (the teacher's, in the learner's frame and units), as in the
  training env's DAgger episodes, or
* ``own``: the learner's own previous action, as when it drives the robot itself.

A third measure lets the learner drive and ``scripted`` label (DAgger's later rounds, a kickstarting term on
the learner's rows): ``drives`` is the same error on the learner's own episodes, the teacher running beside it
on its own clock (its phase, its ramps), so its label need not be what it would do from the learner's state.

The printed error is the mean absolute difference [rad] between the learner's and the teacher's joint targets
over all joints, steps and episodes. A learner that imitates by copying its previous action (the "copycat"
shortcut: ``scripted``'s targets move by small ramps, so the previous action predicts the next one almost
exactly) has a small ``fed`` error and a large ``own`` one. The last column is the learner's own success when it
drives the robot on the same starts (`frbench.evaluation.episodes.run_episodes`)::

    python benchmarks/imitation_fidelity.py runs/kickstart/policy.pt [more checkpoints] --episodes 4
"""

from __future__ import annotations

import argparse

import numpy as np

from frbench.evaluation.episodes import run_episodes
from frbench.policies.base import policy_joint_frame
from frbench.policies.registry import load_policy
from frbench.robot_checks.lookup import get_robot
from frbench.tasks.initial_states import draw_starts
from frbench.terrains import make_terrain
from frbench.training.dagger import teacher_label


class Shadow:
    """``scripted`` acts (or, ``drives``, the learner does); the other is asked on the same observations and the
    target errors [rad] are kept (N per step). ``fed``: the learner's previous action is set to the executed one
    (`teacher_label`)."""

    joint_frame = "robot"

    def __init__(self, learner, fed: bool, drives: bool = False):
        self.teacher, self.learner, self.fed, self.drives = load_policy("scripted"), learner, fed, drives
        self.errors: list[np.ndarray] = []

    def supports(self, spec) -> bool:
        return self.teacher.supports(spec) and self.learner.supports(spec)

    def reset(self, spec, num_envs: int) -> None:
        self.frame = policy_joint_frame(self.learner, spec)
        self.teacher.reset(spec, num_envs)
        self.learner.reset(self.frame.canonical_spec(spec) if self.frame is not None else spec, num_envs)

    def act(self, obs: dict) -> np.ndarray:
        teacher = np.asarray(self.teacher.act(obs))
        if self.frame is None:
            learner = self.learner.act(obs)
        else:
            learner = self.frame.targets(self.learner.act(self.frame.observation(obs)))
        self.errors.append(np.abs(teacher - learner).mean(axis=1))
        if self.drives:
            return learner
        if self.fed:  # the executed action, in the learner's frame and units, as its previous action
            self.learner.action = teacher_label(teacher, self.learner.default_pose, self.frame,
                                                self.learner.action_scale)
        return teacher


def fidelity(checkpoint: str, robot: str, terrain_name: str, level: int, episodes: int) -> dict:
    """The ``fed`` and ``own`` errors [rad] and the learner's own successes for one checkpoint."""
    spec = get_robot(robot)
    learner = load_policy(checkpoint)
    if getattr(learner, "base_controller", None) is not None:
        raise SystemExit(f"{checkpoint}: a residual policy; this measures a plain learned policy")
    terrain = make_terrain(terrain_name, level, 0)
    row = {}
    modes = {"fed": dict(fed=True), "own": dict(fed=False), "drives": dict(fed=False, drives=True)}
    for name, mode in modes.items():
        shadow = Shadow(learner, **mode)
        starts = draw_starts(spec, terrain, terrain_name, level, 0, range(episodes))
        run_episodes(spec, "mujoco", terrain, starts, shadow, seed=0, check=False)
        row[name] = float(np.mean(shadow.errors))
    starts = draw_starts(spec, terrain, terrain_name, level, 0, range(episodes))
    task = run_episodes(spec, "mujoco", terrain, starts, learner, seed=0)
    row["success"] = int(np.sum(task.success.success))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoints", nargs="+", help="learned policy checkpoints (policy.pt)")
    parser.add_argument("--robot", default="go2")
    parser.add_argument("--terrain", default="flat")
    parser.add_argument("--level", type=int, default=1)
    parser.add_argument("--episodes", type=int, default=4)
    args = parser.parse_args()
    print(f"target error [rad] on {args.robot}, {args.terrain} level {args.level}, MuJoCo, {args.episodes} starts "
          "of seed 0")
    print(f"{'checkpoint':40s} {'fed':>7s} {'own':>7s} {'drives':>7s} {'own success':>12s}")
    for checkpoint in args.checkpoints:
        row = fidelity(checkpoint, args.robot, args.terrain, args.level, args.episodes)
        print(f"{checkpoint:40s} {row['fed']:7.3f} {row['own']:7.3f} {row['drives']:7.3f} "
              f"{row['success']:>8d}/{args.episodes}")


if __name__ == "__main__":
    main()
