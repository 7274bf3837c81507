"""The SoT ``RosPublish`` with ``addDownsampledSignal``: robot state and signals over LCM.

``add_state_publisher`` publishes the device's ``q`` as ``drake.lcmt_robot_state`` (every position
coordinate by name: joints by their joint name, the floating base as ``<body>_qw, _qx, _qy, _qz,
_x, _y, _z``) on channel ``sot_control/state`` every ``period`` seconds of simulated time (0.01:
100 Hz, downsampled from the 1 kHz loop as the seed's ``addDownsampledSignal(…, 100)``).
``add_signal_publisher`` publishes any vector output as ``drake.lcmt_scope`` with Drake's
``LcmScopeSystem``. LCM's default URL keeps the traffic on this host (``udpm`` with ``ttl=0``).

Both take the rate as the seed wrote it, ``every`` ticks of the device (sot-core's ``PeriodicCall``:
``addDownsampledSignal("ros_publish_state.trigger", 100)`` publishes on every 100th tick), or as a
``period`` in seconds; not both.
"""

from __future__ import annotations

import numbers

from drake import lcmt_robot_state
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcm, DrakeLcmInterface
from pydrake.systems.framework import Context, DiagramBuilder, LeafSystem, OutputPort
from pydrake.systems.lcm import LcmPublisherSystem, LcmScopeSystem

from .atomic import check_vector_port
from .configuration import position_names
from .exceptions import InvalidInput, SotError, check_name, finite_number
from .robot import Robot


class RobotStateMessage(LeafSystem):
    """Input ``state`` (``q``); output ``message``, an ``lcmt_robot_state`` (utime = sim time in µs)."""

    def __init__(self, plant, name: str = "ros_publish_state"):
        LeafSystem.__init__(self)
        self.set_name(name)
        self.names = position_names(plant)
        self.state = self.DeclareVectorInputPort("state", plant.num_positions())
        self.DeclareAbstractOutputPort("message", lambda: AbstractValue.Make(lcmt_robot_state()), self._calc)

    def _calc(self, context: Context, output: AbstractValue) -> None:
        message = lcmt_robot_state()
        message.utime = round(context.get_time() * 1e6)
        message.num_joints = len(self.names)
        message.joint_name = self.names
        message.joint_position = list(self.state.Eval(context))
        output.set_value(message)


def publish_period(robot: Robot, period: float | None = None, every: int | None = None) -> float:
    """The publishing period (s): ``period`` (s, > 0), or ``every`` ticks of ``robot.dt`` (a
    positive integer, a numpy one too: ``every·dt``), or 0.01 s if neither is given; both raise
    :class:`~sotdrake.exceptions.InvalidInput`."""
    _check_robot(robot)
    if period is not None and every is not None:
        raise InvalidInput(f"give the publishing rate as period (s) or as every (ticks), not both: period={period!r}, every={every!r}")
    if every is not None:
        if isinstance(every, bool) or not isinstance(every, numbers.Integral) or every <= 0:
            raise InvalidInput(f"every must be a positive whole number of ticks, got {every!r:.60}")
        return int(every) * robot.dt
    if period is None:
        return 0.01
    if not finite_number(period) or period <= 0:
        raise InvalidInput(f"publish period must be a number > 0 (s), got {period!r}")
    return float(period)


def add_state_publisher(
    robot: Robot, lcm: DrakeLcm | None = None, channel: str = "sot_control/state", period: float | None = None,
    every: int | None = None,
) -> LcmPublisherSystem:
    """Publish ``robot.device.state`` on ``channel`` every ``period`` s or every ``every`` ticks of
    the device (:func:`publish_period`; default 0.01 s); returns the publisher. A given ``lcm`` must
    outlive the diagram (the default one lives as long as ``robot``). A wrong argument:
    :class:`InvalidInput` naming it, nothing added."""
    period = publish_period(robot, period, every)
    _check_channel_and_lcm(channel, lcm)
    if any(system.get_name() == f"lcm_{channel}" for system in robot.builder.GetSystems()):
        raise InvalidInput(f"add_state_publisher: channel {channel!r} is already published by this diagram")
    lcm = lcm or _lcm_of(robot)
    converter = robot.add(RobotStateMessage(robot.model.plant))
    publisher = LcmPublisherSystem.Make(channel, lcmt_robot_state, lcm, period)
    publisher.set_name(f"lcm_{channel}")
    robot.builder.AddSystem(publisher)
    robot.builder.Connect(robot.device.GetOutputPort("state"), converter.get_input_port())
    robot.builder.Connect(converter.get_output_port(), publisher.get_input_port())
    return publisher


def add_signal_publisher(robot: Robot, port: OutputPort, channel: str, lcm: DrakeLcm | None = None,
                         period: float | None = None, every: int | None = None) -> LcmScopeSystem:
    """Publish a vector output port as ``lcmt_scope`` on ``channel`` every ``period`` s or every
    ``every`` ticks of the device (:func:`publish_period`; default 0.01 s). A ``port`` that is not
    a vector-valued output port of a system of ``robot.builder``, or another wrong argument:
    :class:`InvalidInput` naming it, nothing added."""
    period = publish_period(robot, period, every)
    _check_channel_and_lcm(channel, lcm)
    if robot.builder.already_built():
        raise SotError(f"add_signal_publisher: cannot publish {channel!r}: the diagram is already built")
    check_vector_port(f"add_signal_publisher {channel!r}: port", robot.builder, port)
    scope, _ = LcmScopeSystem.AddToBuilder(robot.builder, lcm or _lcm_of(robot), port, channel, period)
    return scope


def _lcm_of(robot: Robot) -> DrakeLcm:
    """The robot's LCM instance (Drake's default URL), created once and kept alive with the robot:
    the publishers only hold a reference to it."""
    if getattr(robot, "lcm", None) is None:  # (a RobotDyn has none until then)
        robot.lcm = DrakeLcm()
    return robot.lcm


def _check_robot(robot: object) -> None:
    if not isinstance(getattr(robot, "builder", None), DiagramBuilder) or not finite_number(getattr(robot, "dt", None)):
        raise InvalidInput(f"publishing: robot must be a Robot (sotdrake.talos(builder), Robot(builder, model)), "
                           f"got {type(robot).__name__}")


def _check_channel_and_lcm(channel: object, lcm: object) -> None:
    check_name("publishing: channel", channel)
    if lcm is not None and not isinstance(lcm, DrakeLcmInterface):
        raise InvalidInput(f"publishing: lcm must be a DrakeLcm (or None: the robot's), got {type(lcm).__name__}")
