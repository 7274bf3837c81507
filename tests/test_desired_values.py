"""Desired values depend only on their settings and their own inputs (narrow prerequisites): they
are computed once, not every tick, and yet every change of a target reaches the feature, whether
it comes from a context command, an ``attime`` event or a connected trajectory input."""

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from sotdrake.features import Feature6dDesired
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.sequencer import attime


def test_targets_are_computed_once_and_changes_reach_the_feature(talos_model, monkeypatch):
    calls = {"position": 0}
    original = Feature6dDesired._position

    def counted(self, context, output):
        calls["position"] += 1
        original(self, context, output)

    monkeypatch.setattr(Feature6dDesired, "_position", counted)
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    com = MetaTaskKineCom(robot)
    sot.push(com.task.name)
    sot.push(hand.task.name)
    p0 = hand.current_pose().translation()
    gotoNd(hand, p0 + [0.1, 0.0, 0.0], "111", 1.0)
    attime(0.05, lambda: hand.featureDes.setPosition(p0 + [0.0, 0.2, 0.0]), "a new target")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()
    simulator.AdvanceTo(0.0405)  # 41 ticks
    assert calls["position"] <= 2  # not once per tick
    feature_context = hand.feature.GetMyContextFromRoot(simulator.get_context())
    error = hand.feature.GetOutputPort("error").Eval(feature_context)
    current = hand.current_pose(simulator.get_context()).translation()
    np.testing.assert_allclose(error, current - (p0 + [0.1, 0.0, 0.0]), atol=1e-12)

    simulator.AdvanceTo(0.0605)  # the attime event at 0.05 s changed the target
    error = hand.feature.GetOutputPort("error").Eval(feature_context)
    current = hand.current_pose(simulator.get_context()).translation()
    np.testing.assert_allclose(error, current - (p0 + [0.0, 0.2, 0.0]), atol=1e-12)

    target = p0 + [0.0, 0.0, -0.1]  # a command between AdvanceTo calls
    hand.featureDes.setPosition(target, simulator.get_mutable_context())
    error = hand.feature.GetOutputPort("error").Eval(feature_context)
    np.testing.assert_allclose(error, current - target, atol=1e-12)
    assert calls["position"] <= 4


def test_a_connected_trajectory_input_still_drives_the_target(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    com = MetaTaskKineCom(robot)
    source = robot.add(ConstantVectorSource(np.array([0.1, 0.0, 0.9])), "com_target")
    builder.Connect(source.get_output_port(), com.featureDes.GetInputPort("value_in"))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    error = com.feature.GetOutputPort("error").Eval(com.feature.GetMyContextFromRoot(context))
    np.testing.assert_allclose(error, robot.dynamic.com_at(robot.device.initial_position) - [0.1, 0.0, 0.9], atol=1e-12)
    source.get_mutable_source_value(source.GetMyMutableContextFromRoot(context)).set_value([0.2, 0.0, 0.9])
    error = com.feature.GetOutputPort("error").Eval(com.feature.GetMyContextFromRoot(context))
    np.testing.assert_allclose(error, robot.dynamic.com_at(robot.device.initial_position) - [0.2, 0.0, 0.9], atol=1e-12)
