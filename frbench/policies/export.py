"""Export a trained policy to ONNX, estimator included, so it runs without frbench.

The ONNX graph takes the raw (unnormalised) o_t ``obs`` (N, 42) and, for
estimator methods, the raw ``history`` (N, 5·42, oldest frame first) and
returns ``actions`` (N, 12), N being any batch size (a dynamic axis, named
``batch``); joint targets are q* = q̊ + action_scale · actions. The
normalisers and the Mass-Contact Predictor are inside the graph. A JSON
sidecar ``<file>.onnx.json`` (`sidecar_path`) records the conventions (input
layout, action scale, method) and, under ``"layout"``, the policy's
`frbench.policies.contract.PolicyLayout`, which ``frbench evaluate --policy
<file>.onnx`` reads; the ONNX file carries the same layout in its metadata
(key ``frbench_layout``), so that the file alone can be evaluated.
"""

from __future__ import annotations

import json
from pathlib import Path

from frbench.errors import PolicyError
from frbench.io import atomic_write_bytes, atomic_write_text, check_output_path
from frbench.policies.contract import EMBEDDED_LAYOUT_KEY, learned_layout, sidecar_path
from frbench.policies.learned import LearnedPolicy
from frbench.policies.registry import load_policy

#: Name of the dynamic batch axis of every input and output.
BATCH_AXIS = "batch"


def onnx_module(policy):
    """The torch module that is exported, its input names, output names and example inputs (batch 1)."""
    model = policy.actor.as_onnx(verbose=False)
    model.eval()
    inputs = model.get_dummy_inputs()
    inputs = inputs if isinstance(inputs, tuple) else (inputs,)
    return model, list(model.input_names), list(model.output_names), inputs


def export_onnx(policy_path: str, out: Path) -> Path:
    """Write ``out`` (.onnx) and its sidecar `sidecar_path(out)`; returns the ONNX path."""
    check_output_path(out, suffixes=(".onnx",))  # before torch is imported or anything loaded
    check_output_path(sidecar_path(out))
    import io

    import torch

    policy = load_policy(policy_path)
    if not isinstance(policy, LearnedPolicy):
        raise PolicyError(f"policy {policy_path!r} is not a trained checkpoint; only trained policies export to ONNX")
    if policy.base_controller is not None:
        raise PolicyError(f"policy {policy_path!r} is a residual over {policy.base_controller_name!r}, whose targets "
                          "come from Python code outside the network; an ONNX file would hold the residual alone. "
                          "Run it through frbench (frbench evaluate / render) instead")
    j = policy.num_actions
    model, input_names, output_names, inputs = onnx_module(policy)
    buffer = io.BytesIO()
    torch.onnx.export(model, inputs, buffer, export_params=True, opset_version=18,
                      input_names=input_names, output_names=output_names, dynamo=False,
                      dynamic_axes={name: {0: BATCH_AXIS} for name in input_names + output_names})
    layout = learned_layout(policy)
    if [i.name for i in layout.inputs] != input_names:
        raise PolicyError(f"policy {policy_path!r}: its graph inputs {input_names} are not its layout's "
                          f"{[i.name for i in layout.inputs]}")
    sidecar = {
        "method": policy.method,
        "inputs": {name: [BATCH_AXIS, *tensor.shape[1:]] for name, tensor in zip(input_names, inputs)},
        "outputs": {name: [BATCH_AXIS, j] for name in output_names},
        "observation": f"o_t = [base angular velocity (body) 3, projected gravity 3, q - q_default {j}, "
                       f"joint velocity {j}, previous action {j}]; history = last {policy.frames} o_t, oldest first",
        "action": f"joint targets q* = q_default + {policy.action_scale} * actions, in the robot's joint order"
                  + (" (canonical FL, FR, RL, RR)" if policy.robot_kind == "quadruped" else ""),
        "action_scale": policy.action_scale,
        "checkpoint": str(policy.checkpoint),
        "robot_kind": policy.robot_kind,
        "layout": layout.to_dict(),
    }
    import onnx

    graph = onnx.load_model_from_string(buffer.getvalue())
    onnx.helper.set_model_props(graph, {EMBEDDED_LAYOUT_KEY: json.dumps({"layout": layout.to_dict(),
                                                                         "robot_kind": policy.robot_kind})})
    atomic_write_bytes(out, graph.SerializeToString())
    atomic_write_text(sidecar_path(out), json.dumps(sidecar, indent=1) + "\n")
    return out
