"""ONNX policies, run with onnxruntime: frbench's own export or any network exported to ONNX.

The layout comes from ``--spec FILE``, else the sidecar ``<file>.onnx.json``,
else the model's metadata (``metadata_props`` key ``frbench_layout``: the JSON
of a layout; ``frbench export`` writes both), else frbench's default
`PolicyLayout` (one input, the 42-value o_t of a quadruped, normalised actions
q* = q_default + 1.0 · a). Layout inputs are matched to the graph's inputs by
name, or by position when both have one input. Inputs are cast to the graph's
float type (float32, float64 or float16); the first output is the action. A
graph whose batch axis is fixed to 1 (``torch.onnx.export`` without dynamic
axes) is run one environment at a time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from frbench.errors import PolicyError
from frbench.policies.contract import EMBEDDED_LAYOUT_KEY, Contract, PolicyLayout
from frbench.policies.layout_policy import LayoutPolicy, model_layout, safe_name

#: onnxruntime's tensor types that a layout's float inputs may be cast to.
FLOAT_TYPES = {"tensor(float)": np.float32, "tensor(double)": np.float64, "tensor(float16)": np.float16}


def import_onnxruntime():
    """The onnxruntime module, or a one-line `PolicyError` saying how to install it."""
    try:
        import onnxruntime
    except ImportError:
        raise PolicyError("ONNX policies run with onnxruntime, which is not installed: "
                          "pip install 'frbench[onnx]'") from None
    return onnxruntime


class OnnxPolicy(LayoutPolicy):
    """An ONNX network (one onnxruntime session on one thread) driven through its layout."""

    def __init__(self, path: Path, layout: PolicyLayout, session, kind: str | None = None):
        super().__init__(safe_name(path.stem), path, layout, kind)
        self.session = session
        self.graph_inputs = {i.name: i for i in session.get_inputs()}
        self.output = session.get_outputs()[0].name
        #: A graph exported without a dynamic batch axis (batch fixed to 1) runs environment by environment.
        self.one_row = all(list(i.shape)[:1] == [1] for i in self.graph_inputs.values())

    def _graph_name(self, name: str) -> str:
        """The graph input that feeds layout input ``name``."""
        if name in self.graph_inputs:
            return name
        if len(self.graph_inputs) == 1 and len(self.layout.inputs) == 1:
            return next(iter(self.graph_inputs))
        raise PolicyError(f"{self.who}: the layout's input {name!r} is not an input of the graph "
                          f"(graph inputs: {', '.join(self.graph_inputs)})")

    def check(self, contract: Contract) -> None:
        """Input names, ranks, float types and widths against the layout, then a dry run."""
        n, layout = contract.n_joints, contract.layout
        self._contract = contract
        expected = self.expected()
        fed = set()
        for name, width in layout.input_sizes(n).items():
            graph = self.graph_inputs[self._graph_name(name)]
            fed.add(graph.name)
            if graph.type not in FLOAT_TYPES:
                raise PolicyError(f"{self.who}: graph input {graph.name!r} has type {graph.type}, expected a float "
                                  f"tensor {expected}")
            shape = list(graph.shape)
            if len(shape) != 2 or (isinstance(shape[-1], int) and shape[-1] != width):
                raise PolicyError(f"{self.who}: graph input {graph.name!r} has shape {shape}, expected (N, {width}) "
                                  f"for robot {contract.robot!r} {expected}")
        missing = sorted(set(self.graph_inputs) - fed)
        if missing:
            raise PolicyError(f"{self.who}: graph input {missing[0]!r} is not in the layout {expected}")
        super().check(contract)

    def forward(self, inputs: dict[str, np.ndarray]) -> np.ndarray:
        """The graph's first output for the inputs (cast to the graph's float types)."""
        feeds = {}
        for name, values in inputs.items():
            graph = self.graph_inputs[self._graph_name(name)]
            feeds[graph.name] = values.astype(FLOAT_TYPES.get(graph.type, np.float32), copy=False)
        try:
            if self.one_row:
                rows = len(next(iter(feeds.values())))
                return np.concatenate([self.session.run([self.output], {name: value[k:k + 1] for name, value in
                                                                        feeds.items()})[0] for k in range(rows)])
            return self.session.run([self.output], feeds)[0]
        except Exception as exc:  # onnxruntime raises its own types for bad feeds
            raise PolicyError(f"{self.who}: onnxruntime failed on the layout's inputs {self.expected()} "
                              f"({type(exc).__name__}: {str(exc).splitlines()[0][:200]})") from None


def load_onnx_policy(path: Path, layout_file: str | None = None) -> OnnxPolicy:
    """The ONNX policy at ``path`` with the layout of ``layout_file``, its sidecar or the default."""
    ort = import_onnxruntime()
    options = ort.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1  # one core per evaluation worker
    options.log_severity_level = 3
    try:
        session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own types for unreadable models
        raise PolicyError(f"{path}: not a readable ONNX model ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0][:200] if str(exc) else ''})") from None
    embedded = session.get_modelmeta().custom_metadata_map.get(EMBEDDED_LAYOUT_KEY)
    layout, kind = model_layout(path, layout_file, embedded)
    return OnnxPolicy(path, layout, session, kind)
