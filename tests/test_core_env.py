"""The core environment: the Gymnasium env is a shell over it (equal observations and rewards), held actions
compose in it, and it owns and frees the simulator it builds."""

import numpy as np

from frbench.gym import FallRecoveryEnv, reward_config
from frbench.robots import get_robot
from frbench.tasks.actions import DirectTargets
from frbench.tasks.core_env import CoreEnv
from frbench.tasks.observations import observation_bounds
from frbench.terrains import height_at, make_terrain
from frbench.training.action_hold import HeldAction
from frbench.training.step_reward import StepReward


def _core(spec, terrain, hold: int = 1, num_envs: int = 1) -> CoreEnv:
    reward = StepReward(reward_config("training", spec.kind), spec, spec.nominal_height,
                        lambda xy: height_at(terrain, xy))
    return CoreEnv(spec, "mujoco", terrain, num_envs, transform=DirectTargets(spec.default_pose, 1.0),
                   hold=HeldAction(hold), reward=reward, rng=np.random.default_rng(0))


def _actions(steps: int, n_joints: int) -> np.ndarray:
    return np.random.default_rng(7).uniform(-1.0, 1.0, size=(steps, n_joints))


def test_the_gym_env_gives_the_core_env_s_observations_and_rewards_step_for_step():
    spec, terrain = get_robot("go2"), make_terrain("rough", 3, 0)
    gym_env = FallRecoveryEnv(robot="go2", terrain="rough", level=3, terrain_seed=0)
    core = _core(spec, terrain)
    low, high = observation_bounds(spec)
    try:
        gym_obs, _ = gym_env.reset(seed=11)
        core.seed(11)
        core.new_episodes()  # the default start distribution: the protocol's fallen starts on the terrain
        np.testing.assert_array_equal(gym_obs, np.clip(core.flat_observation()[0], low, high).astype(np.float32))
        rewards = []
        for action in _actions(10, spec.n_joints):
            gym_obs, gym_reward, terminated, truncated, info = gym_env.step(action.astype(np.float32))
            reward, terms, alive = core.step(action.astype(np.float32)[None].astype(np.float64))
            np.testing.assert_array_equal(gym_obs, np.clip(core.flat_observation()[0], low, high).astype(np.float32))
            assert gym_reward == np.float32(reward[0]) and not terminated and not truncated and alive.all()
            assert info["reward_terms"] == {k: float(v[0]) for k, v in terms.items()}
            assert info["success"] == bool(core.success_info()["success"][0])
            rewards.append(gym_reward)
        assert core.t == 10 and core.env_steps == 10 and not core.done
        assert len(set(rewards)) == 10 and np.isfinite(rewards).all()  # ten different steps, not a constant
    finally:
        gym_env.close()
        core.close()


def test_a_held_action_is_the_sum_of_its_control_steps():
    spec, terrain = get_robot("go2"), make_terrain("flat", 1, 0)
    single, held = _core(spec, terrain, hold=1, num_envs=2), _core(spec, terrain, hold=2, num_envs=2)
    try:
        for env in (single, held):
            env.reset(env.draw_fallen(np.random.default_rng(3), terrain), settle_steps=2)
            env.begin()
        actions = _actions(2, spec.n_joints)
        both = np.stack([actions[0], actions[1]])  # environment k gets action k
        first, first_terms, _ = single.step(both)
        second, second_terms, _ = single.step(both)  # the same action twice: within a decision a_{t-1} = a_t
        total, terms, alive = held.step(both)
        assert held.t == single.t == 2 and held.env_steps == single.env_steps == 4 and alive.all()
        np.testing.assert_array_equal(total, first + second)
        for name in terms:
            np.testing.assert_array_equal(terms[name], first_terms[name] + second_terms[name])
        np.testing.assert_array_equal(held.state.q, single.state.q)
        assert np.abs(total).min() > 0.0
    finally:
        single.close()
        held.close()


def test_the_core_env_frees_the_simulator_it_built_once():
    spec, terrain = get_robot("go2"), make_terrain("flat", 1, 0)
    core = _core(spec, terrain)
    closed, free = [], core.backend.close
    core.backend.close = lambda: (closed.append(1), free())
    core.reset(core.draw_fallen(np.random.default_rng(0), terrain), settle_steps=1)
    core.begin()
    core.step(np.zeros((1, spec.n_joints)))
    assert closed == [] and core.task.backend is core.backend  # the task works on it, never closes it
    core.close()
    assert closed == [1]


def test_the_shells_and_start_sources_reach_the_simulator_only_through_the_core_env():
    """No shell (gym, the rsl-rl env) and no start source or assist builds a backend or a task, or calls a
    method of one: the core env builds both and its API (drive, restart, set_base_force, ...) is the way in."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "frbench"
    files = ["gym.py", "training/env.py", "training/start_sources.py", "training/demo_starts.py", "training/assist.py"]
    found = []
    for name in files:
        for node in ast.walk(ast.parse((root / name).read_text())):
            if isinstance(node, ast.Name) and node.id in ("make_backend", "RecoveryTask"):
                found.append((name, node.id))
            if isinstance(node, ast.Attribute) and node.attr in ("backend", "task"):
                owner = node.value.attr if isinstance(node.value, ast.Attribute) else node.value.id
                if owner != "cfg":  # the config's backend name
                    found.append((name, f"{owner}.{node.attr}"))  # e.g. self.core.backend, self.task
    assert found == [("training/env.py", "core.backend")]  # RecoveryTrainingEnv.backend: read by a throughput benchmark
