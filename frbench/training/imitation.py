"""Kickstarting: PPO with an imitation term toward a teacher's action (Schmitt et al. 2018), after DAgger.

`KickstartPPO` (``"frbench.training.imitation:KickstartPPO"``) is frbench's `EstimatorPPO` (rsl-rl's PPO, the
Mass-Contact Predictor trained on PPO's mini-batches, the critic on the privileged observation: unchanged)
with one more loss term on each mini-batch,

    L = L_PPO(rows scaled by w_rl) + w_im · mean_rows Σ_j (μ_j(o) − a*_j)²,

where μ is the actor's mean action, a* the teacher's label (`frbench.training.teacher`: the observation group
``teacher`` holds the label, w_im, w_rl and whether the teacher acted, per row, at the env step the row was
collected, `frbench.training.dagger.ImitationSchedule`). DAgger's rows have w_rl = 0: their advantages are
zeroed (the surrogate has no gradient; the teacher, not the sampled action, moved those episodes), the entropy
bonus is off and the learning rate stays fixed (PPO's KL rule would read the imitation's steps as a policy
change), while the value function and the estimator learn as in PPO. After DAgger w_im decays to 0; the rows
of episodes the teacher still acts in (``kickstart_beta``) keep w_rl = 0, the learner's rows have w_rl = 1 and,
with ``imitate_rows = "teacher"``, w_im = 0 (`frbench.training.dagger.ImitationSchedule.row_weights`); after the
decay it is plain FR-Net PPO.

The term enters through rsl-rl's extension slot for a policy loss, ``PPO.symmetry`` (`ImitationLoss`:
``augment_batch`` leaves the batch, ``compute_loss`` returns the term, which PPO adds to its loss before its
one backward pass), so rsl-rl's update runs as it is; its mean is logged as ``imitation`` with the mean
weight ``imitation_weight``. Mirrored samples (`frbench.training.symmetry`) are not combined with it.
"""

from __future__ import annotations

import torch

from frbench.training.algorithm import EstimatorPPO
from frbench.training.teacher import TEACHER_GROUP


def imitation_loss(mean: torch.Tensor, teacher: torch.Tensor) -> torch.Tensor:
    """w_im · mean over rows of Σ_j (μ_j − a*_j)² for actor means ``mean`` (B, J) and the ``teacher`` group
    (B, J + 3): label (J), imitation weight, PPO weight, teacher acted."""
    joints = mean.shape[-1]
    label, weight = teacher[:, :joints], teacher[:, joints]
    return (weight * (mean - label).square().sum(dim=-1)).mean()


class ImitationLoss:
    """The imitation term in rsl-rl's policy-loss slot (``PPO.symmetry``; module docstring)."""

    use_data_augmentation = False
    use_mirror_loss = True  # PPO adds ``mirror_loss_coeff`` × `compute_loss` to its loss
    mirror_loss_coeff = 1.0

    def augment_batch(self, batch, original_batch_size: int) -> None:
        """No augmentation: the batch stays as it is."""

    def compute_loss(self, actor, batch, original_batch_size: int) -> torch.Tensor:
        """The term on this mini-batch, from the actor's forward pass PPO has just run on it."""
        return imitation_loss(actor.output_mean[:original_batch_size], batch.observations[TEACHER_GROUP].float())


class KickstartPPO(EstimatorPPO):
    """`EstimatorPPO` with the imitation term and DAgger's rows (module docstring). Same arguments."""

    def __init__(self, actor, critic, storage, **kwargs) -> None:
        if kwargs.get("symmetry_cfg"):
            raise ValueError("KickstartPPO: symmetry_cfg: mirrored samples are not combined with the imitation term")
        super().__init__(actor, critic, storage, **kwargs)
        if TEACHER_GROUP not in self.storage.observations.keys():
            raise ValueError(f"KickstartPPO needs the env's {TEACHER_GROUP!r} observation group "
                             "(TrainEnvConfig.teacher, e.g. 'scripted')")
        self.symmetry = ImitationLoss()
        self.base_entropy_coef, self.base_schedule = self.entropy_coef, self.schedule

    def _weights(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(imitation weight, PPO weight) of every stored row, each (T, N, 1)."""
        teacher = self.storage.observations[TEACHER_GROUP]
        joints = teacher.shape[-1] - 3
        return teacher[..., joints:joints + 1], teacher[..., joints + 1:joints + 2]

    def compute_returns(self, obs) -> None:
        """PPO's returns and normalised advantages, each row's advantage then scaled by its PPO weight."""
        super().compute_returns(obs)
        self.storage.advantages = self.storage.advantages * self._weights()[1]

    def update(self) -> dict[str, float]:
        """`EstimatorPPO.update` with the entropy bonus scaled by the rollout's mean PPO weight and the learning
        rate fixed while that weight is 0; the imitation term logged as ``imitation`` and its mean weight as
        ``imitation_weight``."""
        imitation_weight, rl_weight = (float(w.mean()) for w in self._weights())
        self.entropy_coef = self.base_entropy_coef * rl_weight
        self.schedule = self.base_schedule if rl_weight > 0 else "fixed"
        try:
            losses = super().update()
        finally:
            self.entropy_coef, self.schedule = self.base_entropy_coef, self.base_schedule
        losses["imitation"] = losses.pop("symmetry")
        losses["imitation_weight"] = imitation_weight
        return losses
