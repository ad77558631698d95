"""TorchScript policies: a module saved with ``torch.jit.save``, called as ``module(*inputs) -> actions``.

The layout comes from ``--spec FILE``, else the sidecar ``<file>.json`` beside
it (``policy.pt`` → ``policy.pt.json``), else the extra file
``frbench_layout.json`` saved in the archive (``torch.jit.save(module, path,
_extra_files={"frbench_layout.json": layout_json})``), else frbench's default
`PolicyLayout`.
The module gets one float32 tensor (N, width) per layout input, in the layout's
order, and returns actions (N, J) (or a tuple whose first element they are).
Such files come from other training setups (legged_gym's ``play.py`` traces its
actor and saves it; rsl-rl's ``export_policy_to_jit`` scripts it). torch 2.13
deprecates TorchScript but still reads it; frbench reads these files and writes
none (its own export is ONNX, `frbench.policies.export`).
"""

from __future__ import annotations

import warnings
import zipfile
from pathlib import Path

import numpy as np

from frbench.errors import PolicyError
from frbench.policies.contract import EMBEDDED_LAYOUT_KEY, PolicyLayout
from frbench.policies.layout_policy import LayoutPolicy, model_layout, safe_name


def is_torchscript_archive(path: Path) -> bool:
    """Whether ``path`` is a ``torch.jit.save`` archive (a zip with the module's ``code/`` and constants)."""
    try:
        with zipfile.ZipFile(path) as archive:
            return any(name.endswith("/constants.pkl") or "/code/" in name for name in archive.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


class TorchScriptPolicy(LayoutPolicy):
    """A TorchScript module driven through its layout (torch's thread count is the caller's)."""

    def __init__(self, path: Path, layout: PolicyLayout, module, kind: str | None = None):
        super().__init__(safe_name(path.stem), path, layout, kind)
        self.module = module

    def forward(self, inputs: dict[str, np.ndarray]) -> np.ndarray:
        """``module(*inputs)`` (the first element of a tuple output) as an array."""
        import torch

        tensors = [torch.from_numpy(inputs[i.name]) for i in self.layout.inputs]
        try:
            with torch.inference_mode():
                out = self.module(*tensors)
        except Exception as exc:  # TorchScript raises RuntimeError and its own types for bad inputs
            message = next((line.strip() for line in str(exc).splitlines() if line.strip()), "")
            raise PolicyError(f"{self.who}: the module does not take the layout's inputs {self.expected()} "
                              f"({type(exc).__name__}: {message[:200]})") from None
        if isinstance(out, (tuple, list)) and out:
            out = out[0]
        if not isinstance(out, torch.Tensor):
            raise PolicyError(f"{self.who}: the module returned {type(out).__name__}, expected a tensor "
                              f"{self.expected()}")
        return out.detach().numpy()


def load_torchscript_policy(path: Path, layout_file: str | None = None) -> TorchScriptPolicy:
    """The TorchScript module at ``path`` with the layout of ``layout_file``, its sidecar or the default."""
    import torch

    extra = {f"{EMBEDDED_LAYOUT_KEY}.json": ""}
    try:
        with warnings.catch_warnings():
            # torch 2.13 deprecates torch.jit.load in favour of torch.export, which cannot read a TorchScript file:
            # a user's TorchScript policy is what their training setup wrote, and reading it is why this loader
            # exists. The deprecation is torch's notice to the file's author, not something the reader can act on.
            warnings.filterwarnings("ignore", message=r"`torch\.jit\.load` is deprecated", category=DeprecationWarning)
            module = torch.jit.load(str(path), map_location="cpu", _extra_files=extra)
    except Exception as exc:  # torch raises many types for unreadable archives
        raise PolicyError(f"{path}: not a loadable TorchScript module ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0][:200] if str(exc) else ''})") from None
    module.eval()
    embedded = extra[f"{EMBEDDED_LAYOUT_KEY}.json"]
    layout, kind = model_layout(path, layout_file, embedded.decode() if isinstance(embedded, bytes) else embedded)
    return TorchScriptPolicy(path, layout, module, kind)
