"""ONNX export: a dynamic batch axis, the ``<file>.onnx.json`` sidecar, and onnxruntime agreeing with torch."""

import json

import numpy as np
import pytest

from frbench.cli import main

ort = pytest.importorskip("onnxruntime")


@pytest.mark.parametrize("name", ["frnet", "ppo-3m"])
def test_exported_policy_runs_in_onnxruntime_at_batch_1_and_64_like_torch(tmp_path, capsys, name):
    import torch

    from frbench.policies.export import onnx_module
    from frbench.policies.registry import load_policy

    out = tmp_path / f"{name}.onnx"
    results = tmp_path / f"{name}.json"  # where `evaluate` would write: the export must not touch it
    results.write_text("results")
    assert main(["export", "--policy", name, "--out", str(out)]) == 0
    sidecar = json.loads((tmp_path / f"{name}.onnx.json").read_text())
    assert results.read_text() == "results"
    assert sidecar["inputs"]["obs"] == ["batch", 42] and sidecar["outputs"]["actions"] == ["batch", 12]
    assert sidecar["action_scale"] == 1.0 and "q* = q_default + 1.0 * actions" in sidecar["action"]

    model, input_names, output_names, examples = onnx_module(load_policy(name))
    session = ort.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    assert [i.name for i in session.get_inputs()] == input_names
    assert all(i.shape[0] == "batch" for i in session.get_inputs())
    rng = np.random.default_rng(0)
    for batch in (1, 64):
        feeds = {n: rng.normal(0.0, 1.0, (batch, *e.shape[1:])).astype(np.float32) for n, e in zip(input_names, examples)}
        (onnx_actions,) = session.run(output_names, feeds)
        with torch.no_grad():
            torch_actions = model(*(torch.from_numpy(feeds[n]) for n in input_names)).numpy()
        assert onnx_actions.shape == (batch, 12)
        largest = float(np.abs(onnx_actions - torch_actions).max())
        print(f"{name} batch {batch}: largest |onnxruntime - torch| = {largest:.2e}")
        assert largest < 1e-4
