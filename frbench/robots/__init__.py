"""Robots: frozen specs, the registry, the simulation URDF and Pinocchio ground truth."""

from frbench.robots.registry import add_user_robot, get_robot, robot_names
from frbench.robots.spec import LinkGroup, RobotSpec

__all__ = ["LinkGroup", "RobotSpec", "add_user_robot", "get_robot", "robot_names"]
