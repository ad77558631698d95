"""The episode runner: one batch of protocol episodes of a policy, the one loop that evaluation, rendering, the
analyses and the tools share.

`run_episodes` builds the simulator (`frbench.tasks.recovery.open_backend`, unless handed a built one) and the
episode engine over it (`frbench.tasks.recovery.RecoveryTask`), resets them and the policy (drawn `FallenStarts`:
placed, settled and screened, `RecoveryTask.reset`; `RecordedStarts`: begun at the recorded states, no settle,
`RecoveryTask.begin`, as the key frames' rise stage in ``tools/keyframe_search.py`` does), then for every
control step asks the policy for joint targets, checks them (`checked_actions`: shape (N, J), finite; a one-line
`PolicyError` otherwise) and steps the engine; it closes the simulator it built whatever happens (a simulator
handed in stays open: its builder owns it). What callers need beyond the outcome comes in as callbacks:

* ``on_reset(task)`` once after the reset (e.g. the first frame of a video);
* ``on_step(task, targets)`` after each step, with the checked targets (N, J) [rad] just applied (frames,
  per-step records, estimator traces); returning `STOP` ends the episodes early.

A policy whose ``joint_frame`` is ``"canonical"`` (frbench's learned policies, layouts that declare it) reads and writes
joints in the robot's canonical joint frame (`frbench.robots.joint_frame`): it is reset with the robot's spec in
that frame, its observation's joint terms are mapped into it and its targets back, here, the one place a policy's
input and output pass; a policy that declares nothing (``"robot"``) sees the robot's own convention.

A policy that declares ``uses_simulator_state`` (a planner such as ``mpc``, not a blind policy) gets the
terrain and seed (``reset_episode``) and the simulator's `RobotState` before every action (``observe_state``).
The returned task's simulator is closed (when built here); its ``success``, ``metrics``, ``state`` and ``starts`` stay readable.
"""

from __future__ import annotations

from contextlib import nullcontext
from typing import Callable

from frbench.policies.base import checked_actions, policy_joint_frame
from frbench.tasks.initial_states import RecordedStarts
from frbench.tasks.recovery import EPISODE_STEPS, RecoveryTask, open_backend

#: Returned by ``on_step`` to end the episodes before their last step.
STOP = "stop"


def run_episodes(spec, backend, terrain, starts, policy, *, seed: int = 0, steps: int = EPISODE_STEPS,
                 noise_rng=None, on_reset: Callable | None = None, on_step: Callable | None = None,
                 check: bool = True, joint_frame: str | None = None, device: str | None = None) -> RecoveryTask:
    """Run ``len(starts.kinds)`` episodes of ``policy`` on ``spec`` in ``backend`` (a name or a `Backend`) over
    ``terrain`` for ``steps`` control steps from ``starts`` (`FallenStarts` or `RecordedStarts`, see the module
    docstring); ``seed`` is the terrain's, passed to a policy that plans on the simulator. ``check=False``
    skips the action check (a tool's own trusted controller); ``joint_frame`` overrides the policy's declared
    frame (None: the policy's ``joint_frame``); ``device``: where a device simulator named by ``backend`` runs (None:
    ``cpu``; its arrays come to the host)."""
    n = len(starts.kinds)
    with (open_backend(backend, spec, n, terrain, device) if isinstance(backend, str)
          else nullcontext(backend)) as physics:
        task = RecoveryTask(spec, physics, terrain, n, noise_rng=noise_rng)
        obs = task.begin(starts) if isinstance(starts, RecordedStarts) else task.reset(starts)
        frame = policy_joint_frame(policy, spec, joint_frame)
        policy.reset(frame.canonical_spec(spec) if frame is not None else spec, n)
        privileged = getattr(policy, "uses_simulator_state", False)
        if privileged:
            policy.reset_episode(terrain, seed)
        if on_reset is not None:
            on_reset(task)
        for _ in range(steps):
            if privileged:
                policy.observe_state(task.state)
            targets = policy.act(obs) if frame is None else frame.targets(policy.act(frame.observation(obs)))
            if check:
                targets = checked_actions(policy, targets, n, spec.n_joints)
            obs = task.step(targets)
            if on_step is not None and on_step(task, targets) is STOP:
                break
    return task
