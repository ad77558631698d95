"""A robot in the simulators: its measured standing height, its conformance check, and the robot lookup that
gives a robot added by path its measured height. Above `frbench.robots` (data and pure derivation) and
`frbench.backends` (the simulators)."""
