"""``frbench evaluate --policy`` on policies trained elsewhere: frbench's ONNX export (the checkpoint's actions
and successes), TorchScript (the checkpoint's episodes exactly), a foreign ONNX MLP, Python files and modules,
a Stable-Baselines3 model; each in MuJoCo and PyBullet."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from frbench.cli import main
from frbench.policies.registry import load_policy
from frbench.robots import get_robot
from frbench.backends import make_backend
from policy_factory import POLICY_FILE, evaluate, export_onnx, mlp, writing_torchscript

ort = pytest.importorskip("onnxruntime")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("own")


@pytest.fixture(scope="module")
def reference(folder) -> dict:
    """Results of the shipped frnet checkpoint and of the zero policy on the test cell, both simulators."""
    return {name: evaluate(folder / f"{name}.json", name) for name in ("frnet", "zero")}


@pytest.fixture(scope="module")
def frnet_onnx(folder):
    path = folder / "frnet.onnx"
    assert main(["export", "--policy", "frnet", "--out", str(path)]) == 0
    return path


def _task_steps(num_envs: int = 4, steps: int = 30):
    """Observation dicts of a real Go2 episode batch (MuJoCo, flat), driven by the frnet checkpoint."""
    from frbench.tasks.initial_states import draw_starts
    from frbench.tasks.recovery import RecoveryTask
    from frbench.terrains import make_terrain

    spec, terrain = get_robot("go2"), make_terrain("flat", 1, 0)
    task = RecoveryTask(spec, make_backend("mujoco", spec, num_envs, terrain=terrain), terrain, num_envs)
    obs = task.reset(draw_starts(spec, terrain, "flat", 1, 0, range(num_envs)))
    driver = load_policy("frnet")
    driver.reset(spec, num_envs)
    try:
        for _ in range(steps):
            yield obs
            obs = task.step(driver.act(obs))
    finally:
        task.backend.close()


def test_frnet_onnx_export_reproduces_the_checkpoint_s_actions(frnet_onnx):
    spec = get_robot("go2")
    sidecar = json.loads(frnet_onnx.with_name("frnet.onnx.json").read_text())
    assert sidecar["layout"]["inputs"] == [{"name": "obs", "frames": 1}, {"name": "history", "frames": 5}]
    checkpoint, exported = load_policy("frnet"), load_policy(str(frnet_onnx))
    assert exported.layout.input_sizes(12) == {"obs": 42, "history": 210}
    checkpoint.reset(spec, 4)
    exported.reset(spec, 4)
    largest = 0.0
    for obs in _task_steps():
        largest = max(largest, float(np.abs(checkpoint.act(obs) - exported.act(obs)).max()))
    print(f"largest |q*_onnx - q*_pt| over 30 steps x 4 episodes: {largest:.1e} rad")
    assert largest < 1e-5


def test_frnet_onnx_export_scores_like_the_checkpoint_in_both_simulators(folder, reference, frnet_onnx):
    results = evaluate(folder / "frnet-onnx.json", str(frnet_onnx))
    assert results["policy"]["name"] == "frnet" and results["policy"]["checkpoint"] == str(frnet_onnx)
    assert [e["success"] for e in results["episodes"]] == [e["success"] for e in reference["frnet"]["episodes"]]
    assert sum(e["success"] for e in results["episodes"]) == 4


def test_torchscript_frnet_with_the_spec_json_as_sidecar_gives_the_checkpoint_s_episodes(folder, reference, capsys):
    import torch

    path = folder / "frnet-script.pt"
    with writing_torchscript():  # as rsl-rl's export_policy_to_jit writes an actor
        torch.jit.save(torch.jit.script(load_policy("frnet").actor.as_jit()), str(path))
    assert main(["spec", "--robot", "go2", "--policy", "frnet", "--json"]) == 0
    path.with_name(path.name + ".json").write_text(capsys.readouterr().out)
    scripted, checkpoint, spec = load_policy(str(path)), load_policy("frnet"), get_robot("go2")
    scripted.reset(spec, 4)
    checkpoint.reset(spec, 4)
    # The checkpoint infers in float64 (protocol 1.2); the user's TorchScript file keeps its own dtype, so the
    # two agree to float32 rounding, not bit for bit.
    largest = max(float(np.abs(checkpoint.act(obs) - scripted.act(obs)).max()) for obs in _task_steps())
    assert largest < 1e-5
    results = evaluate(folder / "frnet-script.json", str(path))
    assert [e["success"] for e in results["episodes"]] == [e["success"] for e in reference["frnet"]["episodes"]]


def test_model_files_carry_their_layout_without_a_sidecar(folder, frnet_onnx):
    import shutil

    import torch

    alone = folder / "alone"
    alone.mkdir()
    shutil.copy(frnet_onnx, alone / "frnet.onnx")  # the ONNX file alone: the layout is in its metadata
    assert load_policy(str(alone / "frnet.onnx")).layout == load_policy(str(frnet_onnx)).layout
    assert load_policy(str(alone / "frnet.onnx")).layout.input_sizes(12) == {"obs": 42, "history": 210}
    layout = '{"observation": ["base_angvel", "projected_gravity", "joint_pos"], "action_scale": 0.5}'
    with writing_torchscript():
        torch.jit.save(torch.jit.trace(mlp(inputs=18), torch.zeros(1, 18)), str(alone / "small.pt"),
                       _extra_files={"frbench_layout.json": layout})
    small = load_policy(str(alone / "small.pt"))
    assert small.layout.frame_size(12) == 18 and small.layout.action_scale == 0.5
    assert small.supports(get_robot("go1"))


def test_a_foreign_onnx_mlp_runs_in_both_simulators_on_frbench_s_default_layout(folder, reference):
    import torch

    model = mlp(seed=3)
    path = export_onnx(model, folder / "foreign.onnx")  # batch fixed to 1, no sidecar: the default layout
    policy = load_policy(str(path))
    spec = get_robot("go2")
    policy.reset(spec, 4)
    from frbench.tasks.observations import flatten

    for k, obs in enumerate(_task_steps(steps=3)):
        frame = flatten(obs, np.asarray(spec.default_pose))
        if k:
            frame[:, -12:] = previous
        with torch.no_grad():
            expected = model(torch.as_tensor(frame, dtype=torch.float32)).numpy()
        targets = policy.act(obs)
        np.testing.assert_allclose(targets - np.asarray(spec.default_pose), expected, atol=1e-5)
        previous = expected
    results = evaluate(folder / "foreign.json", str(path))
    assert len(results["episodes"]) == 4 and results["policy"]["sha256"]
    assert {e["backend"] for e in results["episodes"]} == {"mujoco", "pybullet"}
    silent = export_onnx(mlp(zero_output=True), folder / "silent.onnx", dynamic_batch=True)
    assert evaluate(folder / "silent.json", str(silent))["episodes"] == reference["zero"]["episodes"]


@pytest.mark.parametrize("attr", ["Zero", "Single", "Targets"])
def test_python_file_policies_batched_single_or_targets_equal_the_zero_policy(folder, reference, attr, monkeypatch):
    path = folder / "my_policy.py"
    path.write_text(POLICY_FILE)
    monkeypatch.chdir(folder)
    results = evaluate(folder / f"py-{attr}.json", f"my_policy.py:{attr}")
    assert results["config"]["policy"] == f"{path}:{attr}"  # shipped to workers as an absolute path
    assert results["policy"]["name"] == f"my_policy-{attr}" and results["policy"]["checkpoint"] == str(path)
    assert results["episodes"] == reference["zero"]["episodes"]


def test_a_module_attr_policy_and_a_native_frbench_policy_by_module_path(folder, reference, monkeypatch):
    (folder / "their_policies.py").write_text(POLICY_FILE)
    monkeypatch.syspath_prepend(str(folder))
    zero_mujoco = [e for e in reference["zero"]["episodes"] if e["backend"] == "mujoco"]
    assert evaluate(folder / "mod.json", "their_policies:Zero", backends="mujoco")["episodes"] == zero_mujoco
    native = evaluate(folder / "native.json", "frbench.policies.zero:ZeroPolicy", backends="mujoco")
    assert native["episodes"] == zero_mujoco and native["policy"]["name"] == "zero"
    sys.modules.pop("their_policies", None)


@pytest.fixture(scope="module")
def sb3_model(folder):
    """A Stable-Baselines3 PPO trained for 128 steps on frbench/FallRecovery-v1 (Go2, MuJoCo, flat)."""
    pytest.importorskip("stable_baselines3")
    import gymnasium
    from stable_baselines3 import PPO

    import frbench.gym  # noqa: F401  (registers the environment)

    env = gymnasium.make("frbench/FallRecovery-v1", robot="go2", backend="mujoco")
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu",
                policy_kwargs={"net_arch": [32, 32]})
    model.learn(total_timesteps=128)
    env.close()
    model.save(folder / "ppo.zip")
    return folder / "ppo.zip", model


def test_an_sb3_model_sees_the_gym_env_s_observations_and_acts_as_there(sb3_model):
    from frbench.gym import FallRecoveryVectorEnv

    path, model = sb3_model
    policy = load_policy(str(path))
    env = FallRecoveryVectorEnv(num_envs=2, robot="go2", backend="pybullet")
    flat, _ = env.reset(seed=1)
    policy.reset(env.spec_robot, 2)
    try:
        for _ in range(5):
            targets = policy.act(env.core.observation())
            np.testing.assert_array_equal(policy.model_inputs(env.core.observation())["obs"], flat)  # the model's input
            actions, _ = model.predict(flat, deterministic=True)
            np.testing.assert_allclose(targets, env.targets(actions), atol=1e-12)
            flat = env.step(actions)[0]
    finally:
        env.close()


def test_an_sb3_model_runs_in_both_simulators(folder, sb3_model):
    results = evaluate(folder / "ppo.json", str(sb3_model[0]))
    assert len(results["episodes"]) == 4 and results["policy"]["name"] == "ppo"
    assert {e["backend"] for e in results["episodes"]} == {"mujoco", "pybullet"}
