"""A cloned context replays its run bit for bit: the state and the trace of a new ``Simulator`` on
the clone equal the original's, whether the clone is taken on a tick or between two (after a
command), and whatever ``Runner`` was asked before the clone."""

from __future__ import annotations

import numpy as np
from pydrake.systems.analysis import Simulator

from sotdrake import Runner, flush_tracers
from sotdrake.scenarios.talos_appli import build_diagram as build_appli
from sotdrake.walking.controller import build_diagram as build_walk


def assert_same_trace(tracer, original, replay) -> None:
    a, b = tracer.data(original), tracer.data(replay)
    assert np.all(np.diff(b["time"]) > 0), "one sample per time"
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def device_state(robot, context) -> np.ndarray:
    return robot.device.GetOutputPort("state").Eval(robot.device.GetMyContextFromRoot(context))


def test_a_clone_replays_the_tutorial_and_its_trace():
    appli = build_appli(push_time=0.15)
    simulator = Simulator(appli.diagram)
    simulator.Initialize()
    simulator.AdvanceTo(0.1)
    flush_tracers(appli.diagram, simulator.get_context())
    clone = simulator.get_context().Clone()
    simulator.AdvanceTo(0.2)
    flush_tracers(appli.diagram, simulator.get_context())
    replay = Simulator(appli.diagram, clone)
    replay.Initialize()  # (publishes at the clone's time again: the trace keeps the first sample)
    replay.AdvanceTo(0.2)
    flush_tracers(appli.diagram, clone)
    np.testing.assert_array_equal(device_state(appli.robot, clone), device_state(appli.robot, simulator.get_context()))
    assert_same_trace(appli.tracer, simulator.get_context(), clone)


def test_a_walk_cloned_between_two_ticks_after_a_command_plans_it_at_the_next_tick():
    walk = build_walk(mode="kinematic")
    simulator = Simulator(walk.diagram)
    simulator.Initialize()
    simulator.AdvanceTo(0.2005)
    walk.pg.setVelocity(0.05, 0.0, 0.1, context=simulator.get_mutable_context())
    clone = simulator.get_context().Clone()
    simulator.AdvanceTo(0.3)
    replay = Simulator(walk.diagram, clone)
    replay.Initialize()
    replay.AdvanceTo(0.3)
    np.testing.assert_array_equal(device_state(walk.robot, clone), device_state(walk.robot, simulator.get_context()))
    assert_same_trace(walk.tracer, simulator.get_context(), clone)


def test_runner_step_zero_leaves_the_tick_for_later():
    appli = build_appli(push_time=0.05)
    runner = Runner(appli.diagram, 1e-3)
    runner.step(100)
    before = device_state(appli.robot, runner.context).copy()
    assert runner.step(0) == runner.t
    np.testing.assert_array_equal(device_state(appli.robot, runner.context), before)
    clone = runner.context.Clone()
    runner.step(50)
    replay = Simulator(appli.diagram, clone)
    replay.Initialize()
    replay.AdvanceTo(runner.t)
    np.testing.assert_array_equal(device_state(appli.robot, clone), device_state(appli.robot, runner.context))
