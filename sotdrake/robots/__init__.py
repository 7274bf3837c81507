"""Robot loaders: URDF fix-ups, reference postures and operational-point maps."""

from .talos import (
    OPERATIONAL_POINTS,
    VARIANTS,
    RobotModel,
    add_talos,
    example_robot_data_dir,
    load_talos,
)

__all__ = [
    "OPERATIONAL_POINTS",
    "VARIANTS",
    "RobotModel",
    "add_talos",
    "example_robot_data_dir",
    "load_talos",
]
