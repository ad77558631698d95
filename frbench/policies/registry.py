"""Find policies by name, checkpoint path, or plugin.

``load_policy(name_or_path)``:

1. a built-in name (`BUILTIN_POLICIES`, imported on first use);
2. a policy trained elsewhere: an ONNX, TorchScript or Stable-Baselines3 file, or a ``module:attr`` /
   ``file.py:attr`` Python policy, optionally with a layout file (`frbench.policies.references`);
3. an existing file or run folder → :func:`frbench.policies.checkpoint.load_checkpoint_policy`;
4. a plugin: an entry point of group ``frbench.policies`` loading to a
   zero-argument callable that returns a policy (read only on a miss, or
   when listing).
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from pathlib import Path

from frbench.errors import PolicyError, unknown_name
from frbench.policies.checkpoint import CHECKPOINT_FORMAT, load_checkpoint_policy, resolve_checkpoint_file
from frbench.policies.references import load_foreign_policy

ENTRY_POINT_GROUP = "frbench.policies"

#: Built-in policies: name → "module:Class" (a zero-argument constructor).
BUILTIN_POLICIES = {
    "zero": "frbench.policies.zero:ZeroPolicy",
    "scripted": "frbench.policies.scripted:ScriptedPolicy",
    "scripted-humanoid": "frbench.policies.scripted_humanoid:HumanoidScriptedPolicy",
    "keyframe-humanoid": "frbench.policies.keyframe_humanoid:KeyframeHumanoidPolicy",
    "mpc": "frbench.policies.mpc:MpcPolicy",
}


def _construct(target: str):
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)()


def plugin_policies() -> dict:
    """Installed plugins: name → entry point."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def policy_names() -> list[str]:
    """Built-in, shipped (when present) and plugin policy names."""
    shipped = [n for n in SHIPPED_CHECKPOINTS if shipped_checkpoint(n).is_file()]
    builtin = [*BUILTIN_POLICIES, *shipped]
    return [*builtin, *(n for n in plugin_policies() if n not in builtin)]


#: The methods of the equal-budget comparison (3.07 M env steps each; RMA's adaptation module then 0.5 M more with
#: its phase-1 policy frozen; checkpoints/budget3m/README.md).
BUDGET_3M_POLICIES = ("frnet-3m", "frnet-no-mass-3m", "frnet-no-contact-3m", "frnet-no-est-3m", "dreamriser-3m",
                      "rma-adaptation-3m", "ppo-3m", "frnet-no-stability-3m")

#: Trained policies shipped with frbench: name → checkpoint file inside the package.
SHIPPED_CHECKPOINTS = {"frnet": "checkpoints/frnet.pt",
                       **{name: f"checkpoints/budget3m/{name}.pt" for name in BUDGET_3M_POLICIES},
                       "mpc-distilled-g1": "checkpoints/mpc-distilled-g1.pt"}


def shipped_checkpoint(name: str) -> Path:
    """Path of a shipped checkpoint (it may not exist yet in a development checkout)."""
    return Path(__file__).resolve().parent / SHIPPED_CHECKPOINTS[name]


def load_base_controller(name: str, parameters: dict | None = None):
    """The policy ``name`` as the base controller of a residual policy, with the tunable ``parameters`` it was
    trained with (name → value, from `base_controller_parameters`; None or empty: its current ones)."""
    policy = load_policy(name)
    if parameters:
        if not hasattr(policy, "from_parameter_dict"):
            raise PolicyError(f"base controller {name!r} takes no parameters, but the checkpoint records some")
        policy = type(policy).from_parameter_dict(parameters)
    return policy


def base_controller_parameters(name: str) -> dict:
    """The tunable parameters of base controller ``name`` as shipped now (empty if it has none), recorded with a
    residual policy so that later tuning of the controller does not change the trained policy."""
    policy = load_policy(name)
    return policy.parameter_dict() if hasattr(policy, "parameter_dict") else {}


def load_policy(name_or_path: str):
    """The policy named ``name_or_path`` or stored at that path."""
    if name_or_path in BUILTIN_POLICIES:
        return _construct(BUILTIN_POLICIES[name_or_path])
    if name_or_path in SHIPPED_CHECKPOINTS:
        path = shipped_checkpoint(name_or_path)
        if not path.is_file():
            raise PolicyError(f"policy {name_or_path!r}: its checkpoint {path} is not in this installation")
        return load_checkpoint_policy(path)
    foreign = load_foreign_policy(name_or_path)  # ONNX, TorchScript, Stable-Baselines3 or a Python policy
    if foreign is not None:
        return foreign
    path = Path(name_or_path)
    if path.exists():
        return load_checkpoint_policy(path)
    plugins = plugin_policies()
    if name_or_path in plugins:
        policy = plugins[name_or_path].load()()
        for attribute in ("name", "reset", "act", "supports"):
            if not hasattr(policy, attribute):
                raise PolicyError(f"plugin policy {name_or_path!r} has no {attribute!r}; see frbench.policies.base.Policy")
        return policy
    if "/" in name_or_path or name_or_path.endswith((".pt", ".onnx")):
        raise PolicyError(f"{name_or_path}: no such checkpoint file or run folder")
    raise unknown_name("policy", name_or_path, policy_names())


def checkpoint_metadata(path: Path) -> dict:
    """The scalar fields of a frbench checkpoint (method, env_steps, wall_s, robot_kind, num_actions,
    action_scale, config_json, ...) read without torch: a ``torch.save`` file is a zip archive whose
    ``data.pkl`` holds the dict, with tensors as references to other members; those are left unread (None).

    Raises:
        PolicyError: the file is not such an archive or not a frbench checkpoint.
    """
    import collections
    import pickle
    import zipfile

    class _Skeleton(pickle.Unpickler):
        def find_class(self, module: str, name: str):
            if module == "collections" and name == "OrderedDict":
                return collections.OrderedDict  # a torch state dict sets its ``_metadata`` attribute
            return lambda *args, **kwargs: None  # tensors, storages: not needed to describe a checkpoint

        def persistent_load(self, pid):
            return None

    file = resolve_checkpoint_file(Path(path))
    try:
        with zipfile.ZipFile(file) as archive:
            member = next(name for name in archive.namelist() if name.endswith("/data.pkl"))
            data = _Skeleton(archive.open(member)).load()
    except (OSError, zipfile.BadZipFile, StopIteration, pickle.UnpicklingError, EOFError, AttributeError) as exc:
        raise PolicyError(f"{file}: unreadable checkpoint ({type(exc).__name__})") from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        raise PolicyError(f"{file}: not a frbench checkpoint (expected format {CHECKPOINT_FORMAT!r})")
    return {key: value for key, value in data.items() if not key.endswith("state_dict")}


def describe_checkpoint(metadata: dict) -> str:
    """One line from a checkpoint's own config: method, env steps, training time, what it was trained on."""
    import json

    if metadata.get("description"):  # a checkpoint that describes itself (e.g. a distilled policy)
        return str(metadata["description"])
    config = json.loads(metadata.get("config_json") or "{}")
    env = config.get("env", {})
    if env.get("robot"):
        robots = env["robot"]
    elif env.get("num_morphologies"):
        robots = f"{env['num_morphologies']} sampled {metadata.get('robot_kind', 'quadruped')} morphologies"
    else:
        robots = metadata.get("robot_kind", "?")
    parts = [f"{metadata.get('method', '?')}", f"{metadata.get('env_steps', 0) / 1e6:.2f} M env steps"]
    if metadata.get("wall_s"):
        parts.append(f"{metadata['wall_s'] / 60:.0f} min training")
    parts.append(f"trained on {robots} in {env.get('backend', '?')}")
    weights = env.get("reward", {}).get("weights", {})
    if weights and "safety_force" not in weights and "body_bias" not in weights:
        parts.append("without the stability reward terms")
    if env.get("base_controller"):
        parts.append(f"residual over {env['base_controller']}")
    return ", ".join(parts)
