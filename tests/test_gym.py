"""The Gymnasium environments: spaces, the action mapping, the training reward in ``info``, the success state,
episode metrics, rendering, and Gymnasium's own checker with its warnings turned into errors."""

import warnings

import gymnasium
import numpy as np
import pytest

import frbench.gym  # noqa: F401  (registers)
from frbench.gym import ACTION_SCALE, ENV_ID, observation_bounds, reward_config
from frbench.robots import get_robot
from frbench.training.reward_tables import training_reward_config


def test_gymnasium_check_env_passes_with_warnings_as_errors():
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco", render_mode="rgb_array", render_size=(64, 48))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env.unwrapped)
    finally:
        env.close()


def test_spaces_are_normalised_and_bounded():
    env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco")
    spec = get_robot("go2")
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, shape=(12,), dtype=np.float32)
    low, high = observation_bounds(spec)
    assert np.isfinite(env.observation_space.low).all() and np.isfinite(env.observation_space.high).all()
    assert env.observation_space.shape == (42,)
    np.testing.assert_array_equal(env.observation_space.high[:6], [50, 50, 50, 1, 1, 1])
    np.testing.assert_allclose(high[6:18], np.asarray(spec.joint_upper) - spec.default_pose, rtol=1e-6)
    env.close()


def test_actions_map_to_default_pose_plus_scale_times_action():
    env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco").unwrapped
    spec = get_robot("go2")
    a = np.linspace(-1.0, 1.0, 12)[None]
    np.testing.assert_allclose(env._vector.targets(a)[0], np.asarray(spec.default_pose) + ACTION_SCALE * a[0])
    np.testing.assert_allclose(env._vector.targets(3 * a)[0], np.asarray(spec.default_pose) + ACTION_SCALE * np.clip(3 * a[0], -1, 1))
    env.close()


def test_info_has_training_reward_terms_success_state_and_episode_metrics():
    env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco")
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    weights = training_reward_config().weights
    total = 0.0
    for t in range(250):
        obs, reward, terminated, truncated, info = env.step(np.zeros(12, dtype=np.float32))
        assert set(info["reward_terms"]) == set(weights)
        assert reward == pytest.approx(sum(info["reward_terms"].values()), rel=1e-5, abs=1e-6)
        total += reward
        if t < 249:
            assert "episode_metrics" not in info
    assert truncated and not terminated
    assert {"success", "upright", "time_to_recover", "diverged"} <= set(info)
    metrics = info["episode_metrics"]
    assert set(metrics) == {"success", "time_to_recover", "final_displacement", "max_displacement", "energy",
                            "smoothness", "peak_contact_force", "rolled_over", "diverged"}
    assert metrics["energy"] > 0 and np.isfinite(total)
    assert metrics["success"] is info["success"] or metrics["success"] == info["success"]
    env.close()


def test_reward_presets_follow_the_robot_kind():
    humanoid = reward_config("training", "humanoid").weights
    assert "head_height" in humanoid and "feet_contact" not in humanoid
    assert "feet_contact" in reward_config("training", "quadruped").weights
    assert reward_config("paper", "quadruped").weights["upright_orientation"] == 6.0
    with pytest.raises(ValueError, match="reward='upright': expected one of training, paper"):
        reward_config("upright", "quadruped")


def test_vector_env_truncates_together_and_renders_one_frame_per_environment():
    venv = gymnasium.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", robot="go2",
                              backend="pybullet", render_mode="rgb_array", render_size=(64, 48))
    obs, _ = venv.reset(seed=1)
    assert obs.shape == (3, 42) and venv.single_action_space.shape == (12,)
    frames = venv.render()
    assert len(frames) == 3 and frames[0].shape == (48, 64, 3) and frames[0].std() > 5
    for _ in range(250):
        obs, reward, terminated, truncated, info = venv.step(venv.action_space.sample())
    assert truncated.all() and info["final_obs"].shape == (3, 42) and reward.shape == (3,)
    assert info["episode_metrics"]["energy"].shape == (3,) and info["reward_terms"]["upright_orientation"].shape == (3,)
    venv.close()


def test_render_collection_gets_one_frame_per_step():
    from gymnasium.wrappers import RenderCollection

    env = RenderCollection(gymnasium.make(ENV_ID, robot="go2", backend="mujoco", render_mode="rgb_array",
                                          render_size=(64, 48)))
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.zeros(12, dtype=np.float32))
    frames = env.render()
    assert len(frames) == 4 and all(f.shape == (48, 64, 3) and f.dtype == np.uint8 for f in frames)
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).max() > 0  # the robot moved, the caption changed
    env.close()


def test_record_video_writes_an_episode(tmp_path):
    pytest.importorskip("moviepy", reason="gymnasium's RecordVideo needs moviepy (gymnasium[other]), not installed")
    from gymnasium.wrappers import RecordVideo

    env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco", render_mode="rgb_array", render_size=(64, 48))
    env = RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda episode: True, disable_logger=True)
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.zeros(12, dtype=np.float32))
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


def test_stable_baselines3_check_env_passes_with_warnings_as_errors():
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")

    env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            sb3_checker.check_env(env.unwrapped, warn=True, skip_render_check=True)
    finally:
        env.close()


def test_unseeded_resets_draw_from_the_generator_seeded_at_construction():
    """``seed`` at make time fixes the starts of resets without a seed; ``reset(seed=S)`` equals make(seed=S)."""
    first = []
    for seed in (3, 3, 4):
        env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco", seed=seed)
        first.append(env.reset()[0])
        env.close()
    np.testing.assert_array_equal(first[0], first[1])
    assert np.abs(first[0] - first[2]).max() > 1e-3
    env = gymnasium.make(ENV_ID, robot="go2", backend="mujoco")
    np.testing.assert_array_equal(env.reset(seed=4)[0], first[2])
    env.close()
