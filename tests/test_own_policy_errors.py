"""Policies trained elsewhere that do not fit: a wrong input size, dtype or action count, a broken file, a
missing library. Each is one line on stderr naming the expected layout, with exit status 2, and writes nothing."""

from __future__ import annotations

import sys

import pytest

from frbench.cli import main
from policy_factory import CELL, POLICY_FILE, export_onnx, mlp, writing_torchscript

pytest.importorskip("onnxruntime")

#: The one-line form of frbench's default layout on Go2, as errors name it.
LAYOUT = "inputs obs (N, 42) float32, frame [base_angvel 3, projected_gravity 3, joint_pos 12, joint_vel 12"


def _refused(tmp_path, capsys, policy: str, *extra: str) -> str:
    """Evaluate ``policy`` and expect a one-line error with status 2 and no results; the error line."""
    out = tmp_path / "results" / "r.json"
    assert main(["evaluate", "--policy", policy, *CELL, "--backends", "mujoco", "--episodes", "1", "--jobs", "1",
                 "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("frbench evaluate: error: ") and "Traceback" not in err
    assert not out.parent.exists()
    return err


def _torchscript(model, path, inputs: int = 42):
    import torch

    with writing_torchscript():
        torch.jit.save(torch.jit.trace(model, torch.zeros(1, inputs)), str(path))
    return path


@pytest.mark.parametrize("case, message", [
    ("onnx-40-inputs", "has shape [1, 40], expected (N, 42) for robot 'go2'"),
    ("onnx-10-actions", "returned actions of shape (1, 10) (10 per environment), expected (1, 12) for robot 'go2'"),
    ("onnx-int64-input", "graph input 'obs' has type tensor(int64), expected a float tensor"),
    ("onnx-two-inputs", "graph input 'history' is not in the layout"),
    ("torchscript-40-inputs", "the module does not take the layout's inputs"),
    ("torchscript-10-actions", "returned actions of shape (1, 10)"),
])
def test_a_model_of_the_wrong_size_or_dtype_names_the_expected_layout(tmp_path, capsys, case, message):
    import torch

    if case == "onnx-40-inputs":
        path = export_onnx(mlp(inputs=40), tmp_path / "m.onnx", inputs=40)
    elif case == "onnx-10-actions":
        path = export_onnx(mlp(outputs=10), tmp_path / "m.onnx")
    elif case == "onnx-int64-input":
        class Ints(torch.nn.Module):
            def forward(self, obs):
                return obs[:, :12].float()

        path = export_onnx(Ints(), tmp_path / "m.onnx", dynamic_batch=True, dtype=torch.int64)
    elif case == "onnx-two-inputs":
        class Two(torch.nn.Module):
            def forward(self, obs, history):
                return obs[:, :12] + history[:, :12]

        path = export_onnx(Two(), tmp_path / "m.onnx", example=(torch.zeros(1, 42), torch.zeros(1, 210)),
                           input_names=["obs", "history"])
    elif case == "torchscript-40-inputs":
        path = _torchscript(mlp(inputs=40), tmp_path / "m.pt", inputs=40)
    else:
        path = _torchscript(mlp(outputs=10), tmp_path / "m.pt")
    err = _refused(tmp_path, capsys, str(path))
    assert message in err and LAYOUT in err


@pytest.mark.parametrize("attr, message", [
    ("ten_actions", "returned actions of shape (1, 10) (10 per environment), expected (1, 12)"),
    ("words", "returned actions of dtype <U2, expected float (N, 12)"),
    ("one_row", "act returned one environment's action (12,) for a batch"),
    ("crashes", "act raised IndexError at my_policy.py:"),
    ("Nothing", "has no attribute 'Nothing'"),
])
def test_a_python_policy_that_does_not_fit_is_one_line(tmp_path, capsys, attr, message):
    (tmp_path / "my_policy.py").write_text(POLICY_FILE)
    err = _refused(tmp_path, capsys, f"{tmp_path / 'my_policy.py'}:{attr}")
    assert message in err


def test_broken_python_files_and_modules_are_one_line(tmp_path, capsys):
    (tmp_path / "broken.py").write_text("import numpy as np\ndef act(obs):\n    return np.zeros(12\n")
    assert "importing it raised SyntaxError" in _refused(tmp_path, capsys, f"{tmp_path / 'broken.py'}:act")
    assert "no such Python file" in _refused(tmp_path, capsys, f"{tmp_path / 'absent.py'}:act")
    assert "cannot import module 'no_such_module_frb'" in _refused(tmp_path, capsys, "no_such_module_frb:Policy")


def test_a_wrong_sb3_model_and_a_missing_sb3_are_one_line(tmp_path, capsys, monkeypatch):
    pytest.importorskip("stable_baselines3")
    import gymnasium
    import numpy as np
    from stable_baselines3 import PPO

    class Forty(gymnasium.Env):
        observation_space = gymnasium.spaces.Box(-1.0, 1.0, (40,), np.float32)
        action_space = gymnasium.spaces.Box(-1.0, 1.0, (12,), np.float32)

    PPO("MlpPolicy", Forty(), n_steps=8, batch_size=8, device="cpu", policy_kwargs={"net_arch": [8]}).save(
        tmp_path / "forty.zip")
    capsys.readouterr()
    err = _refused(tmp_path, capsys, str(tmp_path / "forty.zip"))
    assert "the model's observation space is (40,) float32, expected (42,) float32" in err
    assert "previous_target 12" in err  # the gym environment's layout
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    monkeypatch.setitem(sys.modules, "stable_baselines3.common.save_util", None)
    assert "stable-baselines3 is not installed: pip install 'frbench[sb3]'" in _refused(tmp_path, capsys,
                                                                                         str(tmp_path / "forty.zip"))


def test_unreadable_models_and_misplaced_layout_files_are_one_line(tmp_path, capsys):
    (tmp_path / "garbage.onnx").write_bytes(b"not a protobuf")
    assert "not a readable ONNX model" in _refused(tmp_path, capsys, str(tmp_path / "garbage.onnx"))
    assert "no such ONNX file" in _refused(tmp_path, capsys, str(tmp_path / "absent.onnx"))
    layout = tmp_path / "layout.json"
    layout.write_text('{"action_scale": 0.25}')
    assert "a layout applies to ONNX, TorchScript" in _refused(tmp_path, capsys, "zero", "--spec", str(layout))
    assert "no such layout file" in _refused(tmp_path, capsys, "zero", "--spec", str(tmp_path / "absent.json"))
    model = export_onnx(mlp(), tmp_path / "m.onnx")
    layout.write_text('{"observation": ["base_angvel", "joint_vel"]}')
    err = _refused(tmp_path, capsys, str(model), "--spec", str(layout))
    assert "expected (N, 15) for robot 'go2' [inputs obs (N, 15) float32, frame [base_angvel 3, joint_vel 12]" in err
