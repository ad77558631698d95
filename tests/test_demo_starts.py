"""Starting states along a scripted getting-up motion (frbench.training.demo_starts)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from frbench.tasks.observations import projected_gravity
from frbench.training.demo_starts import assist_probability
from frbench.training.env import RecoveryTrainingEnv, TrainEnvConfig


def test_the_demo_fraction_falls_linearly_to_zero():
    assert assist_probability(0.5, 8e6, 0) == 0.5
    assert assist_probability(0.5, 8e6, 4e6) == pytest.approx(0.25)
    assert assist_probability(0.5, 8e6, 8e6) == 0.0
    assert assist_probability(0.5, 8e6, 20e6) == 0.0
    assert assist_probability(0.0, 8e6, 0) == 0.0
    assert assist_probability(0.5, 0.0, 0) == 0.0  # no horizon: off


@pytest.fixture(scope="module")
def demo_env():
    torch.set_num_threads(1)
    cfg = TrainEnvConfig(num_envs=6, robot="go2", randomize=False, families=("flat",), episode_steps=4,
                         settle_steps=25, demo_start_fraction=1.0, demo_start_until=1e9, demo_steps=200,
                         demo_stride=20)
    environment = RecoveryTrainingEnv(cfg)
    yield environment
    environment.close()


def test_the_bank_holds_a_scripted_getting_up(demo_env):
    bank = demo_env.starts.demo.bank
    assert len(bank.states) == 10 and bank.targets.shape == (10, 6, 12)
    assert bank.valid.all()
    upright_first = projected_gravity(bank.states[0].base_quat)[:, 2] < -0.9
    upright_last = projected_gravity(bank.states[-1].base_quat)[:, 2] < -0.9
    # scripted gets Go2 up on flat ground from every start (100 % in the evaluation): after 4 s all stand
    assert upright_last.sum() == 6 and upright_first.sum() < 6
    heights = bank.states[-1].base_pos[:, 2]
    assert np.all(heights > 0.75 * demo_env.spec.nominal_height)


def test_sampled_starts_are_recorded_states(demo_env):
    bank = demo_env.starts.demo.bank
    state, targets, tiles = bank.sample(np.array([1, 4]), np.random.default_rng(3))
    times = np.random.default_rng(3).integers(0, len(bank.states), size=2)
    for row, (t, i) in enumerate(zip(times, (1, 4))):
        np.testing.assert_array_equal(state.q[row], bank.states[t].q[i])
        np.testing.assert_array_equal(state.qd[row], bank.states[t].qd[i])
        np.testing.assert_array_equal(targets[row], bank.targets[t, i])
    np.testing.assert_array_equal(tiles, bank.tile_row[[1, 4]])


def test_demo_episodes_start_from_the_bank_and_do_not_move_the_curriculum(demo_env):
    assert demo_env.starts.from_demo.all()
    levels = demo_env.curriculum.level.copy()
    for _ in range(4):
        _, _, done, extras = demo_env.step(torch.zeros(6, 12))
    assert done.all()
    np.testing.assert_array_equal(demo_env.curriculum.level, levels)
    stats = demo_env.last_episode_stats
    assert stats["demo_start_share"] == 1.0 and "success_demo_starts" in stats
    assert stats["success_all"] == 0.0  # no fallen start this episode: the fallen-start rate is empty, not inflated
