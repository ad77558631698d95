"""The unseen robots of protocol 1.2: real robot files that no policy trains on, in one list.

The standard grid scores the five quadrupeds that training samples its
morphologies around. The *unseen grid* (`frbench.evaluation.grids`) scores the
robots below instead: real robots from the installed packages, none of them a
built-in robot (`frbench.robots.builtin`), the target of a morphology preset
(`frbench.robots.morphology_presets`) or named by a training preset or a
morphology range (`frbench.training.presets`); ``tests/test_unseen_grid.py``
fails if any of those names one of them. Each passes ``frbench robot check``
by path (docs/robot-plug.md) and is addressed by the name here (``frbench
evaluate --robots a1``), which `frbench.robots.registry` resolves to the
installed file, so a result names the same robot on every machine.

Each entry: its file in its package, its total mass [kg] as Pinocchio loads it
(measured with ``frbench robots``; ``tests/test_unseen_grid.py`` re-measures it),
the package and why it is in the set. The quadrupeds span 2.5-56 kg (the
standard grid: 12.7-32.5 kg); the humanoids are scored only for policies that
drive humanoids (others get "n/a", not 0).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

EXAMPLE_ROBOT_DATA = "example-robot-data"
PYBULLET_DATA = "pybullet_data"


@dataclass(frozen=True)
class UnseenRobot:
    """One robot of the unseen set.

    Attributes:
        name: the registry name results use.
        kind: "quadruped" or "humanoid".
        package: ``example-robot-data`` or ``pybullet_data``.
        file: the URDF's path inside the package (example-robot-data: under ``robots/``).
        mass_kg: total mass [kg] (Pinocchio, the file's inertials).
        reason: why it is in the set.
        sidecar: a `frbench.robots.sidecar` file shipped in ``frbench/robots/unseen_sidecars/`` (None: none needed).
    """

    name: str
    kind: str
    package: str
    file: str
    mass_kg: float
    reason: str
    sidecar: str | None = None

    def path(self) -> Path:
        """The installed URDF (no download: `frbench.robots.paths`)."""
        from frbench.robots.paths import example_robot_data, pybullet_data_file

        return example_robot_data(self.file) if self.package == EXAMPLE_ROBOT_DATA else pybullet_data_file(self.file)

    def sidecar_path(self) -> Path | None:
        """The shipped sidecar file, or None."""
        return Path(__file__).with_name("unseen_sidecars") / self.sidecar if self.sidecar else None

    @property
    def source(self) -> str:
        """Where the file comes from, the same on every machine: ``<package>: <file>``."""
        return f"{self.package}: {self.file}"


_E, _P = EXAMPLE_ROBOT_DATA, PYBULLET_DATA

#: The unseen quadrupeds, lightest first.
UNSEEN_QUADRUPEDS: tuple[UnseenRobot, ...] = (
    UnseenRobot("solo12", "quadruped", _E, "solo_description/robots/solo12.urdf", 2.500,
                "the lightest real quadruped installed (2.5 kg): knees bend backwards on the hind legs and "
                "forwards on the front, a leg layout no training robot has"),
    UnseenRobot("mini_cheetah", "quadruped", _P, "mini_cheetah/mini_cheetah.urdf", 8.852,
                "MIT Mini Cheetah: a 9 kg research robot with short legs and continuous thigh joints; its file "
                "states no effort limits, the sidecar gives the published 18 N·m", "mini_cheetah.frbench.toml"),
    UnseenRobot("spirit40", "quadruped", _P, "quadruped/spirit40.urdf", 11.510,
                "Ghost Robotics Spirit 40: legs folded at zero angles, direct-drive knees; a different maker and "
                "joint convention from the Unitree robots training samples around"),
    UnseenRobot("a1", "quadruped", _E, "a1_description/urdf/a1.urdf", 13.741,
                "Unitree A1: Go1's predecessor at a similar size, the closest to the training robots (a control "
                "for how much of any gap is the maker's layout)"),
    UnseenRobot("laikago", "quadruped", _E, "laikago_description/urdf/laikago.urdf", 25.433,
                "Unitree Laikago: 25 kg with long legs and a high trunk"),
    UnseenRobot("vision60", "quadruped", _P, "quadruped/vision60.urdf", 26.900,
                "Ghost Robotics Vision 60: a 26 kg, long-bodied robot with folded-leg zero pose"),
    UnseenRobot("anymal_b", "quadruped", _E, "anymal_b_simple_description/robots/anymal.urdf", 30.475,
                "ANYbotics ANYmal B: 30 kg, knees pointing inwards (X stance), series-elastic actuators"),
    UnseenRobot("b1", "quadruped", _E, "b1_description/urdf/b1.urdf", 55.689,
                "Unitree B1: 56 kg industrial robot, the heaviest (the standard grid stops at 32.5 kg)"),
    UnseenRobot("anymal_c", "quadruped", _E, "anymal_c_simple_description/urdf/anymal.urdf", 52.135,
                "ANYbotics ANYmal C: 52 kg, X stance, a heavy trunk on light legs"),
)

#: The unseen humanoids, scored for policies that drive humanoids.
UNSEEN_HUMANOIDS: tuple[UnseenRobot, ...] = (
    UnseenRobot("icub", "humanoid", _E, "icub_description/robots/icub.urdf", 28.347,
                "IIT iCub: a child-sized humanoid (0.57 m standing) with a y-up root frame"),
    UnseenRobot("talos", "humanoid", _E, "talos_data/robots/talos_reduced.urdf", 90.272,
                "PAL Talos: a full-size 90 kg humanoid, nearly three times G1's mass"),
)

#: Every unseen robot by name.
UNSEEN_ROBOTS: dict[str, UnseenRobot] = {r.name: r for r in (*UNSEEN_QUADRUPEDS, *UNSEEN_HUMANOIDS)}


def unseen_spec(name: str):
    """The `RobotSpec` of the unseen robot ``name`` (kinematic standing height; `frbench.robot_checks.lookup`
    measures it), named and sourced portably."""
    from frbench.robots.infer import spec_from_path

    robot = UNSEEN_ROBOTS[name]
    sidecar = robot.sidecar_path()
    spec = spec_from_path(robot.path(), sidecar, name=name)
    return spec.replace(source=robot.source)
