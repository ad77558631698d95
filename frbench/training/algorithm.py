"""Algorithms for rsl-rl's ``OnPolicyRunner``: PPO with a jointly trained estimator, and RMA's phase 2.

* :class:`EstimatorPPO` (``"frbench.training.algorithm:EstimatorPPO"``): rsl-rl's
  PPO, the estimator trained on PPO's own mini-batches: the actor's forward pass
  of each mini-batch runs the encoder once, with gradients, and keeps its
  output; the policy reads the features detached, and after PPO's step on that
  mini-batch the estimator takes one step of its own Adam optimiser on the same
  rows. PPO's optimiser (fused where torch has the kernel) holds every actor/critic parameter *except* the
  estimator's, and the estimator's optimiser only the estimator's: the two
  losses never mix.
* :class:`RMAAdaptation` (``"frbench.training.algorithm:RMAAdaptation"``): RMA
  phase 2 — the phase-1 actor acts with ẑ from its adaptation module, which is
  regressed on z = μ(e_t) over each rollout (supervised, on-policy).

Both run their update with torch on every core (`update_threads`): the
simulator's threads are idle then; the rollout keeps torch at one thread.

Estimator rows, from ``storage.observations`` of shape (T, N, …): input the
history at t; targets the ``mass`` / ``contact`` / ``velocity`` groups at t;
reconstruction target the normalised o_{t+1} = the o_t group of the next
transition (for t = T−1, the observation that ``compute_returns`` received),
added to the storage as the group ``NEXT_OBS_GROUP`` (validity
``NEXT_VALID_GROUP``) for the update, so that PPO's mini-batches carry it.
Pairs with ``storage.dones[t] = 1`` cross an episode end (o_{t+1} is already
the next episode's first frame) and are left out of the reconstruction term.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from itertools import chain

import torch
import torch.nn as nn
from tensordict import TensorDict

from rsl_rl.algorithms import PPO
from rsl_rl.env import VecEnv
from rsl_rl.utils import resolve_class, resolve_obs_groups, resolve_optimizer

from frbench.networks.models import EstimatorActor, RMAActor
from frbench.training.distributed import all_reduce_gradients
from frbench.training.storage import HookedRolloutStorage

#: Estimator head → observation group holding its target (the environment contract).
TARGET_GROUPS = {"mass": "mass", "contact": "contact", "velocity": "velocity"}
#: Groups added to the rollout storage for the update only: normalised o_{t+1} (D) and its validity (1).
NEXT_OBS_GROUP, NEXT_VALID_GROUP = "estimator_next_obs", "estimator_next_valid"


def update_threads() -> int:
    """Torch threads for an update: ``$FRBENCH_UPDATE_THREADS``, else every core — unless the machine is
    oversubscribed (1-minute load average above the core count: other processes hold the cores), then 1.

    Measured on 2 cores at a load of ~15 (other jobs running): a toy-env training test took 115 s with 1
    update thread and did not finish in 10 minutes with 2 (OpenMP threads waiting on descheduled peers).
    """
    given = os.environ.get("FRBENCH_UPDATE_THREADS")
    if given:
        return max(1, int(given))
    cores = max(1, os.cpu_count() or 1)
    return 1 if os.getloadavg()[0] > cores else cores


#: Optimisers with torch's fused kernel on CPU (one kernel per step over every parameter, instead of ~10 small
#: ops per tensor): measured about 0.03 s less per FR-Net update of 0.59 s (256 envs, 2 threads, 6 runs).
FUSED_OPTIMIZERS = ("adam", "adamw")


def make_optimizer(name: str, params, learning_rate: float) -> torch.optim.Optimizer:
    """rsl-rl's optimiser ``name`` over ``params``, with the fused kernel where torch has one (Adam, AdamW)."""
    extra = {"fused": True} if name.lower() in FUSED_OPTIMIZERS else {}
    return resolve_optimizer(name)(list(params), lr=learning_rate, **extra)  # type: ignore[operator]


@contextmanager
def torch_threads(count: int):
    """Run the block with ``torch.set_num_threads(count)``, then restore the previous count."""
    previous = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


class EstimatorPPO(PPO):
    """PPO + the estimator on PPO's mini-batches; see the module docstring.

    Args (beyond PPO's): ``estimator_learning_rate`` (Adam, fixed),
    ``estimator_max_grad_norm``. ``estimator_epochs`` and
    ``estimator_mini_batches`` are PPO's (``num_learning_epochs``,
    ``num_mini_batches``): configurations may name them, with those values only.
    With an actor that has no estimator this is exactly rsl-rl's PPO (its update
    on every core).
    """

    def __init__(
        self,
        actor: EstimatorActor,
        critic: nn.Module,
        storage,
        *,
        estimator_learning_rate: float = 1e-3,
        estimator_epochs: int | None = None,
        estimator_mini_batches: int | None = None,
        estimator_max_grad_norm: float = 1.0,
        learning_rate: float = 1e-3,
        optimizer: str = "adam",
        **ppo_kwargs,
    ) -> None:
        storage = HookedRolloutStorage.like(storage)  # the estimator steps after each of PPO's mini-batches
        super().__init__(actor, critic, storage, learning_rate=learning_rate, optimizer=optimizer, **ppo_kwargs)
        for name, value, ppo_value in (("estimator_epochs", estimator_epochs, self.num_learning_epochs),
                                       ("estimator_mini_batches", estimator_mini_batches, self.num_mini_batches)):
            if value is not None and value != ppo_value:
                raise ValueError(f"{name} = {value}: the estimator trains on PPO's mini-batches, so it must equal "
                                 f"PPO's {ppo_value} (or be left out)")
        self.estimator = getattr(self.get_policy(), "estimator", None)
        self.estimator_max_grad_norm = estimator_max_grad_norm
        self._next_obs: TensorDict | None = None
        self._estimator_sums: dict[str, float] = {}
        self._estimator_steps = 0
        own = {id(p) for p in self.estimator.parameters()} if self.estimator is not None else set()
        rl_params = [p for p in chain(self.actor.parameters(), self.critic.parameters()) if id(p) not in own]
        self.optimizer = make_optimizer(optimizer, rl_params, learning_rate)
        if self.estimator is not None:
            self.estimator_optimizer = make_optimizer("adam", self.estimator.parameters(), estimator_learning_rate)

    def compute_returns(self, obs: TensorDict) -> None:
        """PPO's returns; keeps ``obs`` (o_{T}) as the last reconstruction target."""
        self._next_obs = obs
        super().compute_returns(obs)

    def update(self) -> dict[str, float]:
        """PPO's update with the estimator's steps on its mini-batches, torch on `update_threads` threads;
        losses merged (``estimator``, ``estimator_<part>``: means over the mini-batches)."""
        with torch_threads(update_threads()):
            if self.estimator is None:
                return super().update()
            return self._update_with_estimator()

    def _update_with_estimator(self) -> dict[str, float]:
        actor: EstimatorActor = self.get_policy()  # type: ignore[assignment]
        observations = self.storage.observations
        next_o, valid = self.estimator_targets()
        observations[NEXT_OBS_GROUP], observations[NEXT_VALID_GROUP] = next_o, valid.unsqueeze(-1)
        self._estimator_sums, self._estimator_steps = {}, 0
        self.storage.after_batch = self._estimator_step
        actor.keep_estimator_output = True
        self.estimator.train()
        try:
            loss_dict = super().update()
        finally:
            self.storage.after_batch = None
            actor.keep_estimator_output = False
            actor.estimator_output = None
            for key in (NEXT_OBS_GROUP, NEXT_VALID_GROUP):
                if key in observations.keys():
                    del observations[key]
            self._next_obs = None
        steps = max(self._estimator_steps, 1)
        loss_dict.update({k: v / steps for k, v in self._estimator_sums.items()})
        return loss_dict

    def _estimator_step(self, batch) -> None:
        """One Adam step of the estimator on the output the actor kept from this mini-batch's forward pass."""
        actor: EstimatorActor = self.get_policy()  # type: ignore[assignment]
        out = actor.estimator_output
        if out is None:
            raise RuntimeError("EstimatorPPO: the actor kept no estimator output for this mini-batch")
        obs = batch.observations
        cfg = actor.estimator_cfg
        heads = [h for h, on in (("mass", cfg.mass), ("contact", cfg.contact), ("velocity", cfg.velocity)) if on]
        targets = {h: obs[TARGET_GROUPS[h]].float() for h in heads}
        total, parts = self.estimator.loss(out, targets, obs[NEXT_OBS_GROUP], obs[NEXT_VALID_GROUP].squeeze(-1) > 0.5)
        self.estimator_optimizer.zero_grad()
        total.backward()
        all_reduce_gradients(self.estimator.parameters())  # a multi-process run: the mean over ranks
        nn.utils.clip_grad_norm_(self.estimator.parameters(), self.estimator_max_grad_norm)
        self.estimator_optimizer.step()
        self.estimator_optimizer.zero_grad()  # PPO's gradient clipping over the actor must not see these
        actor.estimator_output = None
        logged = {"estimator": total.detach(), **{f"estimator_{k}": v for k, v in parts.items()}}
        for key, value in logged.items():
            self._estimator_sums[key] = self._estimator_sums.get(key, 0.0) + float(value)
        self._estimator_steps += 1

    def estimator_targets(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised o_{t+1} (T, N, D) for every stored transition and its validity (T, N) as 0/1 floats."""
        actor: EstimatorActor = self.get_policy()  # type: ignore[assignment]
        obs, dones = self.storage.observations, self.storage.dones.squeeze(-1).bool()  # (T, N, ...), (T, N)
        o_group = actor.obs_groups[0]
        with torch.no_grad():
            o = obs[o_group]
            valid = ~dones
            if self._next_obs is not None:
                last = self._next_obs[o_group].to(o.device).clone().unsqueeze(0)
            else:  # no o_T known: drop the last step from the reconstruction
                last = o[-1:].clone()
                valid = valid.clone()
                valid[-1] = False
            next_o = actor.normalize_obs(torch.cat([o[1:], last], dim=0))
        return next_o, valid.float()

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
        self.optimizer = make_optimizer("adam", self.actor.adaptation.parameters(), learning_rate)
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
        """Regress φ on the rollout (torch on `update_threads` threads); returns ``{"adaptation": mean MSE}``."""
        with torch_threads(update_threads()):
            return self._regress()

    def _regress(self) -> dict[str, float]:
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
