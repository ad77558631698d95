"""Published quadrupeds as `frbench.robots.morphology.MorphologyParams`: Spot-like and Lite3-like (their sources
are in `frbench.robots.morphology`'s docstring). The registry builds ``spot_like`` and ``lite3_like`` from them.
"""

from __future__ import annotations

from frbench.robots.morphology import MorphologyParams

# --------------------------------------------------------------------------- presets

_SPOT_TOTAL_MASS = 32.5  # kg, manufacturer's spec sheet (see module docstring)
_SPOT_HIP_MASS, _SPOT_THIGH_MASS, _SPOT_CALF_MASS, _SPOT_FOOT_MASS = 1.68, 2.34, 0.35, 0.04

#: Spot-like quadruped: Menagerie ``spot.xml`` kinematics and leg masses, the
#: spec sheet's 32.5 kg total (trunk 14.86 kg), estimated trunk box.
SPOT_LIKE = MorphologyParams(
    trunk_mass=_SPOT_TOTAL_MASS - 4 * (_SPOT_HIP_MASS + _SPOT_THIGH_MASS + _SPOT_CALF_MASS + _SPOT_FOOT_MASS),
    trunk_length=0.892,
    trunk_width=0.256,
    trunk_height=0.205,
    hip_mass=_SPOT_HIP_MASS,
    hip_length=0.1108,
    thigh_mass=_SPOT_THIGH_MASS,
    thigh_length=0.321,
    thigh_width=0.12,
    thigh_height=0.10,
    calf_mass=_SPOT_CALF_MASS,
    calf_length=0.3365,
    calf_width=0.046,
    calf_height=0.074,
    foot_radius=0.036,
    foot_mass=_SPOT_FOOT_MASS,
    hip_x=0.29785,
    hip_y=0.055,
    hip_torque=45.0,
    thigh_torque=45.0,
    calf_torque=113.2,  # upper end of the angle-dependent 30.6–113.2 N·m knee limit
    hip_lower=-0.785,
    hip_upper=0.785,
    thigh_front_lower=-0.899,
    thigh_front_upper=2.295,
    thigh_rear_lower=-0.899,
    thigh_rear_upper=2.295,
    calf_lower=-2.793,
    calf_upper=-0.254,
    stand_hip=0.0,
    stand_thigh_front=0.9,
    stand_thigh_rear=1.1,
    stand_calf=-1.5,
    kp=150.0,  # published 60 sags 12 %; see frbench.robots.builtin on gains
    kd=3.0,
    hip_inertia=(0.00211474, 0.00181296, 0.00226544),
    thigh_inertia=(0.0275596, 0.0273549, 0.00284815),
    calf_inertia=(0.00399902, 0.00405032, 0.00014934),
)

#: Lite3-like quadruped: DeepRoboticsLab ``Lite3.urdf`` masses, collision boxes,
#: kinematics and inertias.
LITE3_LIKE = MorphologyParams(
    trunk_mass=5.606,
    trunk_length=0.50,
    trunk_width=0.10,
    trunk_height=0.12,
    hip_mass=0.55,
    hip_length=0.09735,
    thigh_mass=0.86,
    thigh_length=0.200,
    thigh_width=0.045,
    thigh_height=0.040,
    calf_mass=0.153,
    calf_length=0.210,
    calf_width=0.03,
    calf_height=0.03,
    hip_radius=0.04,
    foot_radius=0.022,
    foot_mass=0.02,
    hip_x=0.1745,
    hip_y=0.062,
    hip_torque=24.0,
    thigh_torque=24.0,
    calf_torque=36.0,
    hip_velocity=26.2,
    thigh_velocity=26.2,
    calf_velocity=17.3,
    hip_lower=-0.523,
    hip_upper=0.523,
    thigh_front_lower=-0.314,
    thigh_front_upper=2.67,
    thigh_rear_lower=-0.314,
    thigh_rear_upper=2.67,
    calf_lower=-2.792,
    calf_upper=-0.524,
    stand_hip=0.0,
    stand_thigh_front=1.0,
    stand_thigh_rear=1.0,
    stand_calf=-1.8,
    kp=60.0,  # published 20 sags 26 %; see frbench.robots.builtin on gains
    kd=0.7,  # the published value; 1.5 makes the light calves' explicit PD chatter (kd·dt/I ≈ 2.2)
    trunk_inertia=(0.02456, 0.05518, 0.07016),
    hip_inertia=(0.0003949, 0.0004028, 0.0004472),
    thigh_inertia=(0.005736, 0.004960, 0.001436),
    calf_inertia=(0.00089039, 0.00090672, 3.1266e-05),
)
