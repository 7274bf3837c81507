"""Robot loaders: URDF fix-ups, reference postures and operational-point maps.

``load_robot(name, variant)`` loads any robot of :data:`ROBOTS` (example-robot-data), and
``load_robot("path/to/robot.urdf")`` your own (URDF, SDF or MJCF, see :mod:`.from_file`);
``load_talos`` is the TALOS case.
"""

from .catalog import BASES, ROBOTS, TALOS_GRIPPERS, RobotSpec
from .loader import add_robot, available_robots, example_robot_data_dir, load_robot, robot_spec
from .model import OperationalPoints, RobotModel
from .packages import PackageResolver
from .talos import OPERATIONAL_POINTS, VARIANTS, add_talos, load_talos

__all__ = [
    "BASES",
    "OPERATIONAL_POINTS",
    "ROBOTS",
    "TALOS_GRIPPERS",
    "VARIANTS",
    "OperationalPoints",
    "PackageResolver",
    "RobotModel",
    "RobotSpec",
    "add_robot",
    "add_talos",
    "available_robots",
    "example_robot_data_dir",
    "load_robot",
    "load_talos",
    "robot_spec",
]
