"""``Solver(robot)``: the seed's solver wrapper (sot-dynamic's ``dynamic_graph.sot.dynamics.solver``,
used by ``ros-kineromeo.py`` and ``ros-walkromeo.py``).

It adds a solver named ``solver`` with the seed's inversion setting 1e-6 and a
:class:`~sotdrake.joint_limitator.JointLimitator` between the solver and the device::

    tasks → solver.control → joint_limitator.control_in
            joint_limitator.control → device.control        device.state → joint_limitator.position

so a joint whose next position would leave its limits is stopped, whichever solver is used.

* ``solver="cascade"`` (the seed's: sot-core's ``SOT``): the seed sets the ``SOT``'s ``damping``
  signal to 1e-6, and that signal is sot-core's SVD truncation threshold, so here it is
  :meth:`SOT.setThreshold` (1e-6), with no damped least squares (``setDamping`` stays 0);
* ``solver="hqp"`` (sot-dyninv's variant of the wrapper: ``SolverKine``): soth's damping 1e-6 on the
  last level, joint limits also hard in the QP.
"""

from __future__ import annotations

from typing import Any

from .exceptions import InvalidInput
from .joint_limitator import JointLimitator
from .robot import Robot
from .solvers import SOT, SolverKine
from .solvers.base_velocity import velocity_limit_vector

__all__ = ["SEED_INVERSION_SETTING", "Solver"]

#: The wrapper's ``sot.signal('damping').value``.
SEED_INVERSION_SETTING = 1e-6


class Solver:
    """The seed's ``solver = Solver(robot)``: ``solver.sot`` (the solver, named ``name``) and
    ``solver.jointLimitator`` (between the solver's ``control`` and the device's), added to
    ``robot``'s builder; ``solver.push(task)`` and the other stack commands go to ``solver.sot``.

    ``solver``: ``"cascade"`` (sot-core's ``SOT``, SVD threshold ``inversion``) or ``"hqp"``
    (``SolverKine``, damping ``inversion``); ``inversion`` defaults to the seed's 1e-6."""

    def __init__(self, robot: Robot, solver: str = "cascade", name: str = "solver",
                 inversion: float = SEED_INVERSION_SETTING, limitator_name: str = "joint_limitator"):
        if solver not in ("cascade", "hqp"):
            raise InvalidInput(f"Solver: unknown solver {solver!r}: 'cascade' (SOT) or 'hqp' (SolverKine)")
        if not isinstance(robot, Robot):
            raise InvalidInput(f"Solver: robot must be a sotdrake Robot (robot(builder, ...)), got {type(robot).__name__}")
        self.robot = robot
        self.jointLimitator = JointLimitator(robot.model.plant, robot.dt, limitator_name)
        sot: SOT | SolverKine
        if solver == "cascade":
            sot = SOT(name, robot.dimension, svd_threshold=inversion, damping=0.0, dt=robot.dt)
            sot.setVelocityLimit(velocity_limit_vector(robot.model))
        else:
            sot = SolverKine(name, robot.model, robot.dt, inversion)
        robot.add_solver(sot, self.jointLimitator)
        self.sot = sot

    def push(self, task: Any) -> None:
        """``sot.push``: a task, a meta task or a task name, at the bottom of the stack."""
        self.sot.push(task)

    def remove(self, task: Any) -> None:
        """``sot.remove``."""
        self.sot.remove(task)

    def __getattr__(self, name: str) -> Any:
        """Every other command of the solver (``up``, ``down``, ``addContact``, ``stack`` …)."""
        if name in ("sot", "robot", "jointLimitator"):  # not set yet: construction failed
            raise AttributeError(name)
        return getattr(self.sot, name)
