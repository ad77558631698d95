"""Policies trained elsewhere under ``--executor ray``: the reference shipped to the workers (an ONNX file with its
layout file, a ``file.py:attr`` made absolute) gives the local executor's episodes."""

from __future__ import annotations

import json

import pytest

ray = pytest.importorskip("ray")
pytest.importorskip("onnxruntime")

from frbench.policies.references import resolve_reference  # noqa: E402
from policy_factory import POLICY_FILE, evaluate, export_onnx, mlp  # noqa: E402
from test_ray_executor import ray_instance  # noqa: E402, F401  (a 2-CPU local instance for this module)


def test_onnx_with_a_layout_file_and_a_python_file_run_on_ray_as_locally(ray_instance, tmp_path, monkeypatch):
    model = export_onnx(mlp(inputs=45, seed=5), tmp_path / "commands.onnx", inputs=45, dynamic_batch=True)
    layout = tmp_path / "layout.json"  # legged_gym-like: scaled velocities, three zero commands in the middle
    layout.write_text(json.dumps({"observation": [
        {"name": "base_angvel", "scale": 0.25}, "projected_gravity", {"name": "constant", "size": 3, "value": 0.0},
        "joint_pos", {"name": "joint_vel", "scale": 0.05}, "previous_action"], "action_scale": 0.25}))
    (tmp_path / "my_policy.py").write_text(POLICY_FILE)
    monkeypatch.chdir(tmp_path)
    assert resolve_reference("my_policy.py:Zero") == f"{tmp_path / 'my_policy.py'}:Zero"
    for policy, extra in ((str(model), ("--spec", "layout.json")), ("my_policy.py:Single", ())):
        local = evaluate(tmp_path / "local.json", policy, *extra)
        on_ray = evaluate(tmp_path / "ray.json", policy, *extra, "--executor", "ray")
        assert len(on_ray["episodes"]) == 4 and on_ray["episodes"] == local["episodes"]
        assert on_ray["config"]["policy"] == local["config"]["policy"]
    assert local["config"]["policy"] == f"{tmp_path / 'my_policy.py'}:Single"
    assert on_ray["config"]["policy"].startswith(str(tmp_path))
