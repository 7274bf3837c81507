"""Mistakes are caught where they are made, with a message that names the valid choices, and
change nothing.

Each row of :data:`MISTAKES` makes one mistake on a freshly built TALOS stack and states the
error (or warning) and the text it must contain; the stack, the targets and the selections are
compared before and after.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import (
    FeatureGeneric,
    FrameNotFound,
    GainAdaptive,
    InvalidInput,
    MetaTaskKine6d,
    MetaTaskKineCom,
    MetaTaskKineJointLimits,
    MetaTaskKineManipulability,
    OperationalPointNotFound,
    SotWarning,
    StackError,
    Task,
    TaskInequality,
    TaskNotFound,
    add_sot,
    check_stack,
    gotoNd,
    hold_feet_and_com,
    simulate,
    talos,
)


@dataclass
class Stack:
    """A TALOS stack: the right-hand task ``rh`` pushed, the CoM task not."""

    builder: DiagramBuilder
    robot: object
    sot: object
    rh: MetaTaskKine6d
    com: MetaTaskKineCom

    def state(self, context=None) -> tuple:
        """What a rejected command must leave as it was."""
        return (
            self.sot.stack(context),
            self.rh.featureDes.settings(context).position.GetAsMatrix4().tobytes(),
            self.rh.feature.settings(context).selection,
            self.rh.gain.settings(context).coefficients,
            tuple(sorted(self.robot._names)),  # no entity added
            repr(self.sot.settings(context).control_selection),
        )


def make_stack(solver: str = "cascade") -> Stack:
    builder = DiagramBuilder()
    robot = talos(builder)
    sot = add_sot(robot, solver=solver)
    rh = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    com = MetaTaskKineCom(robot)
    sot.push(rh.task.name)
    return Stack(builder, robot, sot, rh, com)


@dataclass
class Mistake:
    name: str
    make: Callable[[Stack], object]
    error: type[BaseException]
    match: str


MISTAKES = [
    Mistake(
        "op point with '_' and a synonym",
        lambda s: MetaTaskKine6d("lh", s.robot, "lh", "right_hand"),
        FrameNotFound,
        r"'right_hand' \(did you mean 'right-wrist'",
    ),
    Mistake(
        "op point map, unknown key",
        lambda s: s.robot.OperationalPointsMap["right-hand"],
        OperationalPointNotFound,
        r"unknown operational point 'right-hand' \(did you mean 'right-wrist'.*available: 'left-wrist'",
    ),
    Mistake(
        "mask too long",
        lambda s: gotoNd(s.rh, [0.5, -0.2, 1.0], "1111111"),
        InvalidInput,
        r"mask '1111111' has 7 characters, the feature has 6 components.*X, Y, Z, RX, RY, RZ",
    ),
    Mistake(
        "mask alphabet",
        lambda s: s.rh.feature.selec("11x"),
        InvalidInput,
        r"featurerh.selec: invalid selection mask '11x': expected a string of at most 6 characters '0' or '1'",
    ),
    Mistake(
        "push an object",
        lambda s: s.sot.push(object()),
        TaskNotFound,
        r"sot expects a task name \(str\), a task or a meta task, got a object.*available: 'taskrh', 'taskcom'",
    ),
    Mistake("push a meta task twice", lambda s: s.sot.push(s.rh), StackError, r"'taskrh' is already in the stack"),
    Mistake(
        "gotoNd with a name",
        lambda s: gotoNd("rh", [0.5, -0.2, 1.0]),
        InvalidInput,
        r"gotoNd takes a MetaTaskKine6d or MetaTaskKineCom, got str: pass the meta task itself",
    ),
    Mistake("unknown task name", lambda s: s.sot.push("taskRH"), TaskNotFound, r"unknown task 'taskRH' \(did you mean 'taskrh'"),
    Mistake("hold the feet with a NaN gain", lambda s: hold_feet_and_com(s.robot, s.sot, gain=float("nan")), InvalidInput,
            r"hold_feet_and_com: gain must be a number"),
    Mistake("hold the feet with λ dt ≥ 2", lambda s: hold_feet_and_com(s.robot, s.sot, gain=5000.0), InvalidInput,
            r"hold_feet_and_com gain: λ·dt must be < 2"),
    Mistake("manipulability with λ dt ≥ 2",
            lambda s: MetaTaskKineManipulability("m1", s.robot, "right-wrist", 0.01, gain=5000.0), InvalidInput,
            r"MetaTaskKineManipulability\('m1'\) gain: λ·dt must be < 2"),
    Mistake("joint limits with three gain numbers", lambda s: MetaTaskKineJointLimits(s.robot, name="jl1", gain=(5.0, 1.0, 2.0)),
            InvalidInput, r"MetaTaskKineJointLimits\('jl1'\) gain \(one number\) must be a number in \[1e-06"),
    Mistake("joint limits with a zero gain (every limited joint frozen)",
            lambda s: MetaTaskKineJointLimits(s.robot, name="jl1", gain=0.0), InvalidInput,
            r"MetaTaskKineJointLimits\('jl1'\) gain \(one number\) must be a number in \[1e-06"),
]


@pytest.mark.parametrize("mistake", MISTAKES, ids=[m.name for m in MISTAKES])
def test_mistake_is_named_and_changes_nothing(mistake: Mistake):
    stack = make_stack()
    before = stack.state()
    with pytest.raises(mistake.error, match=mistake.match):
        mistake.make(stack)
    assert stack.state() == before


def test_a_meta_task_is_accepted_where_a_task_name_is():
    stack = make_stack()
    stack.sot.push(stack.com)
    stack.sot.up(stack.com)
    assert stack.sot.stack() == ["taskcom", "taskrh"]
    stack.sot.remove(stack.com.task)
    assert stack.sot.stack() == ["taskrh"]


def _bare_task(stack: Stack, gain: bool, feature: bool) -> Task:
    robot = stack.robot
    task = robot.add_task(Task("bare", robot.dimension))
    generic = robot.add(FeatureGeneric("featurebare", 3, robot.dimension))
    builder = stack.builder
    builder.Connect(robot.dynamic.GetOutputPort("com"), generic.GetInputPort("errorIN"))
    builder.Connect(robot.dynamic.GetOutputPort("Jcom"), generic.GetInputPort("jacobianIN"))
    builder.Connect(stack.com.featureDes.GetOutputPort("errorIN"), generic.GetInputPort("reference"))
    if feature:
        builder.Connect(generic.GetOutputPort("signals"), task.GetInputPort("feature"))
    if gain:
        g = robot.add(GainAdaptive("gainbare"))
        builder.Connect(generic.GetOutputPort("error"), g.GetInputPort("error"))
        builder.Connect(g.GetOutputPort("gain"), task.GetInputPort("controlGain"))
    stack.sot.push("bare")
    return task


@pytest.mark.parametrize(
    ("gain", "feature", "match"),
    [
        (False, True, r"sot: task 'bare' has no gain: connect a gain's 'gain' output to its 'controlGain' input"),
        (True, False, r"sot: task 'bare' has no feature: connect a feature's 'signals' output to its 'feature' input"),
    ],
)
def test_task_without_gain_or_feature_is_named_before_the_run(gain, feature, match):
    stack = make_stack()
    _bare_task(stack, gain, feature)
    diagram = stack.builder.Build()
    with pytest.raises(StackError, match=match):
        check_stack(diagram)
    with pytest.raises(StackError, match=match):
        simulate(diagram, 0.01, progress=False)
    # a Simulator of one's own: the same error at the task's first evaluation, not Drake's
    simulator = Simulator(diagram)
    with pytest.raises(StackError, match=match.removeprefix("sot: ")):
        simulator.AdvanceTo(0.002)


@pytest.mark.parametrize("command", ["gotoNd", "push", "setConstant"])
def test_command_without_context_once_running_warns_and_leaves_the_run_unchanged(command):
    stack = make_stack()
    diagram = stack.builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    before = stack.state(context)
    run = {
        "gotoNd": lambda: gotoNd(stack.rh, [0.5, -0.2, 1.0], "111"),
        "push": lambda: stack.sot.push(stack.com),
        "setConstant": lambda: stack.rh.gain.setConstant(3.0),
    }[command]
    with pytest.warns(SotWarning, match=r"without context=.*NOT changed: pass context=simulator.get_mutable_context\(\)") as said:
        run()
    assert len([w for w in said if issubclass(w.category, SotWarning)]) == 1  # once, for the whole command
    assert stack.state(context) == before  # the running context: unchanged, as the warning says
    assert stack.state(diagram.CreateDefaultContext()) != before  # contexts made from now on: changed


def test_command_with_context_or_before_any_context_does_not_warn(recwarn):
    stack = make_stack()
    gotoNd(stack.rh, [0.5, -0.2, 1.0], "111", 2.0)  # build time: the defaults
    diagram = stack.builder.Build()
    check_stack(diagram)  # a probe: not a running context
    stack.sot.push(stack.com)  # still before any context: applies to every context
    simulator = Simulator(diagram)
    gotoNd(stack.rh, [0.5, -0.2, 0.9], "111", context=simulator.get_mutable_context())
    assert stack.sot.stack(simulator.get_context()) == ["taskrh", "taskcom"]
    assert not [w for w in recwarn if issubclass(w.category, SotWarning)]


def test_inequality_task_without_bounds_warns_once_pushed():
    stack = make_stack(solver="hqp")
    robot = stack.robot
    task = robot.add_task(TaskInequality("unbounded", robot.dimension))
    robot.builder.Connect(stack.rh.feature.GetOutputPort("signals"), task.GetInputPort("feature"))
    gain = robot.add(GainAdaptive("gainunbounded"))
    robot.builder.Connect(gain.GetOutputPort("gain"), task.GetInputPort("controlGain"))
    robot.builder.Connect(stack.rh.feature.GetOutputPort("error"), gain.GetInputPort("error"))
    stack.sot.push(task.name)
    diagram = stack.builder.Build()
    with pytest.warns(SotWarning, match=r"unbounded: an inequality task in the stack without bounds.*setBounds"):
        check_stack(diagram)


def test_hold_feet_and_com_with_the_default_solver_leaves_the_grippers_out(caplog):
    builder = DiagramBuilder()
    robot = talos(builder)
    sot = add_sot(robot)
    hold_feet_and_com(robot, sot)
    selection = sot.settings().control_selection
    plant = robot.model.plant
    for gripper in ("gripper_left_joint", "gripper_right_joint"):
        assert not selection[plant.GetJointByName(gripper).velocity_start()]
    assert selection.sum() == robot.dimension - 2
    rh = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(rh, [0.5, -0.2, 1.0], "111", (4.9, 0.9, 0.01, 0.9))
    sot.push(rh)
    with caplog.at_level(logging.WARNING):
        simulate(builder.Build(), 0.05, progress=False)
    assert not [r for r in caplog.records if "left its limits" in r.getMessage()]


def test_hold_feet_and_com_keeps_a_selection_already_set():
    builder = DiagramBuilder()
    robot = talos(builder)
    sot = add_sot(robot)
    chosen = robot.velocity_selection(excluding=["gripper_left_joint"])
    sot.setControlSelection(chosen)
    hold_feet_and_com(robot, sot)
    np.testing.assert_array_equal(sot.settings().control_selection, chosen)


def _reach(target, duration: float, caplog, out=None) -> list[str]:
    """Run the UR5's tool to ``target``; the task's warnings (and, with ``out``, the run's files)."""
    builder = DiagramBuilder()
    from sotdrake import robot

    bot = robot(builder, "ur5")
    sot = add_sot(bot, solver="hqp")
    tool = MetaTaskKine6d("tool", bot, "tool")
    gotoNd(tool, target, "111", 5.0)
    sot.push(tool)
    diagram = builder.Build()
    with caplog.at_level(logging.WARNING, logger="sotdrake.task"):
        simulate(diagram, duration, progress=False)
    if out is not None:
        from sotdrake import write_run

        write_run(out, diagram, {}, graph=False)
    return [r.getMessage() for r in caplog.records if r.name == "sotdrake.task"]


@pytest.mark.slow
def test_an_unreachable_target_is_reported_once_with_the_remaining_distance(caplog, tmp_path):
    messages = _reach([2.0, 0.0, 0.4], 2.5, caplog, tmp_path)  # the UR5 reaches about 0.9 m
    assert len(messages) == 1
    assert "tasktool" in messages[0] and "has not decreased" in messages[0] and "out of reach" in messages[0]
    remaining = float(messages[0].split("‖e‖ = ")[1].split()[0])
    assert 0.9 < remaining < 1.3
    stalled = json.loads((tmp_path / "summary.json").read_text())["stalled_tasks"]
    assert list(stalled) == ["tasktool"] and stalled["tasktool"] == pytest.approx(remaining, rel=1e-3)


@pytest.mark.slow
def test_a_reachable_target_is_not_reported(caplog, tmp_path):
    assert _reach([0.4, 0.2, 0.4], 2.5, caplog, tmp_path) == []
    assert json.loads((tmp_path / "summary.json").read_text())["stalled_tasks"] == {}


def test_pushing_a_task_without_gain_into_a_running_stack_is_refused_at_push():
    stack = make_stack()
    _bare_task(stack, gain=False, feature=True)
    stack.sot.remove("bare")  # pushed at build time by _bare_task; pushed again below, while running
    simulator = Simulator(stack.builder.Build())
    context = simulator.get_mutable_context()
    with pytest.raises(StackError, match=r"task 'bare' has no gain"):
        stack.sot.push("bare", context)
    assert stack.sot.stack(context) == ["taskrh"]
    simulator.AdvanceTo(0.01)  # the run goes on, unchanged


def test_a_task_that_progresses_again_is_no_longer_stalled(caplog):
    """Warned at its floor (a task out of the stack, a target out of reach), then given a new
    target it tracks: the summary listed it as stalled at the old floor."""
    from sotdrake.progress import CHECK_PERIOD, PATIENCE, ProgressWatch

    watch = ProgressWatch("taskrh")
    t, e = 0.0, np.array([0.4, 0.1])
    with caplog.at_level(logging.WARNING, logger="sotdrake.task"):
        while t < PATIENCE + 3 * CHECK_PERIOD:
            watch.observe(t, e)
            t += CHECK_PERIOD
        assert watch.warned and watch.remaining == pytest.approx(np.linalg.norm(e))
        for _ in range(5):
            e = 0.5 * e
            watch.observe(t, e)
            t += CHECK_PERIOD
    assert not watch.warned and len([r for r in caplog.records if "taskrh" in r.getMessage()]) == 1


@pytest.mark.parametrize("make, match", [
    (lambda: Task(None, 3), r"Task name must be a non-empty string"),
    (lambda: Task("t", -1), r"t: nv \(the velocities\) must be an integer"),
    (lambda: Task("t", 2.5), r"t: nv \(the velocities\) must be an integer"),
    (lambda: Task("t", True), r"t: nv \(the velocities\) must be an integer"),
    (lambda: GainAdaptive(None), r"GainAdaptive name must be a non-empty string"),
    (lambda: GainAdaptive("g", True), r"g: dt must be a number > 0"),
    (lambda: FeatureGeneric("f", -1, 5), r"FeatureGeneric\('f'\): dimension must be an integer"),
    (lambda: FeatureGeneric("f", 3, 0), r"FeatureGeneric\('f'\): nv \(the velocities\) must be an integer"),
], ids=["task name", "task nv < 0", "task nv 2.5", "task nv bool", "gain name", "gain dt bool", "feature dimension", "feature nv"])
def test_an_entity_of_a_wrong_name_or_size_is_refused_when_made(make, match):
    with pytest.raises(InvalidInput, match=match):
        make()


def test_inequality_bounds_of_another_row_count_are_refused_in_a_running_context():
    """The row count is the feature's selection at run time: with a context the command checks it
    there, so a live ``setBounds`` cannot stop the run at the next tick."""
    from sotdrake import MetaTaskKineJointLimits

    builder = DiagramBuilder()
    robot = talos(builder)
    sot = add_sot(robot, solver="hqp")
    limits = MetaTaskKineJointLimits(robot)
    sot.push(limits.task.name)
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    context = simulator.get_mutable_context()
    before = limits.task.settings(context).lower.copy()
    with pytest.raises(InvalidInput, match=r"setBounds: 2 bounds, the feature's error has \d+ rows now"):
        limits.task.setBounds((-0.5, -0.5), (0.5, 0.5), context)
    assert np.array_equal(limits.task.settings(context).lower, before)
    rows = limits.feature.dimension
    limits.task.setBounds([-0.5] * rows, [0.5] * rows, context)
    simulator.AdvanceTo(0.01)


def test_gotond_with_one_entitys_own_context_changes_nothing():
    """gotoNd changes three entities: a context that is one of theirs (not the root's) is refused
    before any of them changes."""
    stack = make_stack()
    context = stack.builder.Build().CreateDefaultContext()
    before = stack.state(context)
    with pytest.raises(InvalidInput, match="featurerh"):
        gotoNd(stack.rh, [0.3, 0.2, 0.1], "111111", 4.0, context=stack.rh.featureDes.GetMyContextFromRoot(context))
    assert stack.state(context) == before
