"""A mixture-density actor: K Gaussian components over the action vector, for targets with several answers.

:class:`MixtureDensityModel` is an `rsl_rl.models.MLPModel` whose MLP outputs, per input, the parameters
of a mixture of K Gaussians with diagonal covariances over the J-dimensional action a:

* mixture logits (K,): weights π = softmax(logits);
* component means μ (K, J);
* component spreads σ (K, J) = ``MIN_STD`` + softplus(raw) [action units, rad for joint targets].

It is trained by the negative log-likelihood of the targets (:meth:`MixtureDensityModel.nll`), so a
target that takes one of several distinct values for the same input is fitted by several components
instead of by their average; :meth:`MixtureDensityModel.loss`, the training objective, gives the means the
gradient of a squared error weighted by each component's responsibility for the target, in place of the
likelihood's, which weighs every residual by 1/σ² (β-NLL with β = 1 for the means: Seitzer et al., "On the
pitfalls of heteroscedastic uncertainty estimation with probabilistic neural networks", ICLR 2022):
otherwise the targets a narrow component fits dominate the shared layers' gradient, and the means of the
broad components fit slowly (docs/planning.md, "A third attempt"). Its ``forward`` is deterministic: the mean of the most probable component
(arg max π), so a loader that builds it from its ``class_name`` (``frbench.policies.learned.LearnedPolicy``)
runs it like any other deterministic actor, with the same (N, J) output.
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDict

from rsl_rl.models import MLPModel
from rsl_rl.modules import HiddenState

#: Smallest component spread [action units]: keeps the likelihood bounded when a component fits one target.
MIN_STD = 0.01


class MixtureDensityModel(MLPModel):
    """An MLP (observation normalisation as `MLPModel`'s) that outputs a K-component Gaussian mixture over
    the ``output_dim`` actions; ``forward`` returns the mean of the most probable component (N, output_dim)."""

    def __init__(self, obs: TensorDict, obs_groups: dict[str, list[str]], obs_set: str, output_dim: int,
                 hidden_dims=(256, 256, 128), activation: str = "elu", obs_normalization: bool = False,
                 components: int = 5) -> None:
        """`MLPModel`'s arguments (``output_dim``: the actions J) plus the number of ``components`` K."""
        if int(components) < 1:
            raise ValueError(f"components: expected a positive integer, got {components!r}")
        self.components, self.action_dim = int(components), int(output_dim)
        super().__init__(obs, obs_groups, obs_set, self.components * (2 * self.action_dim + 1), hidden_dims,
                         activation, obs_normalization)

    def mixture(self, obs: TensorDict) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(log π (N, K), means μ (N, K, J), spreads σ (N, K, J)) of the mixture for the observations."""
        out = self.mlp(self.get_latent(obs))
        k, j = self.components, self.action_dim
        log_weights = torch.log_softmax(out[:, :k], dim=-1)
        means = out[:, k:k + k * j].reshape(-1, k, j)
        stds = MIN_STD + torch.nn.functional.softplus(out[:, k + k * j:].reshape(-1, k, j))
        return log_weights, means, stds

    @staticmethod
    def _log_joint(log_weights, means, stds, targets) -> torch.Tensor:
        """log π_k + log N(targets; μ_k, diag σ_k²) (N, K)."""
        z = (targets[:, None, :] - means) / stds
        log_normal = -0.5 * z.square() - torch.log(stds) - 0.5 * math.log(2.0 * math.pi)
        return log_weights + log_normal.sum(dim=-1)

    def nll(self, obs: TensorDict, targets: torch.Tensor) -> torch.Tensor:
        """Mean negative log-likelihood [nats per sample] of the targets (N, J) under the mixture."""
        return -torch.logsumexp(self._log_joint(*self.mixture(obs), targets), dim=-1).mean()

    def loss(self, obs: TensorDict, targets: torch.Tensor) -> torch.Tensor:
        """The training objective for targets (N, J): the NLL with the means held fixed (it trains π and σ)
        plus ½ Σ_k r_k ‖μ_k − target‖² (it trains the means), r_k the components' responsibilities for the
        target (posterior, held fixed). Same minimiser in π, σ as the NLL; per sample, mean over N."""
        log_weights, means, stds = self.mixture(obs)
        log_joint = self._log_joint(log_weights, means.detach(), stds, targets)
        responsibility = torch.softmax(log_joint, dim=-1).detach()
        squared = (means - targets[:, None, :]).square().sum(dim=-1)
        return (-torch.logsumexp(log_joint, dim=-1) + 0.5 * (responsibility * squared).sum(dim=-1)).mean()

    def forward(
        self,
        obs: TensorDict,
        masks: torch.Tensor | None = None,
        hidden_state: HiddenState = None,
        stochastic_output: bool = False,
    ) -> torch.Tensor:
        """The mean (N, J) of each input's most probable component (deterministic; ``stochastic_output`` is
        refused: the model is an imitation student, not a PPO actor)."""
        if stochastic_output:
            raise ValueError("MixtureDensityModel: only deterministic output (the most probable component's mean)")
        log_weights, means, _ = self.mixture(obs)
        best = log_weights.argmax(dim=-1)
        return means[torch.arange(len(means)), best]
