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

The graph comes from torch's current exporter (``torch.onnx.export(...,
dynamo=True)``: ``torch.export`` then onnxscript's translation, opset 18),
with a dynamic batch axis on every input and output.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Iterator

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


@contextlib.contextmanager
def quiet_onnx_exporter() -> Iterator[None]:
    """Run torch's ONNX exporter without the noise it makes on every export that no caller can avoid.

    * A ``FutureWarning`` ("`isinstance(treespec, LeafSpec)` is deprecated"): torch 2.13's
      ``ExportedProgram.run_decompositions`` deep-copies its module call graph, and copying re-creates the
      ``LeafSpec`` leaves of its tree specs, a class torch itself deprecated. It is raised inside torch for any
      model (frbench uses no ``LeafSpec``), so it is ignored here, by its message, and nowhere else.
    * Log lines "torchvision is not installed. Skipping torchvision::nms" (four, at warning level, from
      ``torch.onnx._internal.exporter._registration``): the exporter looks for torchvision's operators, which no
      frbench policy uses; that logger is raised to ERROR while the exporter runs.
    """
    import logging
    import warnings

    registration = logging.getLogger("torch.onnx._internal.exporter._registration")
    level = registration.level
    registration.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=r"`isinstance\(treespec, LeafSpec\)` is deprecated",
                                    category=FutureWarning)
            yield
    finally:
        registration.setLevel(level)


def dynamic_batch(input_names: list[str]) -> tuple[dict, ...]:
    """``dynamic_shapes`` for ``torch.onnx.export``: axis 0 of every input is the batch, named `BATCH_AXIS`.

    The first input names the axis; the others take ``Dim.DYNAMIC`` and the exporter finds them equal to it (the
    network adds them up), so every input and output of the graph gets the one axis ``batch`` (naming it on
    each input would make the exporter warn that the names collapse into one).
    """
    import torch

    return tuple({0: BATCH_AXIS if i == 0 else torch.export.Dim.DYNAMIC} for i in range(len(input_names)))


def export_onnx(policy_path: str, out: Path) -> Path:
    """Write ``out`` (.onnx) and its sidecar `sidecar_path(out)`; returns the ONNX path."""
    check_output_path(out, suffixes=(".onnx",))  # before torch is imported or anything loaded
    check_output_path(sidecar_path(out))
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
    with quiet_onnx_exporter():
        program = torch.onnx.export(model, inputs, None, export_params=True, opset_version=18, dynamo=True,
                                    input_names=input_names, output_names=output_names, verbose=False,
                                    dynamic_shapes=dynamic_batch(input_names))
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

    graph = program.model_proto
    onnx.helper.set_model_props(graph, {EMBEDDED_LAYOUT_KEY: json.dumps({"layout": layout.to_dict(),
                                                                         "robot_kind": policy.robot_kind})})
    atomic_write_bytes(out, graph.SerializeToString())
    atomic_write_text(sidecar_path(out), json.dumps(sidecar, indent=1) + "\n")
    return out
