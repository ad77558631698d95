"""frbench: a benchmark for legged-robot fall recovery in MuJoCo and PyBullet.

Importing frbench has no side effects: simulators, torch and plugins load when
first used.
"""

__version__ = "0.1.0"
