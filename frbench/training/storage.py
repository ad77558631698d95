"""rsl-rl's rollout storage with a hook after each feed-forward mini-batch.

`HookedRolloutStorage` is rsl-rl's public `RolloutStorage` whose ``mini_batch_generator`` hands every
mini-batch to ``after_batch`` once its consumer (PPO's update) has taken its step on it and asks for the
next one. `frbench.training.algorithm.EstimatorPPO` trains the estimator there, on PPO's own mini-batches.
"""

from __future__ import annotations

from typing import Callable, Generator

from rsl_rl.storage import RolloutStorage


class HookedRolloutStorage(RolloutStorage):
    """`RolloutStorage` (same arguments) with ``after_batch(batch)``, None by default (rsl-rl's generator as is)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.after_batch: Callable[[RolloutStorage.Batch], None] | None = None

    @classmethod
    def like(cls, storage: RolloutStorage) -> "HookedRolloutStorage":
        """An empty storage of ``storage``'s type, sizes, observation groups and device."""
        return cls(storage.training_type, storage.num_envs, storage.num_transitions_per_env,
                   storage.observations[0], storage.actions_shape, storage.device)

    def mini_batch_generator(self, num_mini_batches: int,
                             num_epochs: int = 8) -> Generator[RolloutStorage.Batch, None, None]:
        """rsl-rl's shuffled mini-batches; after the consumer is done with each, ``after_batch`` on it."""
        for batch in super().mini_batch_generator(num_mini_batches, num_epochs):
            yield batch
            if self.after_batch is not None:
                self.after_batch(batch)
