"""The Mass-Contact Predictor (MCP) of FR-Net and its variants (DreamRiser's estimator, ablations).

One network, configured by :class:`EstimatorConfig`:

* **encoder** E_φ: an MLP over the normalised history o_t^H = [o_{t−H+1}, …, o_t]
  (N, H·D), D = 42, whose last linear layer emits every head at once, in the
  order [m̂ (4), ĉ logits (13), v̂ (3), μ_z (L), log σ²_z (L)] (disabled heads are
  absent);
* **heads**: m̂ the four group masses (base, hip, thigh, calf; each summed over
  the legs) *divided by* :attr:`EstimatorConfig.mass_scale`; ĉ = σ(logits), the
  contact probabilities of the 13 bodies; v̂ the body-frame base velocity
  [m/s] (DreamRiser); ẑ the variational latent (L = 16 in the paper);
* **decoder** D_θ (only when L > 0): [m̂, ĉ, v̂, z] → ô_{t+1} (N, D), in the
  normalised observation space.

The policy sees :meth:`Estimator.policy_features`: [m̂, ĉ, v̂, μ_z]; the latent
enters as its mean (deterministic), while the decoder is trained on the
reparameterised sample z = μ + σ·ε, as in a VAE.

Loss (the paper's L_φ = L^est + L^VAE, DreamRiser's velocity term added)::

    λm·MSE(m̂, m / s_m) + λc·BCE(ĉ, c) + λv·MSE(v̂, v)
      + λrec·MSE(ô_{t+1}, o_{t+1}) + λKL·KL(N(μ, σ²) ‖ N(0, I))

MSE and BCE are means over batch and components; the KL is summed over the L
latent dimensions and averaged over the batch (the divergence of the
L-dimensional Gaussian); the reconstruction is a mean over the valid pairs
only (pairs (t, t+1) that cross an episode end carry no information).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
import torch.nn as nn
import torch.nn.functional as F

from rsl_rl.modules import MLP

#: Mass scale [kg] per group (base, hip, thigh, calf): the paper's MCP heat map
#: normalises by 15 for the body and 5 for the limbs (each limb group summed over 4 legs).
PAPER_MASS_SCALE = (15.0, 5.0, 5.0, 5.0)


@dataclass(frozen=True)
class EstimatorConfig:
    """Shape, heads and loss weights of the estimator (one frozen value per method).

    Default weights: the paper gives none. Every regression target is O(1)
    (masses divided by :attr:`mass_scale`, observations normalised to unit
    variance, velocities in m/s), and BCE at chance is ln 2 ≈ 0.7, so
    λm = λc = λvel = λrec = 1 weigh the terms equally. λKL = 0.01: with the KL
    summed over 16 latent dimensions and the reconstruction a per-component
    mean over D = 42, this is a β-VAE with β = λKL·D/2 ≈ 0.2 in ELBO units
    (unit-variance Gaussian decoder); β < 1 keeps the latent informative
    (avoids posterior collapse), the regime DreamWaQ/DreamRiser use.
    """

    history_frames: int = 5
    """H: frames of o_t in the encoder input (the paper: 5)."""
    obs_dim: int = 42
    """D: width of one frame o_t (replaced by the environment's width when an actor builds it)."""
    mass: bool = True
    """Estimate the 4 group masses m̂ (FR-Net)."""
    contact: bool = True
    """Estimate the 13 contact probabilities ĉ (FR-Net)."""
    velocity: bool = False
    """Estimate the body-frame base velocity v̂ (DreamRiser)."""
    latent_dim: int = 16
    """L: variational latent size; 0 means no auto-encoder (no latent, no decoder)."""
    num_masses: int = 4
    num_contacts: int = 13
    velocity_dim: int = 3
    encoder_hidden_dims: tuple[int, ...] = (256, 128)
    decoder_hidden_dims: tuple[int, ...] = (128, 256)
    activation: str = "elu"
    mass_scale: tuple[float, ...] = field(default=PAPER_MASS_SCALE)
    """Divisors [kg] of the mass targets (and units of m̂): base 15, limbs 5."""
    mass_weight: float = 1.0
    """λm."""
    contact_weight: float = 1.0
    """λc."""
    velocity_weight: float = 1.0
    """λvel."""
    recon_weight: float = 1.0
    """λrec."""
    kl_weight: float = 0.01
    """λKL."""

    def __post_init__(self) -> None:
        if self.history_frames < 1 or self.obs_dim < 1 or self.latent_dim < 0:
            raise ValueError(f"EstimatorConfig: history_frames, obs_dim must be ≥ 1 and latent_dim ≥ 0, got {self}")
        if self.mass and len(self.mass_scale) != self.num_masses:
            raise ValueError(f"EstimatorConfig: mass_scale has {len(self.mass_scale)} values, "
                             f"expected {self.num_masses}")
        object.__setattr__(self, "encoder_hidden_dims", tuple(self.encoder_hidden_dims))
        object.__setattr__(self, "decoder_hidden_dims", tuple(self.decoder_hidden_dims))
        object.__setattr__(self, "mass_scale", tuple(float(s) for s in self.mass_scale))

    @property
    def estimate_dim(self) -> int:
        """Width of the explicit estimates [m̂, ĉ, v̂] (decoder input without z)."""
        return (self.num_masses * self.mass + self.num_contacts * self.contact
                + self.velocity_dim * self.velocity)

    @property
    def feature_dim(self) -> int:
        """Width of what the policy receives from the estimator: [m̂, ĉ, v̂, ẑ]."""
        return self.estimate_dim + self.latent_dim

    @property
    def head_dim(self) -> int:
        """Width of the encoder's raw output: the estimates, μ_z and log σ²_z."""
        return self.estimate_dim + 2 * self.latent_dim

    @property
    def input_dim(self) -> int:
        """Width of the flattened history, H·D."""
        return self.history_frames * self.obs_dim

    @property
    def enabled(self) -> bool:
        """Whether there is anything to estimate (False: no estimator at all)."""
        return self.feature_dim > 0

    def slices(self) -> dict[str, slice]:
        """Column ranges of the enabled heads in the encoder's raw output."""
        out, start = {}, 0
        for name, on, width in (("mass", self.mass, self.num_masses), ("contact", self.contact, self.num_contacts),
                                ("velocity", self.velocity, self.velocity_dim),
                                ("z_mean", self.latent_dim > 0, self.latent_dim),
                                ("z_logvar", self.latent_dim > 0, self.latent_dim)):
            if on:
                out[name] = slice(start, start + width)
                start += width
        return out


@dataclass
class EstimatorOutput:
    """What one estimator pass produces; absent heads are None. N rows each.

    ``mass`` (N, 4) in units of ``mass_scale``; ``contact`` (N, 13) probabilities
    with their ``contact_logits``; ``velocity`` (N, 3) [m/s]; ``z_mean``,
    ``z_logvar``, ``z`` (N, L) (``z`` is the sample in training, the mean
    otherwise); ``recon`` (N, D) the predicted normalised o_{t+1}.
    """

    features: torch.Tensor
    mass: torch.Tensor | None = None
    contact_logits: torch.Tensor | None = None
    contact: torch.Tensor | None = None
    velocity: torch.Tensor | None = None
    z_mean: torch.Tensor | None = None
    z_logvar: torch.Tensor | None = None
    z: torch.Tensor | None = None
    recon: torch.Tensor | None = None


class EncoderHeads(nn.Module):
    """E_φ: normalised history (N, H·D) → raw heads (N, head_dim); exportable on its own."""

    def __init__(self, cfg: EstimatorConfig) -> None:
        super().__init__()
        self.mlp = MLP(cfg.input_dim, cfg.head_dim, cfg.encoder_hidden_dims, cfg.activation)
        mask = torch.zeros(cfg.head_dim, dtype=torch.bool)
        if cfg.contact:
            mask[cfg.slices()["contact"]] = True
        self.register_buffer("sigmoid_mask", mask)
        self.feature_dim = cfg.feature_dim

    def forward(self, history: torch.Tensor) -> torch.Tensor:
        """Raw head outputs (N, head_dim) of a normalised history (N, H·D)."""
        return self.mlp(history)

    def features(self, raw: torch.Tensor) -> torch.Tensor:
        """[m̂, ĉ = σ(logits), v̂, μ_z] (N, feature_dim) from raw heads (N, head_dim)."""
        return torch.where(self.sigmoid_mask, torch.sigmoid(raw), raw)[:, : self.feature_dim]

    def policy_features(self, history: torch.Tensor) -> torch.Tensor:
        """Deterministic policy features (N, feature_dim) of a normalised history (N, H·D)."""
        return self.features(self.forward(history))


class Estimator(nn.Module):
    """The MCP: encoder + heads + (optional) VAE decoder; see the module docstring."""

    def __init__(self, cfg: EstimatorConfig) -> None:
        super().__init__()
        if not cfg.enabled:
            raise ValueError("Estimator: the configuration has no head and no latent; use no estimator instead")
        self.cfg = cfg
        self._slices = cfg.slices()
        self.encoder = EncoderHeads(cfg)
        self.decoder = (MLP(cfg.feature_dim, cfg.obs_dim, cfg.decoder_hidden_dims, cfg.activation)
                        if cfg.latent_dim > 0 else None)
        self.register_buffer("mass_scale", torch.tensor(cfg.mass_scale if cfg.mass else (), dtype=torch.float32))

    def policy_features(self, history: torch.Tensor) -> torch.Tensor:
        """[m̂, ĉ, v̂, μ_z] (N, feature_dim) for the policy, from a normalised history (N, H·D)."""
        return self.encoder.policy_features(history)

    def forward(self, history: torch.Tensor, sample: bool | None = None) -> EstimatorOutput:
        """Every head of a normalised history (N, H·D); ``sample`` defaults to ``self.training``.

        With ``sample`` the decoder sees z = μ + exp(½ log σ²)·ε, ε ~ N(0, I)
        (reparameterisation); otherwise z = μ.
        """
        sample = self.training if sample is None else sample
        raw = self.encoder(history)
        features = self.encoder.features(raw)
        s = self._slices
        out = EstimatorOutput(features=features)
        if "mass" in s:
            out.mass = raw[:, s["mass"]]
        if "contact" in s:
            out.contact_logits = raw[:, s["contact"]]
            out.contact = features[:, s["contact"]]
        if "velocity" in s:
            out.velocity = raw[:, s["velocity"]]
        if self.decoder is not None:
            out.z_mean, out.z_logvar = raw[:, s["z_mean"]], raw[:, s["z_logvar"]]
            out.z = (out.z_mean + torch.exp(0.5 * out.z_logvar) * torch.randn_like(out.z_mean)
                     if sample else out.z_mean)
            estimates = features[:, : self.cfg.estimate_dim]
            out.recon = self.decoder(torch.cat([estimates, out.z], dim=-1))
        return out

    def masses_kg(self, output: EstimatorOutput) -> torch.Tensor:
        """The mass estimate (N, 4) back in kg."""
        return output.mass * self.mass_scale

    def loss(
        self,
        output: EstimatorOutput,
        targets: dict[str, torch.Tensor],
        next_obs: torch.Tensor | None = None,
        next_valid: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        """Weighted total loss (scalar) and its unweighted parts (detached scalars).

        Args:
            output: :meth:`forward` of the batch.
            targets: ``"mass"`` (N, 4) [kg], ``"contact"`` (N, 13) in {0, 1},
                ``"velocity"`` (N, 3) [m/s], as the enabled heads need.
            next_obs: normalised o_{t+1} (N, D); needed when the decoder exists.
            next_valid: (N,) bool, False for pairs that cross an episode end
                (excluded from the reconstruction mean); None = all valid.
        """
        cfg = self.cfg
        parts: dict[str, torch.Tensor] = {}
        total = output.features.new_zeros(())
        if output.mass is not None:
            parts["mass"] = F.mse_loss(output.mass, targets["mass"] / self.mass_scale)
            total = total + cfg.mass_weight * parts["mass"]
        if output.contact_logits is not None:
            parts["contact"] = F.binary_cross_entropy_with_logits(output.contact_logits, targets["contact"].float())
            total = total + cfg.contact_weight * parts["contact"]
        if output.velocity is not None:
            parts["velocity"] = F.mse_loss(output.velocity, targets["velocity"])
            total = total + cfg.velocity_weight * parts["velocity"]
        if output.recon is not None:
            if next_obs is None:
                raise ValueError("Estimator.loss: the decoder needs next_obs (the normalised o_{t+1})")
            per_row = (output.recon - next_obs).pow(2).mean(dim=-1)
            if next_valid is None:
                parts["recon"] = per_row.mean()
            else:
                w = next_valid.float()
                parts["recon"] = (per_row * w).sum() / w.sum().clamp(min=1.0)
            parts["kl"] = kl_to_standard_normal(output.z_mean, output.z_logvar)
            total = total + cfg.recon_weight * parts["recon"] + cfg.kl_weight * parts["kl"]
        return total, {k: v.detach() for k, v in parts.items()}


def kl_to_standard_normal(mean: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(N(μ, diag σ²) ‖ N(0, I)) summed over the last dimension, averaged over rows: a scalar.

    = ½ Σ_k (μ_k² + σ_k² − 1 − log σ_k²).
    """
    return 0.5 * (mean.pow(2) + logvar.exp() - 1.0 - logvar).sum(dim=-1).mean()
