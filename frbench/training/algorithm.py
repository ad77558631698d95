"""Algorithms for rsl-rl's ``OnPolicyRunner``: PPO with a jointly trained estimator, and RMA's phase 2.

* :class:`EstimatorPPO` (``"frbench.training.algorithm:EstimatorPPO"``): rsl-rl's
  PPO, then the estimator's own epochs over the same rollout with its own Adam
  optimiser. PPO's optimiser holds every actor/critic parameter *except* the
  estimator's, and the estimator's optimiser only the estimator's: the two
  losses never mix (the policy reads the estimates detached).
* :class:`RMAAdaptation` (``"frbench.training.algorithm:RMAAdaptation"``): RMA
  phase 2 — the phase-1 actor acts with ẑ from its adaptation module, which is
  regressed on z = μ(e_t) over each rollout (supervised, on-policy).

Estimator batches, from ``storage.observations`` of shape (T, N, …):
input the history at t; targets the ``mass`` / ``contact`` / ``velocity`` groups
at t; reconstruction target the normalised o_{t+1} = the o_t group of the next
transition (for t = T−1, the observation that ``compute_returns`` received).
Pairs with ``storage.dones[t] = 1`` cross an episode end (o_{t+1} is already
the next episode's first frame) and are left out of the reconstruction term.
"""

from __future__ import annotations

from itertools import chain

import torch
import torch.nn as nn
from tensordict import TensorDict

from rsl_rl.algorithms import PPO
from rsl_rl.env import VecEnv
from rsl_rl.utils import resolve_class, resolve_obs_groups, resolve_optimizer

from frbench.training.distributed import all_reduce_gradients
from frbench.training.models import EstimatorActor, RMAActor

#: Estimator head → observation group holding its target (the environment contract).
TARGET_GROUPS = {"mass": "mass", "contact": "contact", "velocity": "velocity"}


class EstimatorPPO(PPO):
    """PPO + the estimator's supervised epochs; see the module docstring.

    Args (beyond PPO's): ``estimator_learning_rate`` (Adam, fixed),
    ``estimator_epochs`` and ``estimator_mini_batches`` (passes over the
    rollout, default as PPO's 5 × 4), ``estimator_max_grad_norm``.
    With an actor that has no estimator this is exactly rsl-rl's PPO.
    """

    def __init__(
        self,
        actor: EstimatorActor,
        critic: nn.Module,
        storage,
        *,
        estimator_learning_rate: float = 1e-3,
        estimator_epochs: int = 5,
        estimator_mini_batches: int = 4,
        estimator_max_grad_norm: float = 1.0,
        learning_rate: float = 1e-3,
        optimizer: str = "adam",
        **ppo_kwargs,
    ) -> None:
        super().__init__(actor, critic, storage, learning_rate=learning_rate, optimizer=optimizer, **ppo_kwargs)
        self.estimator = getattr(self._raw_actor, "estimator", None)
        self.estimator_epochs = estimator_epochs
        self.estimator_mini_batches = estimator_mini_batches
        self.estimator_max_grad_norm = estimator_max_grad_norm
        self._next_obs: TensorDict | None = None
        if self.estimator is not None:
            own = {id(p) for p in self.estimator.parameters()}
            rl_params = [p for p in chain(self.actor.parameters(), self.critic.parameters()) if id(p) not in own]
            self.optimizer = resolve_optimizer(optimizer)(rl_params, lr=learning_rate)  # type: ignore[operator]
            self.estimator_optimizer = torch.optim.Adam(self.estimator.parameters(), lr=estimator_learning_rate)

    def compute_returns(self, obs: TensorDict) -> None:
        """PPO's returns; keeps ``obs`` (o_{T}) as the last reconstruction target."""
        self._next_obs = obs
        super().compute_returns(obs)

    def update(self) -> dict[str, float]:
        """PPO's update, then the estimator's; losses merged (``estimator``, ``estimator_<part>``)."""
        loss_dict = super().update()
        if self.estimator is not None:
            loss_dict.update(self.update_estimator())
        self._next_obs = None
        return loss_dict

    def estimator_batch(self) -> tuple[torch.Tensor, dict[str, torch.Tensor], torch.Tensor, torch.Tensor]:
        """The whole rollout as estimator data, flattened to T·N rows.

        Returns normalised histories (T·N, H·D), targets {head: (T·N, k)},
        normalised next observations (T·N, D) and their validity (T·N,) bool.
        """
        actor: EstimatorActor = self._raw_actor  # type: ignore[assignment]
        obs, dones = self.storage.observations, self.storage.dones.squeeze(-1).bool()  # (T, N, ...), (T, N)
        o_group, h_group = actor.obs_groups[0], actor.obs_groups[1]
        with torch.no_grad():
            o = obs[o_group]
            valid = ~dones
            if self._next_obs is not None:
                last = self._next_obs[o_group].to(o.device).clone().unsqueeze(0)
            else:  # no o_T known: drop the last step from the reconstruction
                last = o[-1:].clone()
                valid = valid.clone()
                valid[-1] = False
            next_o = actor.normalize_obs(torch.cat([o[1:], last], dim=0)).flatten(0, 1)
            history = actor.normalize_history(obs[h_group].flatten(0, 1))
            cfg = actor.estimator_cfg
            heads = [h for h, on in (("mass", cfg.mass), ("contact", cfg.contact), ("velocity", cfg.velocity)) if on]
            targets = {h: obs[TARGET_GROUPS[h]].flatten(0, 1).float() for h in heads}
        return history, targets, next_o, valid.flatten()

    def update_estimator(self) -> dict[str, float]:
        """Run the estimator's epochs over the rollout; mean losses as ``estimator`` and ``estimator_<part>``."""
        history, targets, next_o, valid = self.estimator_batch()
        rows = history.shape[0]
        size = rows // self.estimator_mini_batches
        sums: dict[str, float] = {}
        count = 0
        self.estimator.train()
        for _ in range(self.estimator_epochs):
            order = torch.randperm(rows, device=history.device)
            for i in range(self.estimator_mini_batches):
                idx = order[i * size:(i + 1) * size]
                out = self.estimator(history[idx], sample=True)
                batch_targets = {k: v[idx] for k, v in targets.items()}
                total, parts = self.estimator.loss(out, batch_targets, next_o[idx], valid[idx])
                self.estimator_optimizer.zero_grad()
                total.backward()
                all_reduce_gradients(self.estimator.parameters())  # a multi-process run: the mean over ranks
                nn.utils.clip_grad_norm_(self.estimator.parameters(), self.estimator_max_grad_norm)
                self.estimator_optimizer.step()
                logged = {"estimator": total.detach(), **{f"estimator_{k}": v for k, v in parts.items()}}
                for key, value in logged.items():
                    sums[key] = sums.get(key, 0.0) + float(value)
                count += 1
        return {k: v / count for k, v in sums.items()}

    def save(self) -> dict:
        """PPO's dict plus ``estimator_optimizer_state_dict`` (the estimator's weights are in the actor's)."""
        saved = super().save()
        if self.estimator is not None:
            saved["estimator_optimizer_state_dict"] = self.estimator_optimizer.state_dict()
        return saved

    def load(self, loaded_dict: dict, load_cfg: dict | None, strict: bool) -> bool:
        """PPO's load; the estimator optimiser follows ``load_cfg["optimizer"]`` (all when None)."""
        load_iteration = super().load(loaded_dict, load_cfg, strict)
        wants_optimizer = load_cfg is None or load_cfg.get("optimizer")
        if self.estimator is not None and wants_optimizer and "estimator_optimizer_state_dict" in loaded_dict:
            self.estimator_optimizer.load_state_dict(loaded_dict["estimator_optimizer_state_dict"])
        return load_iteration


class RMAAdaptation:
    """RMA phase 2: the adaptation module φ regresses z = μ(e_t) while the phase-1 policy acts with ẑ = φ(·).

    Used through ``OnPolicyRunner`` like PPO (``algorithm.class_name =
    "frbench.training.algorithm:RMAAdaptation"``; the actor an :class:`RMAActor`
    with groups ``[o_t, extrinsics, long history]``). The runner must first
    ``load`` a phase-1 checkpoint (PPO's ``actor_state_dict``): π, μ and the
    normalisers are then frozen (their statistics are not updated); only φ's
    parameters are in the optimiser. Each iteration: a rollout of
    ``num_steps_per_env`` steps acting with ẑ (the policy mean by default,
    ``act_stochastic`` for sampled actions), then ``num_learning_epochs`` ×
    ``num_mini_batches`` Adam steps on MSE(φ(history), μ(e)). No critic, no returns.
    """

    def __init__(
        self,
        actor: RMAActor,
        num_envs: int,
        num_steps_per_env: int,
        obs: TensorDict,
        learning_rate: float = 1e-3,
        num_learning_epochs: int = 4,
        num_mini_batches: int = 4,
        max_grad_norm: float = 1.0,
        act_stochastic: bool = False,
        device: str = "cpu",
        **_unused,
    ) -> None:
        if actor.adaptation is None:
            raise ValueError("RMAAdaptation: the actor has no adaptation module (add the long-history group)")
        self.device = device
        self.actor = actor.to(device)
        self.actor.use_adaptation = True
        self.learning_rate = learning_rate
        self.num_learning_epochs = num_learning_epochs
        self.num_mini_batches = num_mini_batches
        self.max_grad_norm = max_grad_norm
        self.act_stochastic = act_stochastic
        self.optimizer = torch.optim.Adam(self.actor.adaptation.parameters(), lr=learning_rate)
        self.rnd = None
        groups = actor.obs_groups[1:]  # extrinsics, long history
        self.buffer = TensorDict(
            {g: torch.zeros(num_steps_per_env, *obs[g].shape, dtype=obs[g].dtype, device=device) for g in groups},
            batch_size=[num_steps_per_env, num_envs], device=device,
        )
        self.step = 0
        self.teacher_loaded = False

    # --- runner interface ---
    def act(self, obs: TensorDict) -> torch.Tensor:
        """Actions (N, A) with ẑ = φ(long history); records the rollout's regression data."""
        actions = self.actor(obs, stochastic_output=True)
        if not self.act_stochastic:
            actions = self.actor.output_mean
        for g in self.buffer.keys():
            self.buffer[g][self.step].copy_(obs[g])
        return actions.detach()

    def process_env_step(self, obs: TensorDict, rewards: torch.Tensor, dones: torch.Tensor, extras: dict) -> None:
        """Advance the buffer cursor."""
        self.step += 1

    def compute_returns(self, obs: TensorDict) -> None:
        """No returns in supervised adaptation."""

    def update(self) -> dict[str, float]:
        """Regress φ on the rollout; returns ``{"adaptation": mean MSE}``."""
        data = self.buffer[: self.step].flatten(0, 1)
        self.step = 0
        with torch.no_grad():
            target = self.actor.extrinsics_latent(data)
        rows = target.shape[0]
        size = rows // self.num_mini_batches
        total, count = 0.0, 0
        for _ in range(self.num_learning_epochs):
            order = torch.randperm(rows, device=target.device)
            for i in range(self.num_mini_batches):
                idx = order[i * size:(i + 1) * size]
                loss = nn.functional.mse_loss(self.actor.adaptation_latent(data[idx]), target[idx])
                self.optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(self.actor.adaptation.parameters(), self.max_grad_norm)
                self.optimizer.step()
                total += loss.item()
                count += 1
        return {"adaptation": total / count}

    def train_mode(self) -> None:
        self.actor.train()

    def eval_mode(self) -> None:
        self.actor.eval()

    def get_policy(self) -> RMAActor:
        return self.actor

    def save(self) -> dict:
        """``actor_state_dict`` (with φ) and ``adaptation_optimizer_state_dict``."""
        return {"actor_state_dict": self.actor.state_dict(),
                "adaptation_optimizer_state_dict": self.optimizer.state_dict()}

    def load(self, loaded_dict: dict, load_cfg: dict | None, strict: bool) -> bool:
        """Load a phase-2 checkpoint, or a phase-1 (PPO) one whose actor lacks only ``adaptation.*``."""
        if "adaptation_optimizer_state_dict" in loaded_dict:
            self.actor.load_state_dict(loaded_dict["actor_state_dict"], strict=strict)
            self.optimizer.load_state_dict(loaded_dict["adaptation_optimizer_state_dict"])
            self.teacher_loaded = True
            return load_cfg is None or bool(load_cfg.get("iteration", False))
        result = self.actor.load_state_dict(loaded_dict["actor_state_dict"], strict=False)
        missing = [k for k in result.missing_keys if not k.startswith("adaptation.")]
        if missing or result.unexpected_keys:
            raise RuntimeError(f"RMAAdaptation: phase-1 checkpoint does not fit the actor (missing {missing}, "
                               f"unexpected {result.unexpected_keys})")
        self.teacher_loaded = True
        return False

    @staticmethod
    def construct_algorithm(obs: TensorDict, env: VecEnv, cfg: dict, device: str) -> RMAAdaptation:
        """Build the phase-2 actor (``use_adaptation=True``) and the algorithm from a runner config."""
        alg_class, alg_cfg = resolve_class(cfg["algorithm"])
        actor_class, actor_cfg = resolve_class(cfg["actor"])
        cfg["obs_groups"] = resolve_obs_groups(obs, cfg["obs_groups"], ["actor"])
        actor_cfg["use_adaptation"] = True
        actor = actor_class(obs, cfg["obs_groups"], "actor", env.num_actions, **actor_cfg).to(device)
        return alg_class(actor, env.num_envs, cfg["num_steps_per_env"], obs, device=device, **alg_cfg)
