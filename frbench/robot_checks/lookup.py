"""The robots as frbench simulates them: `frbench.robots`' lookup plus the measured standing height.

`frbench.robots.get_robot` derives a robot added by path (a URDF path, a robot of
``frbench robot add``) without running a simulator, so its spec carries the
kinematic standing height (`frbench.robots.infer.needs_measured_height`).
:func:`get_robot` here settles such a robot in MuJoCo and PyBullet
(:func:`frbench.robot_checks.standing.measured_height`, cached by the spec's
content) and gives the spec that measured nominal height: the height that the
success test, the starts and the rewards scale with. Built-in and plugin
robots, and robots whose sidecar sets ``nominal_height``, come back unchanged.
"""

from __future__ import annotations

from frbench.robot_checks.standing import measured_height
from frbench.robots import registry
from frbench.robots.infer import needs_measured_height, with_standing
from frbench.robots.spec import RobotSpec


def with_measured_height(spec: RobotSpec) -> RobotSpec:
    """``spec`` with its standing height measured in both simulators when it still has the kinematic one."""
    return with_standing(spec, measured_height(spec)) if needs_measured_height(spec) else spec


def get_robot(name_or_path: str | RobotSpec) -> RobotSpec:
    """The `RobotSpec` of a registered name or a URDF path (`frbench.robots.registry.get_robot`), with the
    measured standing height of a robot added by path."""
    return with_measured_height(registry.get_robot(name_or_path))
