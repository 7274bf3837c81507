"""What reads a run or adds an output refuses a wrong argument before Drake sees it: a context that is
not the root one of the diagram (None, a leaf context, another diagram's), a port that is not a
vector output of the builder, a system name already taken, a tick count given as a numpy integer is
accepted. Each refusal is an :class:`InvalidInput` naming the argument, with nothing added or
written, so that the corrected call works (and the builder still builds)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcm
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from sotdrake.collision import CollisionWorld, minimum_distance, pair_distances
from sotdrake.exceptions import InvalidInput
from sotdrake.meta_tasks import MetaTaskKine6d
from sotdrake.physics.actuators import hold_one_tick
from sotdrake.publishing import add_signal_publisher, add_state_publisher, publish_period
from sotdrake.robot import Robot
from sotdrake.target_marker import desired_position
from sotdrake.tracing import Tracer, flush_tracers


@pytest.fixture(scope="module")
def run(talos_model, tmp_path_factory):
    """A built TALOS diagram with a streaming tracer and a hand task, its root context, a leaf
    context of it and the root context of another diagram."""
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    tracer = Tracer(builder, 0.01, stream=tmp_path_factory.mktemp("trace") / "trace.chunks")
    tracer.add(robot.device.GetOutputPort("state"), "q")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    other = DiagramBuilder()
    other.AddSystem(ConstantVectorSource(np.zeros(1)))
    return {"diagram": diagram, "context": context, "tracer": tracer, "hand": hand, "robot": robot,
            "leaf": robot.device.GetMyContextFromRoot(context), "other": other.Build().CreateDefaultContext()}


@pytest.fixture(scope="module")
def world(talos_model):
    return CollisionWorld(talos_model)


def _unbuilt(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    abstract = builder.AddSystem(ConstantValueSource(AbstractValue.Make(RigidTransform()))).get_output_port(0)
    foreign = DiagramBuilder().AddSystem(ConstantVectorSource(np.zeros(2))).get_output_port(0)
    return builder, robot, abstract, foreign


def _names(builder: DiagramBuilder) -> list[str]:
    return [system.get_name() for system in builder.GetSystems()]


def test_the_tracer_refuses_a_context_that_is_not_the_root_one(run, tmp_path):
    tracer, context = run["tracer"], run["context"]
    calls = {"flush": lambda c: tracer.flush(c, force=True), "data": tracer.data,
             "save": lambda c: tracer.save(c, tmp_path / "t.npz"), "save_csv": lambda c: tracer.save_csv(c, tmp_path / "t.csv"),
             "plot": lambda c: tracer.plot(c, tmp_path / "t.png")}
    for what, call in calls.items():
        for bad, says in ((None, "NoneType"), (run["leaf"], "leaf context"), (run["other"], "another diagram"),
                          ("context", "str")):
            with pytest.raises(InvalidInput, match=rf"tracer: {what}: context must be the root Context.*{says}"):
                call(bad)
    assert list(tmp_path.iterdir()) == []
    assert tracer.data(context)["q"].shape == (0, run["robot"].model.nq)
    assert tracer.save(context, tmp_path / "t.npz").is_file()


def test_flush_tracers_refuses_a_wrong_context_or_diagram_before_drake_sees_it(run):
    diagram, context = run["diagram"], run["context"]
    for bad, says in ((None, "NoneType"), (run["leaf"], "leaf context"), (run["other"], "another diagram")):
        with pytest.raises(InvalidInput, match=rf"flush_tracers: context must be the root Context.*{says}"):
            flush_tracers(diagram, bad)
    with pytest.raises(InvalidInput, match="flush_tracers: diagram must be a built Diagram"):
        flush_tracers(None, context)  # type: ignore[arg-type]
    assert flush_tracers(diagram, context) == 0  # (no sample yet: nothing to move)


def test_desired_position_refuses_a_context_of_another_diagram(run):
    hand, context = run["hand"], run["context"]
    for bad in (None, run["leaf"], run["other"]):
        with pytest.raises(InvalidInput, match="context"):
            desired_position(hand, bad)
    with pytest.raises(InvalidInput, match="desired_position: task"):
        desired_position(None, context)  # type: ignore[arg-type]
    assert desired_position(hand, context).shape == (3,)


def test_collision_queries_refuse_a_context_that_is_not_the_worlds(run, world):
    context, q0 = world.new_context(), world.model.half_sitting
    leaf = world.plant.GetMyContextFromRoot(context)
    for bad, says in ((None, "None"), (leaf, "a leaf context"), (run["context"], "another diagram's context")):
        for call in (world.query, world.plant_context, lambda c: minimum_distance(world, c, q0),
                     lambda c: pair_distances(world, c, 0.5)):
            with pytest.raises(InvalidInput, match=rf"context must be a context of its collision diagram.*got {says}"):
                call(bad)
    assert np.array_equal(world.plant.GetPositions(leaf), world.plant.GetPositions(world.plant.CreateDefaultContext()))
    for call in (lambda: minimum_distance(None, context, q0), lambda: pair_distances("world", context, 0.5)):
        with pytest.raises(InvalidInput, match="world must be a CollisionWorld"):
            call()  # type: ignore[arg-type]
    assert np.isfinite(minimum_distance(world, context, q0))


def test_hold_one_tick_refuses_before_adding_anything(talos_model):
    builder, robot, abstract, foreign = _unbuilt(talos_model)
    com, names = robot.dynamic.GetOutputPort("com"), _names(builder)
    for bad_name, says in (("device", "an entity named 'device' already exists"), ("", "name"), (None, "name")):
        # (a name taken or empty: Build() would end the process)
        with pytest.raises(InvalidInput, match=f"hold_one_tick: {says}"):
            hold_one_tick(builder, com, bad_name, 1e-3)  # type: ignore[arg-type]
    for port, says in ((abstract, "abstract-valued"), (foreign, "another builder"), (None, "NoneType")):
        with pytest.raises(InvalidInput, match=rf"hold_one_tick 'held': port: it needs a vector output port.*{says}"):
            hold_one_tick(builder, port, "held", 1e-3)  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="builder"):
        hold_one_tick(None, com, "held", 1e-3)  # type: ignore[arg-type]
    assert _names(builder) == names
    assert hold_one_tick(builder, com, "held", np.float64(1e-3)).size() == 3  # the corrected call
    with pytest.raises(InvalidInput, match="hold_one_tick: an entity named 'held' already exists"):
        hold_one_tick(builder, com, "held", 1e-3)
    assert _names(builder) == [*names, "held"]
    builder.Build()


def test_the_signal_publisher_refuses_before_adding_anything(talos_model):
    builder, robot, abstract, foreign = _unbuilt(talos_model)
    com, lcm, names = robot.dynamic.GetOutputPort("com"), DrakeLcm("memq://"), _names(builder)
    for port, says in ((abstract, "abstract-valued"), (foreign, "another builder"), (None, "NoneType")):
        with pytest.raises(InvalidInput, match=rf"add_signal_publisher 'c': port: it needs a vector output port.*{says}"):
            add_signal_publisher(robot, port, "c", lcm)  # type: ignore[arg-type]
    for kwargs, says in (({"channel": ""}, "channel"), ({"channel": None}, "channel"), ({"lcm": "memq://"}, "lcm")):
        with pytest.raises(InvalidInput, match=says):
            add_signal_publisher(robot, com, **{"channel": "c", "lcm": lcm, **kwargs})  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="robot"):
        add_signal_publisher(None, com, "c", lcm)  # type: ignore[arg-type]
    assert _names(builder) == names
    add_signal_publisher(robot, com, "c", lcm, every=np.int64(2))  # the corrected call, with a numpy tick count
    assert len(_names(builder)) == len(names) + 2
    builder.Build()


def test_the_state_publisher_takes_a_numpy_tick_count(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    assert publish_period(robot, every=np.int64(2)) == pytest.approx(2 * robot.dt)
    for every in (np.int64(0), np.float64(2.0), np.True_):
        with pytest.raises(InvalidInput, match="every must be a positive whole number"):
            publish_period(robot, every=every)  # type: ignore[arg-type]
    add_state_publisher(robot, DrakeLcm("memq://"), "state", every=np.int64(2))
    with pytest.raises(InvalidInput, match="channel 'state' is already published"):
        add_state_publisher(robot, DrakeLcm("memq://"), "state")
    builder.Build()
