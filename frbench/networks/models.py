"""Actors for rsl-rl: FR-Net's estimator actor (and its ablations, DreamRiser) and RMA's actor.

Both subclass :class:`rsl_rl.models.MLPModel` and only change what the policy
MLP sees (``get_latent``). Their observation groups are positional:

* :class:`EstimatorActor`: ``[o_t group, history group]`` (``["policy", "history"]``),
  or ``[o_t group]`` alone when the estimator is disabled;
* :class:`RMAActor`: ``[o_t group, extrinsics group]`` in phase 1, plus
  ``long history group`` third for phase 2 (``["policy", "extrinsics", "long_history"]``).

Normalisation: the MLPModel normaliser (``obs_normalizer``) covers o_t only
(D = 42 columns). Histories are normalised **per frame with the same
statistics** (reshape (N, H·D) → (N, H, D)): one set of statistics serves o_t,
the estimator's input and its reconstruction target, the zero padding before
an episode start does not bias them, and an exported policy carries one
mean/std pair.

To read their groups they override ``_get_obs_dim`` and ``_get_latent_dim``, the hooks that rsl-rl's own
subclasses of MLPModel (``CNNModel``, ``RNNModel``) override for the same purpose.

Exports (``as_onnx`` / ``as_jit``) take the RAW o_t (N, D) and the raw second
input (history, extrinsics or long history) and return deterministic actions;
they need torch only (no frbench, no rsl-rl) to run.
"""

from __future__ import annotations

import copy
import dataclasses

import torch
import torch.nn as nn
from tensordict import TensorDict

from rsl_rl.models import MLPModel
from rsl_rl.modules import MLP, EmpiricalNormalization, HiddenState
from rsl_rl.utils import resolve_nn_activation

from frbench.networks.estimator import EncoderHeads, Estimator, EstimatorConfig


def _group_width(obs: TensorDict, group: str) -> int:
    if obs[group].dim() != 2:
        raise ValueError(f"observation group {group!r}: expected shape (N, k), got {tuple(obs[group].shape)}")
    return int(obs[group].shape[-1])


def _normalize_frames(normalizer: nn.Module, history: torch.Tensor, frames: int, frame_dim: int) -> torch.Tensor:
    """(N, T·D) → normaliser applied to each of the T frames → (N, T·D)."""
    return normalizer(history.reshape(-1, frames, frame_dim)).reshape(-1, frames * frame_dim)


class _FramewiseNormalizer(nn.Module):
    """Normalise a flattened history (N, T·D) frame by frame with a D-wide normaliser."""

    def __init__(self, normalizer: nn.Module, frames: int, frame_dim: int) -> None:
        super().__init__()
        self.normalizer = normalizer
        self.frames = frames
        self.frame_dim = frame_dim

    def forward(self, history: torch.Tensor) -> torch.Tensor:
        x = self.normalizer(history.reshape(-1, self.frames, self.frame_dim))  # inline: TorchScript-compatible
        return x.reshape(-1, self.frames * self.frame_dim)


class _SideBranch(nn.Module):
    """Export helper: raw side input → normaliser → network → features (N, k)."""

    def __init__(self, normalizer: nn.Module, net: nn.Module) -> None:
        super().__init__()
        self.normalizer = normalizer
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(self.normalizer(x))


class _FeatureNet(nn.Module):
    """Export helper: the estimator's deterministic policy features."""

    def __init__(self, heads: EncoderHeads) -> None:
        super().__init__()
        self.heads = heads

    def forward(self, history: torch.Tensor) -> torch.Tensor:
        return self.heads.policy_features(history)


class _TwoInputPolicy(nn.Module):
    """Exported policy: actions = MLP([norm(o_t), side(raw side input)]), deterministic.

    ``forward(obs (N, D), side (N, S)) -> actions (N, A)``; TorchScript- and ONNX-exportable.
    """

    is_recurrent: bool = False

    def __init__(self, model: MLPModel, side: nn.Module, side_dim: int, side_name: str, verbose: bool = False) -> None:
        super().__init__()
        self.verbose = verbose
        self.obs_normalizer = copy.deepcopy(model.obs_normalizer)
        self.side = copy.deepcopy(side)
        self.mlp = copy.deepcopy(model.mlp)
        if model.distribution is not None:
            self.deterministic_output = model.distribution.as_deterministic_output_module()
        else:
            self.deterministic_output = nn.Identity()
        self.input_size = model.obs_dim
        self.side_dim = side_dim
        self.side_name = side_name

    def forward(self, obs: torch.Tensor, side: torch.Tensor) -> torch.Tensor:
        latent = torch.cat([self.obs_normalizer(obs), self.side(side)], dim=-1)
        return self.deterministic_output(self.mlp(latent))

    @torch.jit.export
    def reset(self) -> None:
        """No recurrent state."""
        pass

    def get_dummy_inputs(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Example inputs for ONNX tracing: zeros (1, D) and (1, S)."""
        return torch.zeros(1, self.input_size), torch.zeros(1, self.side_dim)

    @property
    def input_names(self) -> list[str]:
        return ["obs", self.side_name]

    @property
    def output_names(self) -> list[str]:
        return ["actions"]


class EstimatorActor(MLPModel):
    """FR-Net's actor: π(a | [o_t, m̂, ĉ, v̂, ẑ]) with the estimator inside.

    Policy input ``get_latent`` (N, D + feature_dim): 75 for FR-Net
    (42 + 4 + 13 + 16), 71 without mass, 62 without contact, 59 without the
    auto-encoder, 61 for DreamRiser (42 + 3 + 16).

    Gradient stop: the estimator's features enter the policy detached, so PPO's
    loss never reaches the estimator; the estimator is trained only by its own
    loss (:class:`frbench.training.algorithm.EstimatorPPO`), as the paper's
    separate L_φ. This keeps the estimates meaning what they are supervised to
    mean (masses, contacts) rather than whatever helps the surrogate.

    The latent enters as its mean μ_z (deterministic): PPO recomputes the
    log-probabilities of stored actions, and a fresh z sample per pass would
    make the importance ratio (and the adaptive-KL schedule) noisy; the
    reparameterised sample trains the decoder only.

    Args (beyond MLPModel's): ``estimator``: keyword arguments of
    :class:`EstimatorConfig` (``obs_dim`` is taken from the o_t group; None =
    the paper's MCP). A configuration without heads and with ``latent_dim=0``
    gives no estimator: the policy sees o_t only (groups ``[o_t group]``).
    """

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        hidden_dims: tuple[int, ...] | list[int] = (256, 128, 128),
        activation: str = "elu",
        obs_normalization: bool = True,
        distribution_cfg: dict | None = None,
        estimator: dict | None = None,
    ) -> None:
        # Plain attributes may be set before nn.Module.__init__; _get_obs_dim and _get_latent_dim need them.
        self.estimator_cfg = EstimatorConfig(**(estimator or {}))
        super().__init__(obs, obs_groups, obs_set, output_dim, hidden_dims, activation, obs_normalization,
                         distribution_cfg)
        self.estimator = Estimator(self.estimator_cfg) if self.estimator_cfg.enabled else None
        #: Set by `EstimatorPPO` during its update: forward passes with gradients then keep the estimator's
        #: full output (with its graph) in ``estimator_output`` for the estimator's step on the same rows.
        self.keep_estimator_output = False
        self.estimator_output = None

    def _get_obs_dim(self, obs: TensorDict, obs_groups: dict[str, list[str]], obs_set: str) -> tuple[list[str], int]:
        groups = list(obs_groups[obs_set])
        cfg = self.estimator_cfg
        if not 1 <= len(groups) <= 2:
            raise ValueError(f"EstimatorActor: obs groups of {obs_set!r} must be [o_t group, history group], "
                             f"got {groups}")
        obs_dim = _group_width(obs, groups[0])
        self.estimator_cfg = cfg = dataclasses.replace(cfg, obs_dim=obs_dim)
        if cfg.enabled:
            if len(groups) != 2:
                raise ValueError(f"EstimatorActor: the estimator needs a history group after {groups[0]!r} in "
                                 f"obs_groups[{obs_set!r}], got {groups}")
            width = _group_width(obs, groups[1])
            if width != cfg.input_dim:
                raise ValueError(f"EstimatorActor: history group {groups[1]!r} has {width} columns, expected "
                                 f"H·D = {cfg.history_frames}·{obs_dim} = {cfg.input_dim} (oldest frame first)")
        return groups, obs_dim

    def _get_latent_dim(self) -> int:
        return self.obs_dim + self.estimator_cfg.feature_dim

    # --- inputs of the estimator (used by the algorithm too) ---
    def normalize_obs(self, o: torch.Tensor) -> torch.Tensor:
        """Normalised o_t, (..., D) → (..., D)."""
        return self.obs_normalizer(o)

    def normalize_history(self, history: torch.Tensor) -> torch.Tensor:
        """Normalised history (N, H·D), frame by frame with the o_t statistics."""
        cfg = self.estimator_cfg
        return _normalize_frames(self.obs_normalizer, history, cfg.history_frames, cfg.obs_dim)

    def get_latent(
        self, obs: TensorDict, masks: torch.Tensor | None = None, hidden_state: HiddenState = None
    ) -> torch.Tensor:
        """Policy input (N, D + feature_dim): [norm(o_t), m̂, ĉ, v̂, μ_z], estimates detached."""
        o = self.obs_normalizer(obs[self.obs_groups[0]])
        if self.estimator is None:
            return o
        history = self.normalize_history(obs[self.obs_groups[1]])
        if self.keep_estimator_output and torch.is_grad_enabled():  # PPO's update: the estimator trains on this pass
            self.estimator_output = self.estimator(history, sample=True)
            features = self.estimator_output.features
        else:
            with torch.no_grad():
                features = self.estimator.policy_features(history)
        return torch.cat([o, features.detach()], dim=-1)

    def update_normalization(self, obs: TensorDict) -> None:
        """Update the o_t statistics from a batch (history frames share them)."""
        if self.obs_normalization:
            self.obs_normalizer.update(obs[self.obs_groups[0]])  # type: ignore[operator]

    def _export(self, verbose: bool) -> nn.Module:
        cfg = self.estimator_cfg
        side = _SideBranch(_FramewiseNormalizer(self.obs_normalizer, cfg.history_frames, cfg.obs_dim),
                           _FeatureNet(self.estimator.encoder))
        return _TwoInputPolicy(self, side, cfg.input_dim, "history", verbose)

    def as_jit(self) -> nn.Module:
        """TorchScript-ready policy: ``forward(obs (N, D), history (N, H·D)) -> actions``."""
        return super().as_jit() if self.estimator is None else self._export(False)

    def as_onnx(self, verbose: bool = False) -> nn.Module:
        """ONNX-ready policy: inputs ``obs`` (N, D), ``history`` (N, H·D); output ``actions``."""
        return super().as_onnx(verbose) if self.estimator is None else self._export(verbose)


class AdaptationModule(nn.Module):
    """RMA's adaptation module φ: the last T frames of o_t (N, T·D) → ẑ (N, z_dim).

    As in RMA (Kumar et al. 2021): each frame is embedded to 32 by a 2-layer
    MLP, then three 1-D convolutions over time (channels 32, kernel/stride
    8/4, 5/1, 5/1), flattened and projected linearly to ẑ. o_t already holds
    a_{t−1}, so frames of o_t are RMA's (x, a) pairs. Needs T ≥ 40 (T = 50 in RMA).
    """

    def __init__(self, frames: int, frame_dim: int, z_dim: int, channels: int = 32, activation: str = "elu") -> None:
        super().__init__()
        length = frames
        for kernel, stride in ((8, 4), (5, 1), (5, 1)):
            length = (length - kernel) // stride + 1
        if length < 1:
            raise ValueError(f"AdaptationModule: {frames} frames are too few for the RMA convolutions (need ≥ 40)")
        self.frames, self.frame_dim = frames, frame_dim
        self.embed = MLP(frame_dim, channels, (channels,), activation, last_activation=activation)
        self.conv = nn.Sequential(
            nn.Conv1d(channels, channels, 8, stride=4), resolve_nn_activation(activation),
            nn.Conv1d(channels, channels, 5, stride=1), resolve_nn_activation(activation),
            nn.Conv1d(channels, channels, 5, stride=1), resolve_nn_activation(activation),
        )
        self.out = nn.Linear(channels * length, z_dim)

    def forward(self, history: torch.Tensor) -> torch.Tensor:
        """ẑ (N, z_dim) of a normalised flattened history (N, T·D), oldest frame first."""
        x = self.embed(history.reshape(-1, self.frames, self.frame_dim))  # (N, T, C)
        x = self.conv(x.transpose(1, 2))  # (N, C, L)
        return self.out(x.flatten(1))


class RMAActor(MLPModel):
    """RMA's base policy π(a | [o_t, z]) with z from privileged extrinsics (phase 1) or from history (phase 2).

    * Phase 1 (``use_adaptation=False``): z = μ(norm(e_t)), μ an MLP
      (``encoder_hidden_dims`` 256-128) → ``z_dim`` = 8, trained end to end by
      PPO (gradients flow). Groups ``[o_t, extrinsics]``; policy input D + 8.
    * Phase 2 (``use_adaptation=True``): z = φ(norm(o_{t−T+1..t})), φ the
      :class:`AdaptationModule`; groups ``[o_t, extrinsics, long history]``;
      φ is trained by :class:`frbench.training.algorithm.RMAAdaptation`
      to regress μ(e_t) while this actor (π and μ frozen) acts.

    The adaptation module exists whenever a third group is given, so a phase-1
    checkpoint loads into a phase-2 actor with only the ``adaptation.*`` keys missing.
    Extrinsics have their own normaliser; long histories use the o_t statistics per frame.
    """

    def __init__(
        self,
        obs: TensorDict,
        obs_groups: dict[str, list[str]],
        obs_set: str,
        output_dim: int,
        hidden_dims: tuple[int, ...] | list[int] = (256, 128, 128),
        activation: str = "elu",
        obs_normalization: bool = True,
        distribution_cfg: dict | None = None,
        z_dim: int = 8,
        encoder_hidden_dims: tuple[int, ...] | list[int] = (256, 128),
        adaptation_frames: int = 50,
        use_adaptation: bool = False,
    ) -> None:
        self.z_dim = z_dim
        self.adaptation_frames = adaptation_frames
        super().__init__(obs, obs_groups, obs_set, output_dim, hidden_dims, activation, obs_normalization,
                         distribution_cfg)
        self.extrinsics_normalizer = (EmpiricalNormalization(self.extrinsics_dim) if obs_normalization
                                      else nn.Identity())
        self.encoder = MLP(self.extrinsics_dim, z_dim, tuple(encoder_hidden_dims), activation)
        self.adaptation = (AdaptationModule(adaptation_frames, self.obs_dim, z_dim, activation=activation)
                           if self.has_long_history else None)
        if use_adaptation and self.adaptation is None:
            raise ValueError("RMAActor: use_adaptation needs a long-history group third in the actor obs groups")
        self.use_adaptation = use_adaptation

    def _get_obs_dim(self, obs: TensorDict, obs_groups: dict[str, list[str]], obs_set: str) -> tuple[list[str], int]:
        groups = list(obs_groups[obs_set])
        if len(groups) not in (2, 3):
            raise ValueError(f"RMAActor: obs groups of {obs_set!r} must be [o_t, extrinsics(, long history)], "
                             f"got {groups}")
        obs_dim = _group_width(obs, groups[0])
        self.extrinsics_dim = _group_width(obs, groups[1])
        self.has_long_history = len(groups) == 3
        if self.has_long_history:
            width = _group_width(obs, groups[2])
            if width != self.adaptation_frames * obs_dim:
                raise ValueError(f"RMAActor: long-history group {groups[2]!r} has {width} columns, expected "
                                 f"{self.adaptation_frames}·{obs_dim} (oldest frame first)")
        return groups, obs_dim

    def _get_latent_dim(self) -> int:
        return self.obs_dim + self.z_dim

    def extrinsics_latent(self, obs: TensorDict) -> torch.Tensor:
        """z = μ(norm(e_t)) (N, z_dim), the phase-1 latent (and phase-2 target)."""
        return self.encoder(self.extrinsics_normalizer(obs[self.obs_groups[1]]))

    def adaptation_latent(self, obs: TensorDict) -> torch.Tensor:
        """ẑ = φ(norm(long history)) (N, z_dim), the phase-2 latent."""
        history = obs[self.obs_groups[2]]
        return self.adaptation(_normalize_frames(self.obs_normalizer, history, self.adaptation_frames, self.obs_dim))

    def get_latent(
        self, obs: TensorDict, masks: torch.Tensor | None = None, hidden_state: HiddenState = None
    ) -> torch.Tensor:
        """Policy input (N, D + z_dim): [norm(o_t), z] (z from φ in phase 2, detached there)."""
        o = self.obs_normalizer(obs[self.obs_groups[0]])
        if self.use_adaptation:
            with torch.no_grad():
                z = self.adaptation_latent(obs)
        else:
            z = self.extrinsics_latent(obs)
        return torch.cat([o, z], dim=-1)

    def update_normalization(self, obs: TensorDict) -> None:
        """Update the o_t and extrinsics statistics (phase 1 only; phase 2 keeps them frozen)."""
        if self.obs_normalization:
            self.obs_normalizer.update(obs[self.obs_groups[0]])  # type: ignore[operator]
            self.extrinsics_normalizer.update(obs[self.obs_groups[1]])  # type: ignore[operator]

    def _export(self, verbose: bool) -> nn.Module:
        if self.use_adaptation:
            normalizer = _FramewiseNormalizer(self.obs_normalizer, self.adaptation_frames, self.obs_dim)
            side = _SideBranch(normalizer, self.adaptation)
            return _TwoInputPolicy(self, side, self.adaptation_frames * self.obs_dim, "long_history", verbose)
        side = _SideBranch(self.extrinsics_normalizer, self.encoder)
        return _TwoInputPolicy(self, side, self.extrinsics_dim, "extrinsics", verbose)

    def as_jit(self) -> nn.Module:
        """TorchScript-ready policy ``forward(obs, long_history | extrinsics) -> actions``."""
        return self._export(False)

    def as_onnx(self, verbose: bool = False) -> nn.Module:
        """ONNX-ready policy with inputs ``obs`` and ``long_history`` (phase 2) or ``extrinsics`` (phase 1)."""
        return self._export(verbose)
