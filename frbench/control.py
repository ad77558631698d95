"""The control period that every robot, backend, task and policy shares; it sits below all of them.

frbench's policies act at 50 Hz in both simulators (each backend takes ``CONTROL_DT / physics_dt`` physics steps
per control step); the benchmark protocol (`frbench.tasks.protocol`) fixes it for every result.
"""

#: Control period [s] (50 Hz) for every robot and backend.
CONTROL_DT = 0.02
