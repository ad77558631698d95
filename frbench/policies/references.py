"""Policy references for policies trained anywhere: which kind a reference names, and its layout file.

A policy reference is the string ``frbench evaluate --policy`` takes and ships
to every worker (a process of the pool or a Ray task), where
`frbench.policies.registry.load_policy` turns it into a policy. Besides
frbench's names, checkpoints and plugins, it may name:

* an ONNX file (``*.onnx``, `frbench.policies.onnx_policy`);
* a TorchScript file (a ``torch.jit.save`` archive, any suffix; `frbench.policies.torchscript_policy`);
* a Stable-Baselines3 model (a ``model.save`` zip; `frbench.policies.sb3_policy`);
* a Python policy, ``module:attr`` or ``path/to/file.py:attr`` (`frbench.policies.python_policy`).

A layout file (``--spec FILE``) travels inside the reference as
``REFERENCE?spec=FILE`` (`with_layout`). `resolve_reference` makes a ``.py``
file and the layout file absolute before the reference is shipped.
"""

from __future__ import annotations

from pathlib import Path

from frbench.errors import PolicyError
from frbench.policies.onnx_policy import load_onnx_policy
from frbench.policies.python_policy import load_python_policy, parse_python_reference
from frbench.policies.sb3_policy import is_sb3_zip, load_sb3_policy
from frbench.policies.torchscript_policy import is_torchscript_archive, load_torchscript_policy

#: What separates a reference from its layout file.
LAYOUT_SEPARATOR = "?spec="
#: The kinds of policy trained elsewhere that `load_foreign_policy` loads.
FOREIGN_KINDS = ("onnx", "torchscript", "sb3", "python")


def split_reference(reference: str) -> tuple[str, str | None]:
    """(the policy reference, its layout file or None)."""
    base, separator, layout = reference.partition(LAYOUT_SEPARATOR)
    return (base, layout) if separator else (reference, None)


def with_layout(reference: str, layout_file: str | Path | None) -> str:
    """``reference`` carrying ``layout_file`` (unchanged when None)."""
    return reference if layout_file is None else f"{reference}{LAYOUT_SEPARATOR}{layout_file}"


def foreign_kind(reference: str) -> str | None:
    """The kind of policy trained elsewhere that ``reference`` (without a layout file) names, or None."""
    path = Path(reference)
    if path.suffix.lower() == ".onnx":
        return "onnx"
    if path.is_file():
        if is_torchscript_archive(path):
            return "torchscript"
        if is_sb3_zip(path):
            return "sb3"
        return None
    if parse_python_reference(reference):
        return "python"
    return None


def resolve_reference(reference: str, layout_file: str | Path | None = None) -> str:
    """The reference to ship to workers: a ``file.py:attr`` file and the layout file made absolute; a
    layout file must exist and is refused for policies that take none.

    Raises:
        PolicyError: a missing layout file, or a layout file for a policy that is not trained elsewhere.
    """
    base, carried = split_reference(reference)
    layout_file = layout_file if layout_file is not None else carried
    parsed = parse_python_reference(base)
    if parsed and parsed[0].endswith(".py"):
        base = f"{Path(parsed[0]).resolve()}:{parsed[1]}"
    if layout_file is None:
        return base
    layout_path = Path(layout_file)
    if not layout_path.is_file():
        raise PolicyError(f"--spec {layout_file}: no such layout file")
    if foreign_kind(base) is None:
        raise PolicyError(f"--spec {layout_file}: a layout applies to ONNX, TorchScript, Stable-Baselines3 and Python "
                          f"policies, not to {base!r}")
    return with_layout(base, layout_path.resolve())


def load_foreign_policy(reference: str):
    """The policy trained elsewhere that ``reference`` names, or None if it names none (module docstring)."""
    base, layout_file = split_reference(reference)
    kind = foreign_kind(base)
    if kind is None:
        if layout_file is not None:
            raise PolicyError(f"{reference}: a layout (?spec=) applies to ONNX, TorchScript, Stable-Baselines3 and "
                              f"Python policies only")
        return None
    path = Path(base)
    if kind == "onnx":
        if not path.is_file():
            raise PolicyError(f"{base}: no such ONNX file")
        return load_onnx_policy(path, layout_file)
    if kind == "torchscript":
        return load_torchscript_policy(path, layout_file)
    if kind == "sb3":
        return load_sb3_policy(path, layout_file)
    return load_python_policy(base, layout_file)
