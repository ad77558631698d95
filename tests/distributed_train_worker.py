"""One rank of a tiny multi-process FR-Net run, started by tests/test_distributed_training.py under torchrun.

``python -m torch.distributed.run --standalone --nproc-per-node 2 tests/distributed_train_worker.py OUT ITERATIONS
[--no-estimator-reduce]``: trains ITERATIONS iterations (8 envs per rank, 5-step episodes), resumes the run for
one more, and rank 0 saves every rank's parameter groups to ``OUT/ranks.pt``: a list (one entry per rank) of
{"before", "trained", "resumed": {group: flat float64 tensor}, "masses", "iteration", "env_steps"}.
``--no-estimator-reduce`` leaves the estimator's gradients unreduced (the control that shows the check can fail).
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from frbench.training import algorithm, distributed
from frbench.training.env import TrainEnvConfig
from frbench.training.run import TrainingRun

ENVS, STEPS_PER_ENV = 8, 24


def parameter_groups(run: TrainingRun) -> dict[str, torch.Tensor]:
    """Actor (without estimator and normaliser), estimator, critic and both normalisers, each one flat vector."""
    groups: dict[str, list[torch.Tensor]] = {}
    for model_name, model in (("actor", run.runner.alg.actor), ("critic", run.runner.alg.critic)):
        for key, value in model.state_dict().items():
            if key.startswith("estimator."):
                group = "estimator"
            elif key.startswith("obs_normalizer."):
                group = f"{model_name}_normalizer"
            else:
                group = model_name
            groups.setdefault(group, []).append(value.detach().double().flatten().cpu())
    return {name: torch.cat(parts) for name, parts in groups.items()}


def main(out: Path, iterations: int, reduce_estimator: bool) -> None:
    if not reduce_estimator:
        algorithm.all_reduce_gradients = lambda parameters: None
    world = distributed.ranks().world_size
    cfg = TrainEnvConfig(num_envs=ENVS, episode_steps=5, settle_steps=2, num_morphologies=2, families=("flat", "rough"))
    steps = ENVS * STEPS_PER_ENV * world
    run = TrainingRun(out / "run", "frnet", cfg, total_steps=steps * iterations, checkpoint_every=iterations)
    before = parameter_groups(run)
    run.train(progress_bar=False)
    trained = parameter_groups(run)
    resumed = TrainingRun(out / "run", total_steps=steps * (iterations + 1), resume=True, checkpoint_every=1)
    resumed.train(progress_bar=False)
    record = {"before": before, "trained": trained, "resumed": parameter_groups(resumed),
              "masses": torch.as_tensor(run.env.env_masses), "iteration": resumed.iteration,
              "env_steps": resumed.env_steps}
    every = distributed.gather_objects(record)
    if distributed.ranks().is_main:
        torch.save(every, out / "ranks.pt")


if __name__ == "__main__":
    main(Path(sys.argv[1]), int(sys.argv[2]), "--no-estimator-reduce" not in sys.argv[3:])
