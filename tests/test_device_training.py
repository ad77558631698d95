"""One training env for every simulator and device: ``mujoco-warp`` on Warp's CPU device runs the env's code on torch
tensors, the CPU simulators on numpy arrays. On the same states the two paths give the same observation groups and
reward terms, the same curriculum moves (its redraw included), episode statistics and per-episode draws; a tiny
``frbench train --backend mujoco-warp --device cpu`` run logs the CPU run's curve columns, resumes and evaluates;
a device bundle rebuilds the env the CPU builds."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

pytest.importorskip("mujoco_warp")

from frbench.backends.base import RobotState  # noqa: E402
from frbench.cli import main  # noqa: E402
from frbench.training.config import TrainEnvConfig  # noqa: E402
from frbench.training.env import RecoveryTrainingEnv  # noqa: E402

TINY = ["--envs", "4", "--terrains", "flat", "--set", "num_morphologies=2", "--set", "episode_steps=30",
        "--set", "settle_steps=5"]
ROOT = Path(__file__).resolve().parents[1]
FIELDS = ("base_pos", "base_quat", "base_linvel", "base_angvel", "q", "qd")
#: Two families, sampled morphologies and randomised physics: every part of the env that differs per environment.
CONFIG = dict(num_envs=4, num_morphologies=2, families=("flat", "stairs"), episode_steps=6, settle_steps=5, seed=3)


def _host(state) -> RobotState:
    return RobotState(**{k: getattr(state, k).double().numpy().copy() for k in FIELDS})


def test_a_tiny_device_run_logs_the_cpu_runs_columns_resumes_and_evaluates(tmp_path):
    cpu, run = tmp_path / "cpu", tmp_path / "run"
    assert main(["train", "--steps", "192", "--checkpoint-every", "1", "--out", str(cpu), *TINY]) == 0
    assert main(["train", "--backend", "mujoco-warp", "--device", "cpu", "--steps", "192", "--checkpoint-every", "1",
                 "--out", str(run), *TINY]) == 0
    config = json.loads((run / "config.json").read_text())
    assert config["env"]["backend"] == "mujoco-warp" and config["env"]["num_envs"] == 4
    curve = (run / "curve.csv").read_text().splitlines()
    assert len(curve) == 3 and curve[2].startswith("2,192,")  # two iterations of 4 envs x 24 steps
    header = curve[0].split(",")
    assert header == (cpu / "curve.csv").read_text().splitlines()[0].split(",")  # the CPU run's columns
    assert {"level_flat", "level_at_max", "mean_level", "success_flat", "reward_upright_orientation"} <= set(header)
    # --resume continues it (its backend from config.json, --device as given), curriculum and generator restored
    state = torch.load(run / "state.pt", weights_only=False)
    assert set(state["curriculum"]) >= {"version", "rng", "level", "family"}  # TerrainCurriculum's state
    assert main(["train", "--resume", str(run), "--steps", "288", "--device", "cpu", "--checkpoint-every", "1"]) == 0
    assert (run / "curve.csv").read_text().splitlines()[-1].startswith("3,288,")
    out = tmp_path / "eval.json"
    assert main(["evaluate", "--policy", str(run), "--robots", "go2", "--terrains", "flat", "--levels", "1",
                 "--seeds", "0", "--episodes", "1", "--backends", "mujoco", "--out", str(out)]) == 0
    assert len(json.loads(out.read_text())["episodes"]) == 1


def test_a_device_on_a_cpu_simulator_and_an_unknown_device_are_one_line_errors(tmp_path, capsys):
    for flags, message in ((["--device", "cuda:99", "--backend", "mujoco-warp"], "--device cuda:99: torch sees"),
                           (["--device", "tpu"], "--device 'tpu': expected cpu, cuda or cuda:N"),
                           (["--bundle", str(tmp_path)], f"--bundle {tmp_path}: this run trains in mujoco")):
        assert main(["train", "--steps", "96", "--out", str(tmp_path / "never"), *TINY, *flags]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "never").exists()


class TorchView:
    """A CPU simulator handing out its arrays as torch tensors of ``dtype`` on the CPU (a test's device backend):
    the training env on it runs its torch path on the states the numpy path sees."""

    device_arrays = True

    def __init__(self, backend, dtype):
        self.backend, self.dtype = backend, dtype

    def __getattr__(self, name):
        return getattr(self.backend, name)

    def _t(self, x):
        return torch.as_tensor(np.asarray(x), dtype=self.dtype if np.asarray(x).dtype.kind == "f" else None)

    @property
    def diverged(self):
        return self._t(self.backend.diverged)

    def state(self):
        state = self.backend.state()
        return RobotState(**{k: self._t(getattr(state, k)) for k in (*FIELDS, "tau")})

    def contacts(self):
        from frbench.backends.base import summarize_contacts

        return summarize_contacts(self.spec, self.link_names, self._t(self.backend.contacts().link_force))

    def whole_body_com(self):
        return self._t(self.backend.whole_body_com())

    def step(self, targets):
        self.backend.step(targets.numpy() if isinstance(targets, torch.Tensor) else targets)

    def reset(self, ids, state):
        self.backend.reset(np.asarray(ids), state.on_host())


def test_both_array_paths_agree_on_the_same_states_term_by_term(monkeypatch):
    """The training env's numpy path and its torch path on MuJoCo C, one config and seed: the torch env's
    simulator hands out torch tensors (float64, `TorchView`), and the targets it computes in torch are the numpy
    path's bit for bit, so both envs visit the same states. Every observation group, reward term, reward and
    reward-term mean agrees to round-off at every step of an episode; the same draws (robots, families, levels,
    tiles, per-episode physics: one generator, one order); at the episode end (every environment succeeding at the
    top level) the same curriculum redraw, statistics and next physics."""
    import frbench.tasks.core_env as core_env

    numpy_env = RecoveryTrainingEnv(TrainEnvConfig(**CONFIG))
    make = core_env.make_backend
    monkeypatch.setattr(core_env, "make_backend", lambda *a, **k: TorchView(make(*a, **k), torch.float64))
    torch_env = RecoveryTrainingEnv(TrainEnvConfig(**CONFIG))
    try:
        assert not numpy_env.device_arrays and torch_env.device_arrays
        assert isinstance(torch_env.core.state.q, torch.Tensor) and isinstance(numpy_env.core.state.q, np.ndarray)
        np.testing.assert_array_equal(torch_env.robots.assignment, numpy_env.robots.assignment)
        np.testing.assert_array_equal(torch_env.curriculum.family, numpy_env.curriculum.family)
        np.testing.assert_array_equal(torch_env.starts.tile_row, numpy_env.starts.tile_row)
        for name in ("kp", "kd", "motor_strength", "motor_friction", "friction", "payload"):  # the draws
            np.testing.assert_array_equal(getattr(torch_env.params, name), getattr(numpy_env.params, name))
        terms = {}
        for name, env in (("numpy", numpy_env), ("torch", torch_env)):
            reward_of = env.core.reward

            def capture(*args, reward_of=reward_of, name=name):
                terms[name] = reward_of(*args)
                return terms[name]

            env.core.reward = capture
        rng = np.random.default_rng(0)
        for step in range(CONFIG["episode_steps"]):
            groups = numpy_env.get_observations(), torch_env.get_observations()
            assert set(groups[0].keys()) == set(groups[1].keys())
            for key in groups[0].keys():
                want, got = (g[key].numpy() for g in groups)
                np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6, err_msg=f"{key} at step {step}")
            np.testing.assert_array_equal(torch_env.core.state.q.numpy(), numpy_env.core.state.q)  # same states
            action = torch.as_tensor(rng.normal(0, 0.5, (4, 12)), dtype=torch.float32)
            if step == CONFIG["episode_steps"] - 1:  # the last step: every environment at the top level succeeds
                for env in (numpy_env, torch_env):
                    env.curriculum.level[:] = env.curriculum.max_level
                    env.core.task.success.success = env.core.task.success.success | True
            _, numpy_reward, _, _ = numpy_env.step(action)
            _, torch_reward, done, _ = torch_env.step(action)
            (_, want, _), (_, got, _) = terms["numpy"], terms["torch"]
            assert set(got) == set(want)
            for name, values in want.items():
                assert isinstance(got[name], torch.Tensor) and got[name].dtype == torch.float64
                np.testing.assert_allclose(got[name].numpy(), values, rtol=1e-10, atol=1e-12,
                                           err_msg=f"{name} at step {step}")
            np.testing.assert_allclose(torch_reward.numpy(), numpy_reward.numpy(), rtol=1e-6, atol=1e-7)
        assert bool(done.all())
        assert torch_env.last_episode_stats == numpy_env.last_episode_stats
        assert torch_env.last_episode_stats["success_all"] == 1.0
        assert torch_env.last_curriculum_stats == numpy_env.last_curriculum_stats
        means = torch_env.reward_means.means(), numpy_env.reward_means.means()
        assert means[0].keys() == means[1].keys() and means[1]
        np.testing.assert_allclose(list(means[0].values()), list(means[1].values()), rtol=1e-9, atol=2e-6)
        assert (torch_env.curriculum.level < torch_env.curriculum.max_level).any()  # redrawn from the top level
        assert torch_env.curriculum.state_dict() == numpy_env.curriculum.state_dict()  # the same redraw
        np.testing.assert_array_equal(torch_env.starts.tile_row, numpy_env.starts.tile_row)
        for name in ("kp", "kd", "motor_strength", "motor_friction"):  # the next episode's draws
            np.testing.assert_array_equal(getattr(torch_env.params, name), getattr(numpy_env.params, name))
        np.testing.assert_array_equal(torch_env.core.state.q.numpy(), numpy_env.core.state.q)
    finally:
        numpy_env.close()
        torch_env.close()


def test_the_warp_devices_float32_tensors_agree_with_its_host_arrays(monkeypatch):
    """MuJoCo Warp on its CPU device, once handing the env float32 torch tensors (training) and once float64 numpy
    copies (the CPU simulators' path): the same draws and settled states, every observation group at t = 0 and
    every reward term of the first step equal to float32 precision, the per-episode physics in the worlds."""
    import frbench.training.env as env_module

    torch_env = RecoveryTrainingEnv(TrainEnvConfig(**CONFIG, backend="mujoco-warp"), "cpu")
    monkeypatch.setattr(env_module, "DEVICE_SIMULATORS", ())  # the same simulator, its arrays on the host
    numpy_env = RecoveryTrainingEnv(TrainEnvConfig(**CONFIG, backend="mujoco-warp"))
    try:
        assert not numpy_env.device_arrays and torch_env.device_arrays and torch_env.device == "cpu"
        assert torch_env.core.state.q.dtype == torch.float32
        np.testing.assert_array_equal(torch_env.core.state.q.double().numpy(), numpy_env.core.state.q)
        p = numpy_env.params
        np.testing.assert_array_equal(torch_env.params.kp, p.kp)
        gain = torch_env.backend._fields["actuator_gainprm"][:, :12, 0].double().numpy()
        np.testing.assert_allclose(gain, p.motor_strength * p.kp, rtol=1e-6)  # written into the worlds
        groups = numpy_env.get_observations(), torch_env.get_observations()
        for key in groups[0].keys():
            np.testing.assert_allclose(groups[1][key].numpy(), groups[0][key].numpy(), rtol=2e-5, atol=2e-5,
                                       err_msg=key)
        terms = {}
        for name, env in (("numpy", numpy_env), ("torch", torch_env)):
            reward_of = env.core.reward
            env.core.reward = lambda *args, reward_of=reward_of, name=name: terms.setdefault(name, reward_of(*args))
        action = torch.as_tensor(np.random.default_rng(0).normal(0, 0.5, (4, 12)), dtype=torch.float32)
        numpy_env.step(action)
        torch_env.step(action)
        (_, want, _), (_, got, _) = terms["numpy"], terms["torch"]
        for name, values in want.items():
            assert got[name].dtype == torch.float32
            np.testing.assert_allclose(got[name].double().numpy(), values, rtol=1e-4, atol=1e-6, err_msg=name)
    finally:
        numpy_env.close()
        torch_env.close()


def test_episode_statistics_omit_families_without_environments_on_either_path():
    cfg = dict(CONFIG, num_envs=2, families=("flat", "stairs", "rough"), episode_steps=2)
    for backend, device in (("mujoco", None), ("mujoco-warp", "cpu")):
        env = RecoveryTrainingEnv(TrainEnvConfig(**cfg, backend=backend), device)
        try:
            for _ in range(2):
                env.step(torch.zeros(2, 12))
            families = {f for f in cfg["families"] if (env.curriculum.family == cfg["families"].index(f)).any()}
            assert len(families) == 2
            assert {k for k in env.last_episode_stats if k.startswith("success_") and k != "success_all"} == \
                {f"success_{f}" for f in families}, backend
            assert set(env.last_curriculum_stats) == {"level_at_max"} | {f"level_{f}" for f in families}
        finally:
            env.close()


def test_a_bundle_rebuilds_the_env_the_cpu_builds_and_episodes_begin_at_bank_starts(tmp_path):
    """The bundle's parts (robots, rasters, curriculum, generators, bank, compiled world), saved and loaded, give the
    env that `build_parts` gives: the same first observations and draws; each episode begins at a bank entry of
    its (tile, robot variant) cell, without a settle."""
    from frbench.training.device_bundle import build_bundle, bundle_parts, load_bundle, save_bundle

    cfg = TrainEnvConfig(**CONFIG, backend="mujoco-warp", start_bank=1)
    bundle = build_bundle(cfg, log=lambda *_: None)
    loaded = load_bundle(save_bundle(bundle, tmp_path / "bundle"))
    assert loaded.config == cfg and set(loaded.arrays) == set(bundle.arrays)
    assert len(loaded.arrays["bank/tile"]) == 20 * 2  # every tile, every variant once (none diverged)
    direct, from_bundle = RecoveryTrainingEnv(cfg, "cpu"), RecoveryTrainingEnv(cfg, "cpu", bundle_parts(loaded))
    try:
        for env in (direct, from_bundle):
            bank, starts = env.starts.bank, env.starts
            cell = (bank.tile[bank._order] * bank.num_variants + bank.variant[bank._order])
            assert ((bank.cell_count == 1) | (bank.cell_count == 2)).all() and len(cell) == 40
            state = env.core.state
            rows = bank.entries(np.random.default_rng(0), starts.tile_row, env.robots.assignment)
            assert (bank.tile[rows] == starts.tile_row).all()
            # each environment sits at its cell's one entry (float32 in the worlds), velocities as recorded
            np.testing.assert_allclose(state.base_pos.double().numpy(), bank.states.base_pos[rows], atol=1e-6)
            np.testing.assert_allclose(state.qd.double().numpy(), bank.states.qd[rows], atol=1e-5)
        for name in ("policy", "privileged", "mass"):
            np.testing.assert_array_equal(direct.get_observations()[name].numpy(),
                                          from_bundle.get_observations()[name].numpy())
        np.testing.assert_array_equal(direct.params.kp, from_bundle.params.kp)
        assert direct.rng.bit_generator.state == from_bundle.rng.bit_generator.state
    finally:
        direct.close()
        from_bundle.close()
    # on a machine without the CPU stack (the GPU machine's missing packages blocked), the env builds and steps
    (tmp_path / "block").mkdir()
    (tmp_path / "block" / "sitecustomize.py").write_text(
        "import importlib.abc, sys\n"
        "class Block(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path, target=None):\n"
        "        if name.split('.')[0] in ('pinocchio', 'pybullet', 'pybullet_utils', 'example_robot_data', 'gymnasium'):\n"
        "            raise ModuleNotFoundError(name)\n"
        "sys.meta_path.insert(0, Block())\n")
    code = ("import sys, torch\n"
            "from frbench.training.device_bundle import bundle_parts, load_bundle\n"
            "from frbench.training.env import RecoveryTrainingEnv\n"
            f"bundle = load_bundle({str(tmp_path / 'bundle')!r})\n"
            "env = RecoveryTrainingEnv(bundle.config, 'cpu', bundle_parts(bundle))\n"
            "obs, reward, done, _ = env.step(torch.zeros(4, 12))\n"
            "assert 'pinocchio' not in sys.modules and 'pybullet' not in sys.modules\n"
            "print(tuple(obs['privileged'].shape), bool(torch.isfinite(reward).all()))\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "block"), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "(4, 277) True"


def test_the_gpu_run_trains_from_a_bundle_of_its_own_flags():
    from tests.scripts import load_script

    cfg = load_script("tools/gpu_run/make_bundle.py", "make_bundle").training_config()
    assert (cfg.backend, cfg.num_envs, cfg.start_bank) == ("mujoco-warp", 4096, 8)
    # the recipe of the best learned records (docs/training.md, "Learning from scripted"), teacher in the env
    assert (cfg.teacher, cfg.dagger_steps, cfg.imitation_until, cfg.bodies) == ("scripted", 2e6, 12e6, "paper")


@pytest.mark.cuda
def test_a_tiny_run_on_a_cuda_device_resumes_on_the_cpu(tmp_path):
    """On a machine with CUDA: the env's tensors and the worlds on the GPU, the run's state resumed on the CPU."""
    if not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    run = tmp_path / "run"
    assert main(["train", "--backend", "mujoco-warp", "--device", "cuda", "--steps", "96", "--checkpoint-every", "1",
                 "--out", str(run), *TINY]) == 0
    assert main(["train", "--resume", str(run), "--steps", "192", "--device", "cpu", "--checkpoint-every", "1"]) == 0
    assert (run / "curve.csv").read_text().splitlines()[-1].startswith("2,192,")
