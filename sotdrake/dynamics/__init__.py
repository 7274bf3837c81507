"""The dynamic SoT (sot-dyninv): inverse dynamics with contacts, the robot under torque control.

* :mod:`.terms`: the dynamics terms ``M``, ``h``, the actuation matrix, CoM terms from the
  floating-base rows, joint-limit acceleration bounds (pure functions);
* :mod:`.dynamic_entity`: ``DynamicEntity``, the ``dynamic`` entity reading the state ``(q, v)``;
* :mod:`.task_dyn_pd`: ``TaskDynPD``, acceleration tasks ``ë* = −Kp e − Kv ė + ë_ref``;
* :mod:`.contact`: 6D contacts (unilateral, friction pyramid, CoP in the sole) as entities;
* :mod:`.solver_dyn`: ``SolverDyn``, the strict hierarchy over ``(q̈, f, τ)``;
* :mod:`.device`: ``RobotDynSimu``, integration of ``q̈`` on SE(3) × joints;
* :mod:`.station`: the physics plant driven by ``τ`` (no PD);
* :mod:`.robot_dyn`: ``RobotDyn`` and the dynamic meta tasks;
* :mod:`.trajectories`: minimum-jerk references and the ports that feed them to a task.
"""

from .contact import Contact6d, ContactRows
from .device import RobotDynSimu
from .dynamic_entity import DynamicEntity
from .solver_dyn import SolverDyn
from .task_dyn_pd import TaskDynPD
from .terms import DynamicsTerms

__all__ = ["Contact6d", "ContactRows", "DynamicEntity", "DynamicsTerms", "RobotDynSimu", "SolverDyn", "TaskDynPD"]
