"""The observation, reward and success code is one implementation for numpy and torch (`frbench.arrays`):
on the same states the two paths agree term by term — every observation block, every privileged group, every
reward term and the success test — in float64 to round-off and in float32 (the device trainer's dtype) to
float32 precision."""

from dataclasses import fields, replace

import numpy as np
import pytest
import torch

from frbench.tasks import observations as O
from frbench.tasks.success import StepSignals, SuccessTracker
from frbench.training import observation_groups, step_reward
from frbench.training.config import TrainEnvConfig
from frbench.training.env import RecoveryTrainingEnv
from frbench.training.rewards import REWARD_TERMS, compute_rewards, term_arguments
from frbench.training.reward_inputs import RewardInputs


def _torch(value, dtype):
    """``value`` as a tensor: floating arrays in ``dtype``, booleans as they are, scalars unchanged."""
    if isinstance(value, np.ndarray):
        return torch.as_tensor(value, dtype=torch.bool if value.dtype == bool else dtype)
    return value


def _close(a, b, dtype, what):
    b = b.detach().cpu().numpy()
    assert b.shape == np.shape(a), what
    tol = 1e-10 if dtype == torch.float64 else 2e-5
    np.testing.assert_allclose(b, np.asarray(a, dtype=float), rtol=tol, atol=tol, err_msg=what)


@pytest.fixture(scope="module")
def captured():
    """A Go2 training rollout on flat ground and stairs (4 envs, 24 decisions of random actions): each step's
    reward inputs, states, signals and privileged parts, as the numpy trainer computed them."""
    calls = {"rewards": [], "privileged": [], "states": [], "signals": []}
    original_rewards, original_groups = step_reward.compute_rewards, observation_groups.privileged_groups

    def rewards(inputs, config, *args):
        calls["rewards"].append((replace(inputs), config))
        return original_rewards(inputs, config, *args)

    def groups(*args):
        calls["privileged"].append(args)
        return original_groups(*args)

    step_reward.compute_rewards, observation_groups.privileged_groups = rewards, groups
    env = RecoveryTrainingEnv(TrainEnvConfig(num_envs=4, robot="go2", families=("flat", "stairs"), episode_steps=40,
                                             settle_steps=5, seed=2))
    try:
        rng = np.random.default_rng(0)
        for _ in range(24):
            env.step(torch.as_tensor(rng.uniform(-1, 1, size=(4, env.num_actions)), dtype=torch.float32))
            calls["states"].append((env.core.state.copy(), env.core.task.previous_action.copy()))
            calls["signals"].append(env.core.signals)
    finally:
        step_reward.compute_rewards, observation_groups.privileged_groups = original_rewards, original_groups
        env.close()
    calls["default_pose"] = np.asarray(env.spec.default_pose)
    return calls


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_every_reward_term_is_the_same_in_numpy_and_torch(captured, dtype):
    assert len(captured["rewards"]) == 24
    for inputs, config in captured["rewards"]:
        as_torch = RewardInputs(**{f.name: _torch(getattr(inputs, f.name), dtype) for f in fields(RewardInputs)})
        total, terms = compute_rewards(inputs, config)
        total_t, terms_t = compute_rewards(as_torch, config, term_arguments(config, as_torch))
        assert set(terms) == set(terms_t) == set(config.weights)
        for name in terms:
            assert terms_t[name].dtype == dtype, name
            _close(terms[name], terms_t[name], dtype, name)
        _close(total, total_t, dtype, "total")
        # every term of the table, weighted or not, unweighted
        kwargs = term_arguments(config, as_torch)
        for name in ("base_orientation", "upright_orientation", "target_posture", "feet_contact", "body_contact",
                     "safety_force", "body_bias", "position_limits", "velocity_limit", "joint_acceleration",
                     "joint_velocity", "action_smoothing", "joint_torques", "base_height", "feet_on_ground",
                     "upper_body_posture", "action_jerk"):
            args = kwargs.get(name, {})
            _close(REWARD_TERMS[name](inputs, **term_arguments(config).get(name, {})),
                   REWARD_TERMS[name](as_torch, **args), dtype, name)
    # the rollout exercised the gated and counted terms
    assert any(float(np.abs(t["feet_contact"]).max()) > 0 for t in (compute_rewards(i, c)[1] for i, c in captured["rewards"]))


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_every_observation_block_and_privileged_group_is_the_same(captured, dtype):
    default = captured["default_pose"]
    for state, previous in captured["states"]:
        obs = O.proprioception(state, previous)
        state_t = replace(state, **{f.name: _torch(getattr(state, f.name), dtype) for f in fields(state)})
        obs_t = O.proprioception(state_t, torch.as_tensor(previous, dtype=dtype))
        assert list(obs) == list(obs_t) == list(O.PROPRIOCEPTION_KEYS)
        for key in obs:
            _close(obs[key], obs_t[key], dtype, key)
        _close(O.flatten(obs, default), O.flatten(obs_t, torch.as_tensor(default, dtype=dtype)), dtype, "o_t")
    assert len(captured["privileged"]) >= 24
    for args in captured["privileged"]:
        groups = observation_groups.privileged_groups(*args)
        groups_t = observation_groups.privileged_groups(*(_torch(np.asarray(a), dtype) for a in args))
        assert list(groups) == list(groups_t) == ["privileged", "mass", "contact", "velocity", "extrinsics"]
        assert groups["privileged"].shape == (4, 277)
        for key in groups:
            _close(groups[key], groups_t[key], dtype, key)


def _synthetic_signals(rng, steps, n):
    """``steps`` StepSignals of n robots that rise, hold, fall and drift: streaks, holds, breaks and displacements
    past the limit all occur."""
    phase = rng.uniform(0, 2 * np.pi, size=n)
    out = []
    for t in range(steps):
        up = np.sin(0.05 * t + phase) > -0.2
        out.append(StepSignals(
            gravity_z=np.where(up, -0.98, -0.3) + rng.normal(0, 0.01, n),
            height=np.where(up, 0.30, 0.12) + rng.normal(0, 0.01, n),
            body_contact=rng.random(n) < 0.03,
            displacement=np.abs(rng.normal(0.6, 0.5, n)),
            surface_drop=rng.normal(0.0, 0.08, n),
            torso_gravity_z=np.where(up, -0.95, 0.0),
        ))
    return out


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_the_success_test_is_the_same_in_numpy_and_torch(captured, dtype):
    rng = np.random.default_rng(5)
    n, nominal = 64, np.full(64, 0.32)
    for kind in ("quadruped", "humanoid"):
        signals = _synthetic_signals(rng, 200, n)
        alive = rng.random((200, n)) > 0.002
        numpy_tracker = SuccessTracker(n, kind, nominal)
        like = torch.zeros(n, dtype=dtype)
        torch_tracker = SuccessTracker(n, kind, torch.as_tensor(nominal, dtype=dtype), like=like)
        for start in range(0, 200, 40):  # numpy in chunks of 40 steps (as the engine catches up), torch step by step
            chunk = signals[start:start + 40]
            stacked = StepSignals(*(np.stack([getattr(s, f.name) for s in chunk]) for f in fields(StepSignals)))
            numpy_tracker.update_steps(stacked, alive[start:start + 40])
            for t, s in enumerate(chunk):
                s_t = StepSignals(*(_torch(getattr(s, f.name), dtype) for f in fields(StepSignals)))
                np.testing.assert_array_equal(torch_tracker.upright(s_t).numpy(),
                                              SuccessTracker(n, kind, nominal).upright(s))
                torch_tracker.update(s_t, torch.as_tensor(alive[start + t]))
            np.testing.assert_array_equal(torch_tracker.success.numpy(), numpy_tracker.success)
            np.testing.assert_allclose(torch_tracker.time_to_recover.numpy(), numpy_tracker.time_to_recover, rtol=1e-6)
        assert torch_tracker.success.dtype == torch.bool and torch_tracker.time_to_recover.dtype == dtype
        assert 0 < int(numpy_tracker.success.sum()) < n  # some recover, some do not
    # the trainer's own signals (real states)
    tracker, tracker_t = SuccessTracker(4, "quadruped", 0.3), SuccessTracker(4, "quadruped", torch.tensor(0.3, dtype=dtype),
                                                                              like=torch.zeros(4, dtype=dtype))
    for s in captured["signals"]:
        tracker.update(s)
        tracker_t.update(StepSignals(*(_torch(getattr(s, f.name), dtype) for f in fields(StepSignals))))
        np.testing.assert_array_equal(tracker_t.upright(StepSignals(*(_torch(getattr(s, f.name), dtype)
                                                                        for f in fields(StepSignals)))).numpy(),
                                      tracker.upright(s))
    np.testing.assert_array_equal(tracker_t.success.numpy(), tracker.success)
