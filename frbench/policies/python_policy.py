"""Python policies named ``module:attr`` or ``path/to/file.py:attr``, with a small protocol.

``attr`` is a class (built with no arguments), an object or a function. Its
optional attributes and methods:

* ``layout``: a `PolicyLayout` or its dict (default: frbench's, one input, the
  42-value o_t of a quadruped; ``--spec FILE`` overrides it);
* ``batched`` (default True): ``act`` gets all environments at once, (N, F),
  and returns (N, J); False: one environment, (F,) → (J,), each environment
  with its own copy of the object (a new instance of a class, else a deep copy);
* ``reset(info)``: at the start of every batch of episodes; ``info`` is a dict
  with ``num_envs`` (1 for an unbatched policy), ``robot`` and ``contract`` (the
  `Contract` as ``frbench spec --json`` prints it);
* ``act(obs) -> action`` (a function is its own ``act``): ``obs`` is a float32
  array of the layout's input (a dict name → array when it has several);
  ``action`` follows the layout's convention: normalised actions a
  (q* = q_default + action_scale · a) or joint targets q* [rad], in the
  layout's joint order.

An object that already implements frbench's own policy protocol (``supports``,
``reset(spec, num_envs)``, ``act(obs_dict)``; `frbench.policies.base.Policy`)
is used as it is. A module is imported from ``sys.path`` or, failing that, from
the current folder; a file is run as a module with its folder on ``sys.path``.
An exception raised by the policy's code is reported on one line with its file and line.
"""

from __future__ import annotations

import copy
import hashlib
import importlib
import importlib.util
import re
import sys
import traceback
from pathlib import Path

import numpy as np

from frbench.errors import PolicyError
from frbench.policies.contract import Contract, PolicyLayout, read_layout
from frbench.policies.layout_policy import LayoutPolicy, safe_name

#: ``target:attr`` where target is a dotted module name or a ``.py`` file and attr a dotted attribute path.
REFERENCE = re.compile(r"^(?P<target>.+?):(?P<attr>[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)$")
MODULE = re.compile(r"^[A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*$")


def parse_python_reference(reference: str) -> tuple[str, str] | None:
    """(target, attr) of a ``module:attr`` or ``file.py:attr`` reference; None for anything else."""
    match = REFERENCE.match(reference)
    if not match or not (match["target"].endswith(".py") or MODULE.match(match["target"])):
        return None
    return match["target"], match["attr"]


def _where(exc: BaseException) -> str:
    """``file:line`` of the innermost frame of an exception (the user's code)."""
    frames = traceback.extract_tb(exc.__traceback__)
    return f" at {Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else ""


def _user_error(who: str, what: str, exc: BaseException) -> PolicyError:
    message = next((line for line in str(exc).splitlines() if line.strip()), "")
    return PolicyError(f"{who}: {what} raised {type(exc).__name__}{_where(exc)}: {message[:200]}")


def _import_file(path: Path):
    if not path.is_file():
        raise PolicyError(f"{path}: no such Python file")
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:12]
    name = f"frbench_user_{safe_name(path.stem).replace('-', '_').replace('.', '_')}_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    module_spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(module_spec)
    if str(path.parent) not in sys.path:
        sys.path.insert(0, str(path.parent))  # its sibling modules import as they would when run as a script
    sys.modules[name] = module
    try:
        module_spec.loader.exec_module(module)
    except Exception as exc:  # the user's module: any error, reported on one line
        del sys.modules[name]
        raise _user_error(str(path), "importing it", exc) from None
    return module


def _import_module(name: str):
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name.split(".")[0] or "" in sys.path:
            raise PolicyError(f"cannot import module {name!r} ({exc})") from None
    sys.path.append("")  # the current folder, as `python -m` would have it
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        raise PolicyError(f"cannot import module {name!r} ({exc}); it must be importable from sys.path or the "
                          "current folder") from None


def resolve_target(reference: str):
    """The object a ``module:attr`` / ``file.py:attr`` reference names, and the file (or None for a module)."""
    target, attr = parse_python_reference(reference)
    file = Path(target).resolve() if target.endswith(".py") else None
    try:
        module = _import_file(file) if file else _import_module(target)
    except PolicyError:
        raise
    except Exception as exc:
        raise _user_error(target, "importing it", exc) from None
    obj = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise PolicyError(f"{target}: has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj, file


class PythonPolicy(LayoutPolicy):
    """A Python object with ``act`` (and optionally ``reset``, ``layout``, ``batched``), module docstring."""

    def __init__(self, name: str, file: Path | None, layout: PolicyLayout, target, instance, batched: bool):
        super().__init__(name, file, layout)
        self.target, self.instance, self.batched = target, instance, batched
        self.copies = [instance]

    def _call(self, obj, method: str, *args):
        function = obj if method == "act" and not hasattr(obj, "act") else getattr(obj, method)
        try:
            return function(*args)
        except PolicyError:
            raise
        except Exception as exc:  # the user's code: any error, reported on one line with its file and line
            raise _user_error(self.who, method, exc) from None

    def start(self, contract: Contract, num_envs: int) -> None:
        """Call ``reset(info)``; an unbatched policy gets one object per environment."""
        if not self.batched:
            make = self.target if isinstance(self.target, type) else (lambda: copy.deepcopy(self.instance))
            try:
                self.copies = [make() for _ in range(num_envs)]
            except Exception as exc:
                raise _user_error(self.who, "making one copy per environment", exc) from None
        info = {"num_envs": num_envs if self.batched else 1, "robot": contract.robot, "contract": contract.to_dict()}
        for obj in self.copies:
            if hasattr(obj, "reset"):
                self._call(obj, "reset", info)

    def check(self, contract: Contract) -> None:
        """A dry run of one environment (after ``reset``)."""
        self.start(contract, 1)
        super().check(contract)

    def forward(self, inputs: dict[str, np.ndarray]) -> np.ndarray:
        """``act`` of the inputs: all environments at once, or environment by environment."""
        obs = next(iter(inputs.values())) if len(inputs) == 1 else inputs
        if self.batched:
            out = self._call(self.instance, "act", obs)
            if np.ndim(out) == 1:
                raise PolicyError(f"{self.who}: act returned one environment's action {np.shape(out)} for a batch "
                                  f"{self.expected()}; return (N, J), or set batched = False on a single-environment "
                                  "policy")
            return out
        rows = []
        for k, obj in enumerate(self.copies):
            row = obs[k] if isinstance(obs, np.ndarray) else {name: value[k] for name, value in obs.items()}
            rows.append(np.asarray(self._call(obj, "act", row)))
        if any(r.shape != rows[0].shape for r in rows):
            raise PolicyError(f"{self.who}: act returned actions of different shapes {self.expected()}")
        return np.stack(rows)


def load_python_policy(reference: str, layout_file: str | None = None):
    """The policy a ``module:attr`` / ``file.py:attr`` reference names (module docstring)."""
    target, file = resolve_target(reference)
    if isinstance(target, type):
        try:
            instance = target()
        except Exception as exc:
            raise _user_error(reference, f"{target.__name__}()", exc) from None
    elif callable(target) or hasattr(target, "act"):
        instance = target
    else:
        raise PolicyError(f"{reference}: {type(target).__name__} is neither a class, a function nor an object "
                          "with act(obs)")
    if all(hasattr(instance, a) for a in ("supports", "reset", "act")) and not hasattr(instance, "layout"):
        if not hasattr(instance, "name"):
            instance.name = safe_name(reference.rpartition(":")[2])
        return instance  # frbench's own policy protocol
    if layout_file:
        layout = read_layout(layout_file)
    else:
        declared = getattr(instance, "layout", None)
        layout = declared if isinstance(declared, PolicyLayout) else (
            PolicyLayout.from_dict(declared, f"{reference}: layout") if declared is not None else PolicyLayout())
    stem = Path(reference.rpartition(":")[0]).stem
    name = getattr(instance, "name", None)
    name = safe_name(name if isinstance(name, str) and name else f"{stem}-{reference.rpartition(':')[2]}")
    return PythonPolicy(name, file, layout, target, instance, bool(getattr(instance, "batched", True)))
