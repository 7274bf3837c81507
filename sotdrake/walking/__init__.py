"""Walking: the seed's pattern generator (``pg``) in Drake.

One concept a file: :mod:`.gait` (timing, sizes, the command's range), :mod:`.footsteps` (the
footstep planner), :mod:`.support` (support polygons, margins), :mod:`.zmp_reference` (the ZMP
reference), :mod:`.com_planner` (the CoM by Drake's ``ZmpPlanner``), :mod:`.swing` (foot
trajectories), :mod:`.plan` (a walk plan and its replanning), :mod:`.pattern_generator` (the
``PatternGenerator`` LeafSystem); for the physics plant: :mod:`.measured_com`, :mod:`.stabilizer`
(CoM/ZMP feedback), :mod:`.gravity_feedforward` (the servos' static torques), :mod:`.multibody_zmp`
(the whole body's ZMP, and the legs' momentum in the CoM plan).
"""

from .com_planner import GRAVITY, INPUT_COST, ComPlan, plan_com
from .footsteps import Footstep, plan_steps
from .gait import MAX_LINEAR_VELOCITY, MAX_YAW_RATE, GaitParameters, check_velocity
from .gravity_feedforward import GravityFeedforward
from .measured_com import MeasuredCom
from .multibody_zmp import LegMasses, leg_masses, motion_zmp, zmp_from_momentum
from .pattern_generator import PatternGenerator, start_of
from .plan import Start, WalkCommand, WalkPlan, initial_plan, replan
from .stabilizer import ComStabilizer
from .support import footprint, polygon_margin, sole_centre, support_polygon

__all__ = [
    "GRAVITY",
    "INPUT_COST",
    "MAX_LINEAR_VELOCITY",
    "MAX_YAW_RATE",
    "ComPlan",
    "ComStabilizer",
    "Footstep",
    "GaitParameters",
    "GravityFeedforward",
    "LegMasses",
    "MeasuredCom",
    "PatternGenerator",
    "Start",
    "WalkCommand",
    "WalkPlan",
    "check_velocity",
    "footprint",
    "initial_plan",
    "leg_masses",
    "motion_zmp",
    "plan_com",
    "plan_steps",
    "polygon_margin",
    "replan",
    "sole_centre",
    "start_of",
    "support_polygon",
    "zmp_from_momentum",
]
