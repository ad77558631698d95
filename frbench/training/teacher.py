"""A teacher that labels inside the vectorised training env: the ``scripted`` controller, every control step.

`EnvTeacher` runs one `frbench.policies.scripted.ScriptedPolicy` per robot of the training batch (each drives
its own environments, in its robot's joints, as `frbench.training.demo_starts` does) on the observations the
environments really visit, whoever acts. At every control step it gives each environment's label, the action
in the learner's frame and units that asks for the controller's joint targets (`dagger.teacher_label`). In the
episodes the teacher acts in (DAgger's rule, `dagger.ImitationSchedule.acts`) the env executes the label
instead of the learner's action, plus, with ``noise`` > 0, Gaussian noise of that standard deviation [action
units] drawn afresh every control step (DART, Laskey et al. 2017). The noise is what keeps the learner from
copying: the teacher's targets move by small ramps, so without it the previous action in the learner's
observation predicts the next label almost exactly, and a learner that copies it imitates well on the teacher's
states and stalls on its own (docs/training.md, "Why the first recipe stalled"). The label stays the teacher's
clean target; the executed, noisy action is the one the next observation carries.

The training env adds the observation group ``teacher`` (N, J + 3) (`TEACHER_GROUP`): the label (J), each
row's imitation weight and PPO weight at the current env step (`dagger.ImitationSchedule.row_weights`), and 1
where the teacher acted. PPO's storage keeps it with the other groups, so each mini-batch row carries its own label and
weights (`frbench.training.imitation`); no network reads it.

The controller is stateful (its phase, its ramps): it is reset at every new episode and asked exactly once per
control step, so the env needs ``action_hold`` 1. Shapes: N environments, J joints.
"""

from __future__ import annotations

import numpy as np

from frbench.policies.scripted import ScriptedPolicy
from frbench.training.dagger import ImitationSchedule, teacher_label

#: The observation group of the teacher's label and weights.
TEACHER_GROUP = "teacher"
#: Teachers the training env can label with (``TrainEnvConfig.teacher``).
ENV_TEACHERS = ("scripted",)


class EnvTeacher:
    """``scripted`` on every environment of a training batch (module docstring).

    Args:
        specs: the batch's robots; environment i is ``specs[assignment[i]]``.
        assignment: (N,) index into ``specs``.
        policy_default_pose: (J,) the learner's default pose [rad] in its frame.
        frame: the learner's `JointFrame` (None: the robots' own joints).
        scale: the learner's action scale (q* = q̊ + scale·a).
        schedule: the `ImitationSchedule`.
        noise: standard deviation [action units] of the noise added where the teacher acts (0: none).
        seed: the seed of the noise, drawn per episode from a generator seeded by (seed, episode).
    """

    def __init__(self, specs, assignment: np.ndarray, policy_default_pose: np.ndarray, frame, scale: float,
                 schedule: ImitationSchedule, noise: float = 0.0, seed: int = 0):
        self.specs, self.assignment = list(specs), np.asarray(assignment)
        self.groups = [np.flatnonzero(self.assignment == k) for k in range(len(self.specs))]
        self.controllers = [ScriptedPolicy() for _ in self.specs]
        self.policy_default_pose, self.frame, self.scale = np.asarray(policy_default_pose), frame, float(scale)
        self.schedule = schedule
        n = len(self.assignment)
        self.label = np.zeros((n, len(self.policy_default_pose)))
        self.acting = np.zeros(n, dtype=bool)
        self.env_steps = 0
        self.noise, self.seed = float(noise), int(seed)
        self.noise_rng = np.random.default_rng([self.seed, 0, 11])

    def new_episodes(self, observation: dict[str, np.ndarray], env_steps: int, episode: int) -> None:
        """New episodes of every environment from ``observation`` (the robots' proprioception dict, their own
        joints) at ``env_steps``, the ``episode``-th of the run: the controllers reset, who acts drawn, the first
        labels."""
        for controller, spec, ids in zip(self.controllers, self.specs, self.groups):
            if len(ids):
                controller.reset(spec, len(ids))
        self.resume(env_steps, episode)
        self.observe(observation, env_steps)

    def resume(self, env_steps: int, episode: int) -> None:
        """Who acts in the ``episode``-th episode, its noise generator and the weights at ``env_steps`` (also a
        resumed run's current episode)."""
        self.acting = self.schedule.acts(env_steps, episode, len(self.assignment))
        self.noise_rng = np.random.default_rng([self.seed, int(episode), 11])
        self.env_steps = env_steps

    def observe(self, observation: dict[str, np.ndarray], env_steps: int) -> None:
        """The labels (N, J) of this control step's ``observation`` (its ``projected_gravity`` (N, 3) and
        ``joint_pos`` (N, J) [rad], the robots' own joints), and the weights at ``env_steps``."""
        targets = np.zeros_like(self.label)
        for controller, ids in zip(self.controllers, self.groups):
            if len(ids):
                targets[ids] = controller.act({"projected_gravity": observation["projected_gravity"][ids],
                                               "joint_pos": observation["joint_pos"][ids]})
        self.label = teacher_label(targets, self.policy_default_pose, self.frame, self.scale)
        self.env_steps = env_steps

    def executed(self, action: np.ndarray) -> np.ndarray:
        """The actions (N, J) the env executes: the label (plus the noise) where the teacher acts, ``action``
        elsewhere."""
        if not self.acting.any():
            return action
        acted = self.label
        if self.noise > 0:
            acted = acted + self.noise * self.noise_rng.standard_normal(self.label.shape)
        return np.where(self.acting[:, None], acted, action)

    def group(self) -> np.ndarray:
        """The ``teacher`` observation group (N, J + 3): label, imitation weight, PPO weight, teacher acted."""
        imitation, rl = self.schedule.row_weights(self.env_steps, self.acting)
        return np.concatenate([self.label, imitation[:, None], rl[:, None], self.acting[:, None].astype(np.float64)],
                              axis=1)
