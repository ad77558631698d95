"""Training methods as rsl-rl configurations: FR-Net, its ablations and the paper's baselines.

Every method is PPO with the same actor/critic sizes and PPO settings (the
notes' first data point: MLPs 256-128-128 ELU, lr 1e-3 adaptive with KL
target 0.01, 5 epochs × 4 mini-batches, entropy 0.005, γ 0.99, λ 0.95, 24
steps per env); they differ only in what the actor sees:

==================  ===============================  ===========================  ===========
method              actor obs groups                 estimator heads              actor input
==================  ===============================  ===========================  ===========
frnet               policy, history                  mass 4, contact 13, z 16     75
frnet-no-mass       policy, history                  contact 13, z 16             71
frnet-no-contact    policy, history                  mass 4, z 16                 62
frnet-no-est        policy, history                  mass 4, contact 13 (no VAE)  59
dreamriser          policy, history                  velocity 3, z 16             61
rma                 policy, extrinsics               (encoder μ(e) → z 8)         50
ppo                 policy                           —                            42
==================  ===============================  ===========================  ===========

All critics see ``["privileged"]`` (277). ``rma`` is RMA's phase 1; phase 2
is :func:`make_rma_adaptation_cfg` (see :class:`frbench.training.algorithm.RMAAdaptation`).
"""

from __future__ import annotations

import copy

from frbench.errors import unknown_name

ACTOR_HIDDEN = [256, 128, 128]
CRITIC_HIDDEN = [256, 128, 128]
ESTIMATOR_HIDDEN = [256, 128]

PPO_SETTINGS = {
    "learning_rate": 1e-3,
    "schedule": "adaptive",
    "desired_kl": 0.01,
    "num_learning_epochs": 5,
    "num_mini_batches": 4,
    "entropy_coef": 0.005,
    "gamma": 0.99,
    "lam": 0.95,
    "clip_param": 0.2,
    "value_loss_coef": 1.0,
    "max_grad_norm": 1.0,
    "use_clipped_value_loss": True,
}
ESTIMATOR_SETTINGS = {
    "estimator_learning_rate": 1e-3,
    "estimator_epochs": 5,
    "estimator_mini_batches": 4,
    "estimator_max_grad_norm": 1.0,
}
#: Initial action noise 0.5 with the paper's action scale 1 (q* = q̊ + a): the same 0.5 rad of joint-space
#: exploration as legged_gym's scale 0.5 × std 1, which a first run at std 1 × scale 1 showed to be too much
#: (1.5 M steps: target-posture reward 0.0003, joints pressed into their limits; docs/training.md).
DISTRIBUTION = {"class_name": "GaussianDistribution", "init_std": 0.5, "std_type": "scalar"}
CRITIC = {"class_name": "rsl_rl.models:MLPModel", "hidden_dims": CRITIC_HIDDEN, "activation": "elu",
          "obs_normalization": True}


def _estimator_method(**heads) -> dict:
    estimator = {"mass": False, "contact": False, "velocity": False, "latent_dim": 16,
                 "encoder_hidden_dims": ESTIMATOR_HIDDEN, **heads}
    return {
        "obs_groups": {"actor": ["policy", "history"], "critic": ["privileged"]},
        "actor": {"class_name": "frbench.networks.models:EstimatorActor", "hidden_dims": ACTOR_HIDDEN,
                  "activation": "elu", "obs_normalization": True, "distribution_cfg": DISTRIBUTION,
                  "estimator": estimator},
        "critic": CRITIC,
        "algorithm": {"class_name": "frbench.training.algorithm:EstimatorPPO", **PPO_SETTINGS, **ESTIMATOR_SETTINGS},
    }


#: Method name → the method-specific part of an rsl-rl train config (copied by :func:`make_train_cfg`).
METHODS: dict[str, dict] = {
    "frnet": _estimator_method(mass=True, contact=True),
    "frnet-no-mass": _estimator_method(contact=True),
    "frnet-no-contact": _estimator_method(mass=True),
    "frnet-no-est": _estimator_method(mass=True, contact=True, latent_dim=0),
    "dreamriser": _estimator_method(velocity=True),
    "rma": {
        "obs_groups": {"actor": ["policy", "extrinsics"], "critic": ["privileged"]},
        "actor": {"class_name": "frbench.networks.models:RMAActor", "hidden_dims": ACTOR_HIDDEN, "activation": "elu",
                  "obs_normalization": True, "distribution_cfg": DISTRIBUTION, "z_dim": 8,
                  "encoder_hidden_dims": [256, 128], "adaptation_frames": 50},
        "critic": CRITIC,
        "algorithm": {"class_name": "rsl_rl.algorithms:PPO", **PPO_SETTINGS},
    },
    "ppo": {
        "obs_groups": {"actor": ["policy"], "critic": ["privileged"]},
        "actor": {"class_name": "rsl_rl.models:MLPModel", "hidden_dims": ACTOR_HIDDEN, "activation": "elu",
                  "obs_normalization": True, "distribution_cfg": DISTRIBUTION},
        "critic": CRITIC,
        "algorithm": {"class_name": "rsl_rl.algorithms:PPO", **PPO_SETTINGS},
    },
}

#: Runner settings shared by every method.
RUNNER_DEFAULTS = {
    "num_steps_per_env": 24,
    "save_interval": 50,
    "check_for_nan": True,
    "logger": "tensorboard",
}


def deep_merge(base: dict, overrides: dict | None) -> dict:
    """A copy of ``base`` with ``overrides`` applied: nested dicts merge, other values replace."""
    out = copy.deepcopy(base)
    for key, value in (overrides or {}).items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def make_train_cfg(method: str, overrides: dict | None = None) -> dict:
    """A full rsl-rl train config for ``method`` (a fresh dict; ``overrides`` merged in deeply).

    Keys: num_steps_per_env, save_interval, check_for_nan, logger, run_name,
    obs_groups, actor, critic, algorithm.
    """
    if method not in METHODS:
        raise unknown_name("training method", method, METHODS)
    cfg = deep_merge({**RUNNER_DEFAULTS, "run_name": method}, METHODS[method])
    return deep_merge(cfg, overrides)


def make_rma_adaptation_cfg(overrides: dict | None = None) -> dict:
    """RMA phase 2 train config: :class:`RMAAdaptation` with a phase-2 :class:`RMAActor`.

    Needs the env's ``"long_history"`` group (N, 50·D) besides ``policy`` and
    ``extrinsics``; load the phase-1 checkpoint with ``runner.load`` before ``learn``.
    """
    phase1 = METHODS["rma"]
    cfg = {
        **RUNNER_DEFAULTS,
        "run_name": "rma-adaptation",
        "obs_groups": {"actor": ["policy", "extrinsics", "long_history"]},
        "actor": {**phase1["actor"], "use_adaptation": True},
        "algorithm": {"class_name": "frbench.training.algorithm:RMAAdaptation", "learning_rate": 1e-3,
                      "num_learning_epochs": 4, "num_mini_batches": 4, "max_grad_norm": 1.0,
                      "act_stochastic": False},
    }
    return deep_merge(cfg, overrides)
