"""Which sampled morphologies can stand at all: the training set keeps only those.

The paper's morphology table reaches 21–47 kg robots, while the joint torque
limits and the training gains stay those of a Go2-sized dog. Measured
before this filter: with the training's Kp ∈ [50, 80], half of 64 sampled robots held
at their default pose sank below 75 % of their standing height with their
bodies on the ground — episodes no policy can win, which only dilute PPO's
samples. A morphology is kept when, held at its default pose by the PD at the
*lowest* training gains, it stays at least `MIN_HEIGHT_FRACTION` of its
nominal height above flat ground, on its feet only, for `STAND_SECONDS`.
"""

from __future__ import annotations

from frbench.backends.base import PhysicsParams
from frbench.backends.hold import hold_default_pose
from frbench.content_cache import cached_bytes, content_key, source_key
from frbench.robots.sim_urdf import sim_robot_file
from frbench.robots.spec import RobotSpec

#: Height [fraction of nominal] a feasible morphology must hold; the success test asks for 0.75.
MIN_HEIGHT_FRACTION = 0.85
#: Seconds of holding the default pose.
STAND_SECONDS = 1.0


def can_stand(spec: RobotSpec, kp: float, kd: float, backend: str = "mujoco") -> bool:
    """True when ``spec`` holds its default pose on flat ground with gains ``kp`` [N·m/rad], ``kd`` [N·m·s/rad].

    Deterministic, so the answer is cached (`frbench.content_cache`) by the spec, its simulation URDF, the
    gains, the backend and the source of the code that simulates it."""
    import json

    key = content_key(spec, sim_robot_file(spec).path.read_bytes(), float(kp), float(kd), backend,
                      source_key(__name__, "frbench.backends.hold", "frbench.backends.base", "frbench.backends.contact_layout",
                                 f"frbench.backends.{backend}_backend", "frbench.backends.mujoco_model"))
    return cached_bytes("feasibility", key, ".json",
                        lambda: json.dumps(_stands(spec, kp, kd, backend)).encode(), lambda data: bool(json.loads(data)))


def _stands(spec: RobotSpec, kp: float, kd: float, backend: str) -> bool:
    params = PhysicsParams.nominal(spec, 1)
    params.kp[:], params.kd[:] = kp, kd
    held = hold_default_pose(spec, backend, STAND_SECONDS, params=params)
    feet_only = not held.contacts.group_contact[0].any()
    return feet_only and not held.diverged and float(held.state.base_pos[0, 2]) >= MIN_HEIGHT_FRACTION * spec.nominal_height
