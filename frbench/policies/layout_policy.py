"""`LayoutPolicy`: a policy trained elsewhere, driven through a `PolicyLayout`.

The adapters of ``frbench evaluate --policy`` for ONNX, TorchScript, Python and
Stable-Baselines3 policies share this class: it builds each observation frame
from frbench's proprioception dict as the layout says (terms, order, scales,
the layout's joint order), keeps the history frames and the previous output,
calls the model on float32 inputs (N, width), checks what comes back and turns
it into joint targets q* (N, J) [rad] in the robot's canonical order
(`frbench.policies.contract` states the rules).

A subclass implements ``forward(inputs)``: input name → float32 (N, width) →
actions (N, J), and may check its model against the layout in ``check``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from frbench.errors import PolicyError
from frbench.policies.contract import Contract, LayoutInput, PolicyLayout, contract_for, read_layout
from frbench.policies.contract import sidecar_path


def safe_name(text: str) -> str:
    """A results-safe policy name (letters, digits, ``._-``; at most 64 characters)."""
    return re.sub(r"[^A-Za-z0-9._-]", "-", text).strip("-")[:64] or "policy"


def _json(text: str, source: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise PolicyError(f"{source}: not JSON ({exc})") from None


def sidecar_layout(data, source: str) -> PolicyLayout:
    """The layout of a sidecar's JSON; a frbench export's sidecar without ``"layout"`` (an older export) gives
    its inputs' widths and action scale."""
    if isinstance(data, dict) and "layout" not in data and isinstance(data.get("inputs"), dict) and "obs" in data["inputs"]:
        try:
            frame = int(data["inputs"]["obs"][-1])
            inputs = tuple(LayoutInput(name, int(shape[-1]) // frame) for name, shape in data["inputs"].items())
            return PolicyLayout(inputs=inputs, action_scale=float(data["action_scale"]))
        except (TypeError, ValueError, KeyError, IndexError, ZeroDivisionError):
            raise PolicyError(f"{source}: a sidecar without a layout and with unreadable inputs") from None
    return PolicyLayout.from_dict(data, source)


def model_layout(path: Path, layout_file: str | None, embedded: str | None) -> tuple[PolicyLayout, str | None]:
    """The layout of model file ``path`` and the robot kind it declares (or None): from ``layout_file``
    (``--spec``), else its sidecar ``<file>.json``, else the layout JSON ``embedded`` in the model file, else
    frbench's default `PolicyLayout`."""
    sidecar = sidecar_path(path)
    if layout_file:
        return read_layout(layout_file), None
    if sidecar.is_file():
        try:
            data = _json(sidecar.read_text(), str(sidecar))
        except (OSError, UnicodeDecodeError) as exc:
            raise PolicyError(f"{sidecar}: not a readable sidecar ({exc})") from None
        source = str(sidecar)
    elif embedded:
        source = f"{path}: embedded layout"
        data = _json(embedded, source)
    else:
        return PolicyLayout(), None
    kind = data.get("robot_kind") if isinstance(data, dict) else None
    return sidecar_layout(data, source), kind if kind in ("quadruped", "humanoid") else None


def check_output(array, contract: Contract, num_envs: int, who: str) -> np.ndarray:
    """A model's output as float64 (N, J), or a one-line `PolicyError` naming the expected layout."""
    n = contract.n_joints
    array = np.asarray(array)
    if array.dtype.kind not in "fiu":
        raise PolicyError(f"{who}: returned actions of dtype {array.dtype}, expected float (N, {n}) "
                          f"[{contract.layout.describe(n)}]")
    if array.shape != (num_envs, n):
        count = array.shape[-1] if array.ndim else "no"
        raise PolicyError(f"{who}: returned actions of shape {array.shape} ({count} per environment), expected "
                          f"({num_envs}, {n}) for robot {contract.robot!r} [{contract.layout.describe(n)}]")
    return array.astype(np.float64)


class LayoutPolicy:
    """A policy given as a model of inputs → actions, plus the `PolicyLayout` it was trained with.

    Args:
        name: results-safe name.
        checkpoint: the file it was loaded from (its hash goes into the results), or None.
        layout: how it reads observations and what its actions mean.
        kind: the robot kind it drives (None: any robot whose joints the layout fits).
    """

    def __init__(self, name: str, checkpoint: Path | None, layout: PolicyLayout, kind: str | None = None):
        self.name = name
        self.checkpoint = checkpoint
        self.layout = layout
        self.kind = kind

    # -- what a subclass provides -----------------------------------------------------------------------------

    def forward(self, inputs: dict[str, np.ndarray]) -> np.ndarray:
        """Actions (N, J) in the layout's joint order for float32 inputs name → (N, width)."""
        raise NotImplementedError

    def check(self, contract: Contract) -> None:
        """Raise a one-line `PolicyError` if the model cannot take ``contract``'s inputs (default: a dry run
        on zeros, one environment)."""
        self._contract = contract
        zeros = {name: np.zeros((1, width), np.float32) for name, width in contract.layout.input_sizes(
            contract.n_joints).items()}
        check_output(self.forward(zeros), contract, 1, self.who)

    def start(self, contract: Contract, num_envs: int) -> None:
        """Hook at the start of each batch of episodes (after the buffers are reset)."""

    # -- the frbench policy protocol ------------------------------------------------------------------------

    @property
    def joint_frame(self) -> str:
        """The joint frame the layout declares (``robot`` or ``canonical``; `frbench.policies.base.policy_joint_frame`)."""
        return self.layout.joint_frame

    @property
    def who(self) -> str:
        """How errors name the policy."""
        return f"policy {self.name!r}" + (f" ({self.checkpoint})" if self.checkpoint else "")

    def expected(self) -> str:
        """The layout's one-line description for the robot being checked or run, in brackets (for errors)."""
        contract = getattr(self, "_contract", None)
        n = contract.n_joints if contract is not None else 12
        return f"[{(contract.layout if contract is not None else self.layout).describe(n)}]"

    def contract(self, spec) -> Contract:
        """The layout bound to ``spec`` (`PolicyError` if the layout's joints are not the robot's)."""
        try:
            return contract_for(spec, self.layout)
        except PolicyError as exc:
            raise PolicyError(f"{self.who}: {exc}") from None

    def supports(self, spec) -> bool:
        """Robots of its kind (if it has one); for the others the layout and the model are checked and a
        mismatch raises a one-line `PolicyError` that names the expected layout (a wrong input size, dtype
        or action count), rather than a bare False."""
        from frbench.policies.base import policy_joint_frame

        if self.kind is not None and spec.kind != self.kind:
            return False
        policy_joint_frame(self, spec)  # a one-line PolicyError where a canonical layout meets a robot without the frame
        self.check(self.contract(spec))
        return True

    def reset(self, spec, num_envs: int) -> None:
        """New episodes: empty histories, zero previous output."""
        contract = self._contract = self.contract(spec)
        layout, n = contract.layout, contract.n_joints
        self._order = np.asarray(contract.order)
        self._pose = np.asarray(contract.policy_default_pose)  # layout order
        self._canonical_pose = np.asarray(contract.default_pose)
        self._previous = np.zeros((num_envs, n))
        self._targets = np.tile(self._canonical_pose, (num_envs, 1))
        self._frames = max(i.frames for i in layout.inputs)
        self._history = None
        self._calls = 0
        self.num_envs = num_envs
        self.start(contract, num_envs)

    def frame(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The observation frame (N, F) float64 of the layout (module docstring of `frbench.policies.contract`)."""
        order, pose, n = self._order, self._pose, len(self._previous)
        values = {
            "base_angvel": lambda: obs["base_angvel"],
            "projected_gravity": lambda: obs["projected_gravity"],
            "joint_pos": lambda: obs["joint_pos"][:, order] - pose,
            "joint_vel": lambda: obs["joint_vel"][:, order],
            "previous_action": lambda: self._previous,
            "previous_target": lambda: obs["previous_action"][:, order] - pose,
        }
        parts = [term.scale * (np.full((n, term.size), term.value) if term.name == "constant"
                               else values[term.name]()) for term in self._contract.layout.observation]
        frame = np.concatenate(parts, axis=1)
        clip = self._contract.layout.observation_clip
        return frame if clip is None else np.clip(frame, -clip, clip)

    def model_inputs(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Float32 inputs name → (N, frames · F), the history updated with this step's frame."""
        frame = self.frame(obs)
        if self._history is None:  # a new episode: the history starts filled with its first frame
            self._history = np.repeat(frame[:, None, :], self._frames, axis=1)
        else:
            self._history = np.concatenate([self._history[:, 1:], frame[:, None, :]], axis=1)
        n = len(frame)
        return {i.name: self._history[:, -i.frames:].reshape(n, -1).astype(np.float32)
                for i in self._contract.layout.inputs}

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Joint targets q* (N, J) [rad], canonical order; a new decision every ``action_hold`` calls."""
        if self._calls % self._contract.layout.action_hold == 0:
            self._decide(obs)
        self._calls += 1
        return self._targets.copy()

    def _decide(self, obs: dict[str, np.ndarray]) -> None:
        contract, layout = self._contract, self._contract.layout
        action = check_output(self.forward(self.model_inputs(obs)), contract, len(self._previous), self.who)
        if layout.action_clip is not None:
            action = np.clip(action, -layout.action_clip, layout.action_clip)
        if layout.action == "normalised":
            self._previous = action
            targets = self._pose + layout.action_scale * action
        else:
            self._previous = action - self._pose
            targets = action
        self._targets = np.empty_like(targets)
        self._targets[:, self._order] = targets
