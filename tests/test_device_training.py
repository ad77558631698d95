"""The trainer that stays on the device (`frbench.training.device_env`) on Warp's CPU device: a tiny run (4
worlds, 2 PPO iterations) through ``frbench train --backend mujoco-warp`` gives a checkpoint that ``frbench
evaluate`` loads and scores; the bundle round-trips; the device env's groups are the numpy code's numbers."""

import json

import numpy as np
import pytest
import torch

pytest.importorskip("mujoco_warp")

from frbench.cli import main  # noqa: E402
from frbench.tasks.observations import flatten, proprioception  # noqa: E402
from frbench.training.config import TrainEnvConfig  # noqa: E402
from frbench.training.device_bundle import build_bundle, load_bundle, save_bundle  # noqa: E402
from frbench.training.device_env import DeviceTrainingEnv  # noqa: E402

TINY = ["--envs", "4", "--terrains", "flat", "--set", "num_morphologies=2", "--set", "episode_steps=30",
        "--set", "settle_steps=5"]


def test_a_tiny_device_run_resumes_and_gives_a_checkpoint_that_evaluate_scores(tmp_path):
    run = tmp_path / "run"
    assert main(["train", "--backend", "mujoco-warp", "--device", "cpu", "--steps", "192", "--checkpoint-every", "1",
                 "--out", str(run), *TINY]) == 0
    config = json.loads((run / "config.json").read_text())
    assert config["env"]["backend"] == "mujoco-warp" and config["env"]["num_envs"] == 4
    curve = (run / "curve.csv").read_text().splitlines()
    assert len(curve) == 3 and curve[2].startswith("2,192,")  # two iterations of 4 envs x 24 steps
    # --resume continues it on the device (its backend from config.json, --device as given), curriculum restored
    assert main(["train", "--resume", str(run), "--steps", "288", "--device", "cpu", "--checkpoint-every", "1"]) == 0
    assert (run / "curve.csv").read_text().splitlines()[-1].startswith("3,288,")
    out = tmp_path / "eval.json"
    assert main(["evaluate", "--policy", str(run), "--robots", "go2", "--terrains", "flat", "--levels", "1",
                 "--seeds", "0", "--episodes", "1", "--backends", "mujoco", "--out", str(out)]) == 0
    assert len(json.loads(out.read_text())["episodes"]) == 1


def test_the_bundle_round_trips_and_the_device_groups_are_the_numpy_codes(tmp_path):
    cfg = TrainEnvConfig(num_envs=4, num_morphologies=2, families=("flat", "stairs"), episode_steps=12,
                         settle_steps=5, seed=3)
    bundle = build_bundle(cfg, starts_per_cell=1, log=lambda *_: None)
    loaded = load_bundle(save_bundle(bundle, tmp_path / "bundle"))
    assert loaded.config == cfg and set(loaded.arrays) == set(bundle.arrays)
    assert len(loaded.arrays["bank_tile"]) == 20 * 2  # every tile, every variant once (none diverged)
    np.testing.assert_array_equal(loaded.arrays["bank_qpos"], bundle.arrays["bank_qpos"])
    env = DeviceTrainingEnv(loaded, "cpu", seed=0)
    try:
        rng = np.random.default_rng(0)
        for _ in range(12):  # one whole episode, then the new episodes' first observation
            obs = env.get_observations()
            state = env.state
            host = type(state)(**{k: getattr(state, k).double().numpy() for k in
                                  ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")})
            o_t = flatten(proprioception(host, env.targets.double().numpy()), np.asarray(env.spec.default_pose))
            o_t[:, -env.num_actions:] = env.action.numpy()
            np.testing.assert_allclose(obs["policy"].numpy(), o_t, rtol=1e-5, atol=1e-5)
            assert obs["privileged"].shape == (4, 277) and torch.isfinite(obs["privileged"]).all()
            np.testing.assert_allclose(obs["mass"].numpy(), loaded.arrays["masses"], rtol=1e-6)
            _, reward, done, _ = env.step(torch.as_tensor(rng.normal(0, 0.5, (4, env.num_actions)), dtype=torch.float32))
            assert reward.shape == (4,) and torch.isfinite(reward).all()
        assert bool(done.all()) and env.t == 0 and set(env.last_episode_stats) >= {"success_all", "success_flat"}
        assert env.curriculum.level.min() >= 1
    finally:
        env.close()


def test_the_device_env_and_the_cpu_trainer_agree_on_the_same_states_and_physics():
    """The CPU trainer (MuJoCo C, numpy) restarted on the device env's (Warp, torch) states with the bundle's physics:
    the groups at t = 0 equal to float32 (the foot forces aside: one forward pass from a cold solver gives
    another split of the support force), every reward term over three steps within the two simulators' drift
    (measured: 1e-7 relative after one step, below 1e-2 after three)."""
    from frbench.backends.base import PhysicsParams, RobotState
    from frbench.training.env import RecoveryTrainingEnv

    cfg = TrainEnvConfig(num_envs=4, num_morphologies=2, families=("flat", "stairs"), episode_steps=12,
                         settle_steps=5, seed=3)
    bundle = build_bundle(cfg, starts_per_cell=1, log=lambda *_: None)
    a = bundle.arrays
    device_env, cpu_env = DeviceTrainingEnv(bundle, "cpu", seed=0), RecoveryTrainingEnv(cfg)
    try:
        assert a["assignment"].tolist() == cpu_env.robots.assignment.tolist()
        assert a["family"].tolist() == cpu_env.curriculum.family.tolist()
        params = PhysicsParams(*(a[k].copy() for k in ("kp", "kd", "motor_strength", "friction", "payload",
                                                       "motor_friction")))
        cpu_env.core.task.params = params
        cpu_env.core.backend.set_params(params)
        s = device_env.state
        cpu_env.core.restart(np.arange(4), RobotState(**{k: getattr(s, k).double().numpy().copy() for k in
                                                         ("base_pos", "base_quat", "base_linvel", "base_angvel", "q",
                                                          "qd")}))
        assert device_env.tile.tolist() == cpu_env.starts.tile_row.tolist()
        cpu_groups, device_groups = cpu_env.get_observations(), device_env.get_observations()
        feet = slice(277 - 5, 277 - 1)  # the privileged view's foot forces (then friction)
        for key in ("policy", "privileged", "mass", "contact", "velocity", "extrinsics"):
            expected, got = cpu_groups[key].numpy(), device_groups[key].numpy()
            if key == "privileged":
                expected, got = np.delete(expected, np.r_[feet], axis=1), np.delete(got, np.r_[feet], axis=1)
            np.testing.assert_allclose(got, expected, rtol=1e-5, atol=2e-6, err_msg=key)
        captured, reward_of = [], cpu_env.core.reward

        def capture(*args):
            captured.append(reward_of(*args))
            return captured[-1]

        cpu_env.core.reward = capture
        rng = np.random.default_rng(0)
        for _ in range(3):
            action = torch.as_tensor(rng.normal(0, 0.5, (4, 12)), dtype=torch.float32)
            _, cpu_reward, _, _ = cpu_env.step(action)
            _, device_reward, _, _ = device_env.step(action)
            terms = captured[-1][1]
            assert set(terms) == set(device_env.last_terms)
            for name, values in terms.items():
                np.testing.assert_allclose(device_env.last_terms[name].double().numpy(), values, rtol=2e-2, atol=2e-4,
                                           err_msg=name)
            np.testing.assert_allclose(device_reward.numpy(), cpu_reward.numpy(), rtol=2e-2, atol=5e-4)
        # after the steps: the height scan, the CoM (Warp's kinematics of the new state) and the contact flags
        # (measured: 5e-5 m, 2.5e-4 m, equal)
        cpu_view, device_view = cpu_env.get_observations()["privileged"], device_env.get_observations()["privileged"]
        for block, tolerance in ((slice(42, 229), 1e-3), (slice(257, 259), 2e-3), (slice(259, 272), 0.0)):
            np.testing.assert_allclose(device_view[:, block].numpy(), cpu_view[:, block].numpy(), rtol=0,
                                       atol=tolerance)
    finally:
        device_env.close()
        cpu_env.close()


def test_the_gpu_run_trains_the_symmetry_recipe_without_demo_starts_and_refused_settings_are_named():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "tools" / "gpu_run" / "make_bundle.py"
    spec = importlib.util.spec_from_file_location("make_bundle", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    cfg = module.training_config()
    assert (cfg.backend, cfg.num_envs, cfg.demo_start_fraction, cfg.action_hold) == ("mujoco-warp", 4096, 0.0, 1)
    # the symmetry preset's demo starts: a one-line error naming the field, exit status 2, before any work
    assert main(["train", "--backend", "mujoco-warp", "--device", "cpu", "--preset", "symmetry", "--steps", "96",
                 "--out", "/nonexistent/never-written", *TINY]) == 2


def test_each_episode_redraws_the_physics_on_the_device_as_the_cpu_writes_it():
    from frbench.backends.base import MOTOR_FRICTION_VELOCITY, PhysicsParams
    from frbench.backends.mujoco_backend import write_actuator_fields, write_actuator_params

    rng = np.random.default_rng(0)
    n, j, nu = 5, 12, 24
    params = PhysicsParams(kp=rng.uniform(20, 80, (n, j)), kd=rng.uniform(0.6, 2, (n, j)),
                           motor_strength=rng.uniform(0.9, 1.1, (n, j)), friction=np.ones(n), payload=np.zeros(n),
                           motor_friction=rng.uniform(0.2, 1.25, (n, j)))
    limits = rng.uniform(20, 40, j)
    fields = [rng.normal(size=shape) for shape in ((n, nu, 10), (n, nu, 10), (n, nu, 2))]
    expected = [f.copy() for f in fields]
    write_actuator_params(*expected, params, limits)
    got = [torch.as_tensor(f) for f in fields]
    write_actuator_fields(*got, *(torch.as_tensor(a) for a in (params.kp, params.kd, params.motor_strength,
                                                               params.motor_friction, limits)), MOTOR_FRICTION_VELOCITY)
    for e, g in zip(expected, got):  # one formula: torch on the device writes the bytes numpy writes
        np.testing.assert_array_equal(g.numpy(), e)

    cfg = TrainEnvConfig(num_envs=4, num_morphologies=2, families=("flat",), episode_steps=2, settle_steps=5, seed=4)
    bundle = build_bundle(cfg, starts_per_cell=1, log=lambda *_: None)
    env = DeviceTrainingEnv(bundle, "cpu", seed=0)
    try:
        first = env.kp.clone()
        np.testing.assert_array_equal(first.numpy(), bundle.arrays["kp"].astype(np.float32))  # the CPU trainer's draw
        for _ in range(2):  # one episode
            env.step(torch.zeros(4, env.num_actions))
        kp, gain = env.kp, env._gain[:, :env.num_actions, 0]
        assert not torch.equal(kp, first)
        assert float(kp.min()) >= 20.0 and float(kp.max()) <= 80.0
        assert torch.equal(kp, kp[:, :1].expand(-1, 12))  # one Kp per environment for sampled morphologies
        torch.testing.assert_close(gain, (env.motor_strength * kp).float())
        assert float(env.motor_strength.min()) >= 0.9 and float(env.motor_strength.max()) <= 1.1
    finally:
        env.close()
