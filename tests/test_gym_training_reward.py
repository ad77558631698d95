"""The Gymnasium env's ``reward="training"`` is the trainer's reward, term by term (one `StepReward`)."""

import numpy as np
import pytest
import torch

from frbench.gym import FallRecoveryVectorEnv
from frbench.training.config import TrainEnvConfig
from frbench.training.env import RecoveryTrainingEnv


def _same_start(gym_env, train_env) -> None:
    """Both envs restart from the gym's settled fallen starts, placed on the training env's flat tiles."""
    start = gym_env.core.state.copy()
    rows = np.arange(gym_env.num_envs)
    offsets = np.array([train_env.grid.offsets[(int(f), int(level))]
                        for f, level in zip(train_env.curriculum.family, train_env.curriculum.level)])
    gym_env.core.restart(rows, start)
    moved = start.copy()
    moved.base_pos[:, :2] += offsets
    train_env.core.restart(rows, moved)


# The two simulations differ in their terrain geoms (one tile, a grid of tiles) and solver warm starts: Go2's
# steps agree to round-off, the G1's many contacts drift apart (2e-4 relative in one term after 12 steps, 1.8e-3
# in another, 6e-5 after 6); a reward built differently (a threshold, a height, a head point) is off by far more.
@pytest.mark.parametrize("robot, steps, rtol", [("go2", 12, 1e-9), ("g1", 6, 1e-3)])
def test_the_gym_env_and_the_training_env_give_equal_reward_terms(robot, steps, rtol):
    n = 2
    gym_env = FallRecoveryVectorEnv(num_envs=n, robot=robot, terrain="flat", level=1, reward="training")
    train_env = RecoveryTrainingEnv(TrainEnvConfig(num_envs=n, robot=robot, randomize=False, families=("flat",),
                                                   episode_steps=steps + 5, settle_steps=2, seed=0))
    try:
        gym_env.reset(seed=3)
        _same_start(gym_env, train_env)
        captured = []
        reward_of = train_env.core.reward

        def capture(*args):
            out = reward_of(*args)
            captured.append(out)
            return out

        train_env.core.reward = capture
        rng = np.random.default_rng(0)
        for _ in range(steps):
            action = rng.uniform(-1, 1, size=(n, gym_env.spec_robot.n_joints))
            _, gym_reward, _, _, info = gym_env.step(action)
            _, train_reward, _, _ = train_env.step(torch.as_tensor(action))
            _, train_terms, _ = captured[-1]
            assert set(info["reward_terms"]) == set(train_terms)
            for term, values in train_terms.items():
                np.testing.assert_allclose(info["reward_terms"][term], values, rtol=rtol, atol=rtol, err_msg=term)
            np.testing.assert_allclose(gym_reward, train_reward.numpy(), rtol=max(rtol, 1e-6), atol=1e-5)  # float32 in training
        # the velocity-limit threshold is 0.8 x each joint's URDF limit in both, not the literal 0.8 rad/s
        threshold = np.asarray(gym_env.step_reward.config.velocity_threshold)
        assert threshold.shape == (gym_env.spec_robot.n_joints,) and threshold.min() > 5.0
        assert threshold.tolist() == list(reward_of.config.velocity_threshold)
    finally:
        gym_env.close()
        train_env.close()


def test_go2_trains_on_its_urdf_velocity_limits_in_the_gym_env():
    env = FallRecoveryVectorEnv(num_envs=1, robot="go2", reward="training")
    try:
        limits = env.step_reward.config.velocity_threshold
        assert limits[:3] == pytest.approx((0.8 * 30.1, 0.8 * 30.1, 0.8 * 15.7), rel=1e-3)
    finally:
        env.close()
