"""Export a trained policy to ONNX, estimator included, so it runs without frbench.

The ONNX graph takes the raw (unnormalised) o_t ``obs`` (1, 42) and, for
estimator methods, the raw ``history`` (1, 5·42, oldest frame first) and
returns ``actions`` (1, 12); joint targets are q* = q̊ + action_scale · actions.
The normalisers and the Mass-Contact Predictor are inside the graph. A JSON
sidecar records the conventions (input layout, action scale, method).
"""

from __future__ import annotations

import json
from pathlib import Path

from frbench.errors import PolicyError


def export_onnx(policy_path: str, out: Path) -> Path:
    """Write ``out`` (.onnx) and ``out`` with suffix .json; returns the ONNX path."""
    import torch

    from frbench.io import atomic_write_text
    from frbench.policies.learned import LearnedPolicy
    from frbench.policies.registry import load_policy

    policy = load_policy(policy_path)
    if not isinstance(policy, LearnedPolicy):
        raise PolicyError(f"policy {policy_path!r} is not a trained checkpoint; only trained policies export to ONNX")
    if policy.base_controller is not None:
        raise PolicyError(f"policy {policy_path!r} is a residual over {policy.base_controller_name!r}, whose targets "
                          "come from Python code outside the network; an ONNX file would hold the residual alone. "
                          "Run it through frbench (frbench evaluate / render) instead")
    if out.suffix != ".onnx":
        raise PolicyError(f"--out {out}: expected a .onnx file")
    j = policy.num_actions
    model = policy.actor.as_onnx(verbose=False)
    model.eval()
    out.parent.mkdir(parents=True, exist_ok=True)
    inputs = model.get_dummy_inputs()
    torch.onnx.export(model, inputs, str(out), export_params=True, opset_version=18,
                      input_names=model.input_names, output_names=model.output_names, dynamo=False)
    sidecar = {
        "method": policy.method,
        "inputs": {name: list(tensor.shape) for name, tensor in zip(model.input_names, inputs)},
        "observation": f"o_t = [base angular velocity (body) 3, projected gravity 3, q - q_default {j}, "
                       f"joint velocity {j}, previous action {j}]; history = last {policy.frames} o_t, oldest first",
        "action": f"joint targets q* = q_default + {policy.action_scale} * actions, in the robot's joint order"
                  + (" (canonical FL, FR, RL, RR)" if policy.robot_kind == "quadruped" else ""),
        "checkpoint": str(policy.checkpoint),
    }
    atomic_write_text(out.with_suffix(".json"), json.dumps(sidecar, indent=1) + "\n")
    return out
