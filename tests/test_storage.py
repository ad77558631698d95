"""`HookedRolloutStorage`: rsl-rl's mini-batches unchanged, the hook after each one."""

import torch
from rsl_rl.storage import RolloutStorage
from tensordict import TensorDict

from frbench.training.storage import HookedRolloutStorage


def _filled(cls, steps: int = 4, envs: int = 6):
    obs = TensorDict({"policy": torch.zeros(envs, 3)}, batch_size=[envs])
    storage = cls("rl", envs, steps, obs, [2])
    generator = torch.Generator().manual_seed(0)
    for _ in range(steps):
        t = RolloutStorage.Transition()
        t.observations = TensorDict({"policy": torch.randn(envs, 3, generator=generator)}, batch_size=[envs])
        t.actions, t.rewards = torch.randn(envs, 2, generator=generator), torch.randn(envs, generator=generator)
        t.dones, t.values = torch.zeros(envs), torch.randn(envs, 1, generator=generator)
        t.actions_log_prob = torch.randn(envs, generator=generator)
        t.distribution_params = (torch.randn(envs, 2, generator=generator), torch.ones(envs, 2))
        storage.add_transition(t)
    return storage


def test_batches_equal_rsl_rl_s_and_the_hook_runs_after_each_is_consumed():
    plain, hooked = _filled(RolloutStorage), _filled(HookedRolloutStorage)
    events = []
    hooked.after_batch = lambda batch: events.append(("hook", float(batch.actions.sum())))
    torch.manual_seed(1)
    reference = [b.observations["policy"].clone() for b in plain.mini_batch_generator(2, 3)]
    torch.manual_seed(1)
    seen = []
    for batch in hooked.mini_batch_generator(2, 3):
        events.append(("use", float(batch.actions.sum())))
        seen.append(batch.observations["policy"].clone())
    assert len(seen) == len(reference) == 6
    assert all(torch.equal(a, b) for a, b in zip(seen, reference))
    assert [kind for kind, _ in events] == ["use", "hook"] * 6
    assert all(events[i][1] == events[i + 1][1] for i in range(0, 12, 2))  # the hook gets the batch just used


def test_like_copies_sizes_groups_and_device():
    source = _filled(RolloutStorage)
    copy = HookedRolloutStorage.like(source)
    assert (copy.num_envs, copy.num_transitions_per_env, list(copy.actions_shape)) == (6, 4, [2])
    assert copy.observations["policy"].shape == (4, 6, 3) and float(copy.observations["policy"].abs().sum()) == 0.0
    assert copy.after_batch is None
