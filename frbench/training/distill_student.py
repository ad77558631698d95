"""The distilled student: an rsl-rl MLP actor on the ``policy`` and ``history`` groups, its training and checkpoint.

The actor (``student`` "mse", the default) is `rsl_rl.models.MLPModel` (deterministic output, observation
normalisation), the actor of frbench's ``ppo`` method, trained by MSE. With ``student`` "mdn" it is
`frbench.networks.mixture.MixtureDensityModel` (``components`` Gaussians over the action vector, trained
by its likelihood, `MixtureDensityModel.loss`; it acts with the mean of its most probable component). Either way the
checkpoint it is saved in (method ``mpc-distill``, format ``frbench-policy-v1``) loads as a
`frbench.policies.learned.LearnedPolicy`: joint targets q* = q̊ + a with action scale 1, every control step.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from frbench.io import atomic_write_bytes, atomic_write_text
from frbench.policies.checkpoint import CHECKPOINT_FORMAT
from frbench.robot_checks.lookup import get_robot

#: The checkpoint's training method (its loader: `frbench.policies.learned.load_learned_policy`).
METHOD = "mpc-distill"
GROUPS = ["policy", "history"]
#: The student kinds (``DistillConfig.student``) and their actor classes.
STUDENTS = {"mse": "rsl_rl.models:MLPModel", "mdn": "frbench.networks.mixture:MixtureDensityModel"}


def actor_config(hidden, student: str = "mse", components: int = 5) -> dict:
    """The rsl-rl actor config stored in the checkpoint (``train_cfg.actor``)."""
    config = {"class_name": STUDENTS[student], "hidden_dims": list(hidden), "activation": "elu",
              "obs_normalization": True}
    if student == "mdn":
        config["components"] = int(components)
    return config


def _new_actor(frame: int, frames: int, num_actions: int, config: dict):
    """A new actor from an ``actor_config`` dict, for o_t of ``frame`` values and ``frames`` history frames."""
    import torch
    from rsl_rl.utils import resolve_callable
    from tensordict import TensorDict

    dummy = TensorDict({"policy": torch.zeros(1, frame), "history": torch.zeros(1, frames * frame)}, batch_size=[1])
    config = dict(config)
    actor_class = resolve_callable(config.pop("class_name"))
    return actor_class(dummy, {"actor": GROUPS}, "actor", num_actions, **config)


def build_actor(data: dict):
    """The actor (eval mode) of a ``mpc-distill`` checkpoint dict."""
    config = json.loads(data["config_json"])
    frames, num_actions = int(data["history"]), int(data["num_actions"])
    actor = _new_actor(6 + 3 * num_actions, frames, num_actions, config["train_cfg"]["actor"])
    actor.load_state_dict(data["actor_state_dict"])
    return actor.eval()


def _inputs(o_t: np.ndarray, history: np.ndarray):
    import torch
    from tensordict import TensorDict

    return TensorDict({"policy": torch.as_tensor(o_t, dtype=torch.float32),
                       "history": torch.as_tensor(history, dtype=torch.float32)}, batch_size=[len(o_t)])


def student_actions(actor, o_t: np.ndarray, history: np.ndarray) -> np.ndarray:
    """Actions a (N, J) = q* − q̊ [rad] of the actor for o_t (N, F) and history (N, H·F)."""
    import torch

    with torch.inference_mode():
        return actor(_inputs(o_t, history)).numpy().astype(np.float64)


#: Spread [rad] the normaliser gives the previous-action inputs of a student blind to them: they normalise to ~0.
BLIND_SPREAD = 1e6


def _blind_previous_action(normalizer, frame: int, num_actions: int) -> None:
    """Make the normaliser map every a_{t−1} input (the last ``num_actions`` of each ``frame``-wide o_t) to ~0:
    the student cannot copy its previous action (the teacher's, in the data: copying it is imitation's
    classic shortcut, which fails once the student's own actions come back)."""
    import torch

    columns = torch.arange(normalizer._mean.shape[-1]) % frame >= frame - num_actions
    normalizer._mean[:, columns] = 0.0
    normalizer._var[:, columns] = BLIND_SPREAD ** 2
    normalizer._std[:, columns] = BLIND_SPREAD


def train_student(obs: np.ndarray, history: np.ndarray, actions: np.ndarray, config, round_index: int):
    """A new actor fitted to (obs (M, F), history (M, H·F)) → teacher actions (M, J) [rad] with AdamW: by MSE
    (``config.student`` "mse") or by the mixture's negative log-likelihood ("mdn");
    ``config.epochs`` passes in minibatches of ``config.minibatch``, seeded by (``config.seed``, round).
    The normaliser takes the whole dataset's mean and spread; each minibatch's inputs get Gaussian noise of
    ``config.input_noise`` × that spread (a regulariser against the student's own drift), and AdamW decays the
    weights by ``config.weight_decay``. Returns (actor, last epoch's mean loss: MSE [rad²] or the mixture's
    objective, `MixtureDensityModel.loss`)."""
    import torch

    torch.set_num_threads(1)  # small minibatches: one thread is fastest, and fair to a shared machine
    torch.manual_seed(config.seed * 1000 + round_index)
    generator = torch.Generator().manual_seed(config.seed * 1000 + round_index)
    mixture = config.student == "mdn"
    actor = _new_actor(obs.shape[1], config.frames, actions.shape[1],
                       actor_config(config.hidden, config.student, config.components))
    inputs = _inputs(obs, history)
    targets = torch.as_tensor(actions, dtype=torch.float32)
    actor.obs_normalizer.update(torch.cat([inputs["policy"], inputs["history"]], dim=-1))
    spread = actor.obs_normalizer.std * config.input_noise
    if config.blind_to_previous_action:
        _blind_previous_action(actor.obs_normalizer, obs.shape[1], actions.shape[1])
    actor.eval()  # the normaliser keeps the dataset's statistics
    width = inputs["policy"].shape[1]
    optimizer = torch.optim.AdamW(actor.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay)
    loss_sum = 0.0
    for _ in range(config.epochs):
        order = torch.randperm(len(obs), generator=generator)
        loss_sum = 0.0
        for start in range(0, len(obs), config.minibatch):
            index = order[start:start + config.minibatch]
            batch = inputs[index].clone()
            if config.input_noise > 0:
                noise = torch.randn(len(index), len(spread), generator=generator) * spread
                batch["policy"] = batch["policy"] + noise[:, :width]
                batch["history"] = batch["history"] + noise[:, width:]
            if mixture:
                loss = actor.loss(batch, targets[index])
            else:
                loss = torch.nn.functional.mse_loss(actor(batch), targets[index])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            loss_sum += float(loss.detach()) * len(index)
    return actor.eval(), loss_sum / len(obs)


def mixture_fit(actor, obs: np.ndarray, history: np.ndarray, actions: np.ndarray) -> dict:
    """A mixture student's fit to the actions (M, J): ``nll`` [nats per sample] and ``mse`` [rad²] of the
    actions it takes (its most probable component's mean)."""
    import torch

    inputs, targets = _inputs(obs, history), torch.as_tensor(actions, dtype=torch.float32)
    with torch.inference_mode():
        return {"nll": float(actor.nll(inputs, targets)), "mse": float((actor(inputs) - targets).square().mean())}


def save_student(path: Path, actor, config, round_index: int, dataset: dict) -> None:
    """Save the student as a frbench policy checkpoint at ``path`` plus its ``.config.json`` sidecar.

    ``dataset``: episodes, samples and cpu_s (the teacher's CPU seconds) it was trained on."""
    import io

    import torch

    spec = get_robot(config.robot)
    record = {"method": METHOD,
              "env": {"robot": config.robot, "backend": "+".join(config.simulators), "history": config.frames,
                      "action_scale": 1.0, "action_hold": 1, "base_controller": None},
              "train_cfg": {"obs_groups": {"actor": GROUPS},
                           "actor": actor_config(config.hidden, config.student, config.components)},
              "distill": {**config.as_dict(), "round": round_index, "dataset": dataset}}
    kind = f"a {config.components}-component mixture-density MLP" if config.student == "mdn" else "an MLP"
    description = (f"{METHOD}: {kind} on proprioception (history {config.frames}) distilled from {config.teacher} "
                   f"by DAgger ({round_index + 1} rounds, round 0 behaviour cloning) on {dataset['episodes']} "
                   f"{config.robot} {config.terrain} level-{config.level} episodes ({dataset['samples']} samples, "
                   f"{dataset['cpu_s'] / 60:.0f} teacher CPU min) in {' and '.join(config.simulators)}")
    data = {"format": CHECKPOINT_FORMAT, "method": METHOD, "config_json": json.dumps(record, sort_keys=True),
            "actor_state_dict": dict(actor.state_dict()), "action_scale": 1.0, "history": config.frames,
            "num_actions": spec.n_joints, "robot_kind": spec.kind, "env_steps": dataset["samples"],
            "wall_s": None, "description": description}
    buffer = io.BytesIO()
    torch.save(data, buffer)  # a plain dict of tensors: `frbench policies` reads it without torch
    atomic_write_bytes(path, buffer.getvalue())
    atomic_write_text(Path(path).with_suffix(".config.json"), json.dumps(record, indent=1, sort_keys=True) + "\n")
