"""Weighted levels (``TaskWeight``): the level is the weighted least-squares compromise of its
members, in the null space of the levels above (strictness), in the basic cascade, ``SolverKine``
and ``SolverDyn``; weights are settings in the Context; bad weights are refused, changing nothing."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from scipy.linalg import null_space

from sotdrake import (
    TALOS_GRIPPERS,
    InvalidInput,
    MetaTaskKine6d,
    MetaTaskKineCom,
    MetaTaskKinePosture,
    StackError,
    TaskLevel,
    TaskNotFound,
    TaskWeight,
    add_sot,
    add_task_weight,
    gotoNd,
    signals_report,
    weighted_level,
)
from sotdrake.hqp.cascade import solve_cascade
from sotdrake.hqp.solve import HierarchicalQP, LevelRows
from sotdrake.robot import Robot
from sotdrake.task import Task


def reference_under(above: tuple[np.ndarray, np.ndarray], members: list[tuple[np.ndarray, np.ndarray]], weights) -> list[np.ndarray]:
    """Each member's ``J_i x`` at the minimiser of ``Σ w_i ‖J_i x − r_i‖²`` subject to ``J_0 x = r_0``
    (independent of the solvers: a particular solution of the level above plus its null space, by
    numpy's least squares). ``J_i x`` is the same at every minimiser."""
    J0, r0 = above
    x0 = np.linalg.lstsq(J0, r0, rcond=None)[0]
    N = null_space(J0)
    A = np.vstack([np.sqrt(w) * J @ N for (J, _), w in zip(members, weights, strict=True)])
    b = np.concatenate([np.sqrt(w) * (r - J @ x0) for (J, r), w in zip(members, weights, strict=True)])
    x = x0 + N @ np.linalg.lstsq(A, b, rcond=None)[0]
    return [J @ x for J, _ in members]


def random_members(rng, nv, sizes):
    return [(rng.normal(size=(m, nv)), rng.normal(size=m)) for m in sizes]


# --- the maths --------------------------------------------------------------------------------
def test_weighted_level_scales_each_members_rows_by_the_root_of_its_weight(rng):
    J1, J2 = rng.normal(size=(2, 5)), rng.normal(size=(3, 5))
    e1, e2 = rng.normal(size=2), rng.normal(size=3)
    r1, r2 = rng.normal(size=2), rng.normal(size=3)
    level = weighted_level([TaskLevel(J1, r1, r1, e1), TaskLevel(J2, r2, r2, e2)], [4.0, 0.25])
    np.testing.assert_array_equal(level.jacobian, np.vstack([2 * J1, 0.5 * J2]))
    np.testing.assert_array_equal(level.lower, np.concatenate([2 * r1, 0.5 * r2]))
    assert level.upper is level.lower  # an equality level stays one
    assert np.linalg.norm(level.error) ** 2 == pytest.approx(4 * e1 @ e1 + 0.25 * e2 @ e2)
    # a member of weight 0 is left out; an inequality member keeps its infinite sides
    lower, upper = np.array([-np.inf, -1.0, 0.0]), np.array([1.0, np.inf, 2.0])
    mixed = weighted_level([TaskLevel(J1, r1, r1, e1), TaskLevel(J2, lower, upper, e2)], [0.0, 9.0])
    np.testing.assert_array_equal(mixed.jacobian, 3 * J2)
    np.testing.assert_array_equal(mixed.lower, [-np.inf, -3.0, 0.0])
    np.testing.assert_array_equal(mixed.upper, [3.0, np.inf, 6.0])
    assert not mixed.is_equality


@pytest.mark.parametrize("seed", range(4))
def test_the_level_is_the_weighted_least_squares_solution_under_the_level_above(seed):
    rng = np.random.default_rng(seed)
    nv = 9
    J0, r0 = rng.normal(size=(3, nv)), rng.normal(size=3)
    members = random_members(rng, nv, (4, 3, 2))  # 9 rows for 6 free directions: a compromise
    weights = 10.0 ** rng.uniform(-2, 3, size=3)
    expected = reference_under((J0, r0), members, weights)
    level = weighted_level([TaskLevel(J, r, r, r) for J, r in members], weights)
    unbounded = np.full(nv, np.inf)
    x_qp = HierarchicalQP(nv).solve([LevelRows(J0, r0, r0), LevelRows(level.jacobian, level.lower, level.upper)],
                                    -unbounded, unbounded).x
    x_cascade = solve_cascade([(J0, r0), (level.jacobian, level.reference)], nv, svd_threshold=1e-9).velocity
    for x in (x_qp, x_cascade):
        np.testing.assert_allclose(J0 @ x, r0, atol=1e-8)  # the level above is held exactly (strictness)
        for (J, _), y in zip(members, expected, strict=True):
            np.testing.assert_allclose(J @ x, y, atol=1e-7 * max(1.0, np.abs(y).max()))
    # the weights matter: other weights, another compromise
    other = reference_under((J0, r0), members, weights[::-1])
    assert max(np.abs(a - b).max() for a, b in zip(expected, other, strict=True)) > 1e-3


# --- the entity in the kinematic solvers ------------------------------------------------------
def build_kinematic(model, solver: str):
    builder = DiagramBuilder()
    robot = Robot(builder, model)
    sot = add_sot(robot, solver=solver)
    sot.setControlSelection(robot.velocity_selection(TALOS_GRIPPERS))
    feet = []
    for name, op in (("contactRF", "right-ankle"), ("contactLF", "left-ankle")):
        foot = MetaTaskKine6d(name, robot, name[-2:], op)
        foot.gain.setConstant(1.0)
        sot.push(foot.task)
        feet.append(foot)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(hand, (0.5, -0.2, 1.0), "111", 0.5)
    posture = MetaTaskKinePosture(robot)  # stay where you are: against the hand in every joint
    posture.gain.setConstant(1.0)
    group = add_task_weight(robot, "handAndPosture", [hand, posture], [1.0, 1.0])
    sot.push(group)
    return robot, sot, feet, [hand, posture], group, builder.Build()


def rows_in(task, context):
    level = task.GetOutputPort("task").Eval(task.GetMyContextFromRoot(context))
    return level.jacobian, level.reference


@pytest.mark.parametrize("solver", ["cascade", "hqp"])
def test_a_weighted_level_in_the_kinematic_solvers_is_the_weighted_least_squares(talos_model, solver):
    robot, sot, feet, members, group, diagram = build_kinematic(talos_model, solver)
    context = diagram.CreateDefaultContext()
    selection = robot.velocity_selection(TALOS_GRIPPERS)
    feet_rows = [rows_in(foot.task, context) for foot in feet]
    above = (np.vstack([J for J, _ in feet_rows])[:, selection], np.concatenate([r for _, r in feet_rows]))
    member_rows = [rows_in(m.task, context) for m in members]
    sot_context = sot.GetMyContextFromRoot(context)
    answers = []
    for weights in ([1.0, 1.0], [100.0, 0.5]):
        group.setWeights(weights, context)
        v = sot.GetOutputPort("control").Eval(sot_context)
        assert sot.GetOutputPort("velocity_scale").Eval(sot_context)[0] == 1.0 or solver == "hqp"
        assert not v[~selection].any()
        np.testing.assert_allclose(above[0] @ v[selection], above[1], atol=1e-8)  # the feet are held exactly
        expected = reference_under(above, [(J[:, selection], r) for J, r in member_rows], weights)
        for (J, _), y in zip(member_rows, expected, strict=True):
            np.testing.assert_allclose(J @ v, y, atol=1e-6)
        answers.append(v)
    assert np.abs(answers[0] - answers[1]).max() > 1e-3  # the weights change the answer …
    assert group.weights() == {"taskrh": 1.0, "taskposture": 1.0}  # … in that context only
    assert group.weights(context) == {"taskrh": 100.0, "taskposture": 0.5}
    assert "weights" in signals_report(group, context) and "100." in signals_report(group, context)
    np.testing.assert_array_equal(group.GetOutputPort("weights").Eval(group.GetMyContextFromRoot(context)), [100.0, 0.5])


def test_bad_weights_and_groups_are_refused_and_change_nothing(talos_model):
    robot, sot, feet, (hand, posture), group, diagram = build_kinematic(talos_model, "hqp")
    context = diagram.CreateDefaultContext()
    group.setWeights({"taskposture": 3.0}, context)
    for bad, named in ((-1.0, "taskrh"), (np.nan, "taskrh"), (np.inf, "taskrh"), (1e9, "taskrh"), ("1", "taskrh")):
        with pytest.raises(InvalidInput, match=named):
            group.setWeight(hand, bad, context)
    with pytest.raises(InvalidInput, match="taskrh"):
        group.setWeights([-2.0, 1.0], context)
    for bad in ([1.0, 1.0, 1.0], 1.0):
        with pytest.raises(InvalidInput, match="2 numbers"):
            group.setWeights(bad, context)
    for bad in (["1", "2"], [True, 1.0]):
        with pytest.raises(InvalidInput, match="the weight of 'taskrh' must be a finite number"):
            group.setWeights(bad, context)
    with pytest.raises(InvalidInput, match="every weight is 0"):
        group.setWeights([0.0, 0.0], context)
    with pytest.raises(TaskNotFound, match="taskrh"):
        group.setWeight("taskRH", 1.0, context)
    assert group.weights(context) == {"taskrh": 1.0, "taskposture": 3.0}
    nv = robot.dimension
    with pytest.raises(InvalidInput, match="at least one task"):
        TaskWeight("empty", nv, [])
    with pytest.raises(InvalidInput, match="twice"):
        TaskWeight("twice", nv, [posture.task, posture.task])
    with pytest.raises(InvalidInput, match="nv = 5"):
        TaskWeight("wrong", 5, [posture.task])
    with pytest.raises(InvalidInput, match="weight of 'taskposture'"):
        TaskWeight("negative", nv, [posture.task, hand.task], [-1.0, 1.0])


def test_the_cascade_refuses_a_group_with_an_inequality_member_and_the_checks_name_a_member(talos_model):
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot)
    com = MetaTaskKineCom(robot, inequality=True)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    group = add_task_weight(robot, "withBox", [com, hand])
    with pytest.raises(StackError, match="hqp"):
        sot.push(group)
    loose = robot.add_task(Task("loose", robot.dimension))  # no feature, no gain
    unchecked = add_task_weight(robot, "withLoose", [hand, loose])
    sot.push(unchecked)
    diagram = builder.Build()
    from sotdrake import check_stack

    with pytest.raises(StackError, match=r"withLoose.*loose"):
        check_stack(diagram)


# --- the entity in SolverDyn ------------------------------------------------------------------
def test_a_weighted_level_in_solver_dyn_minimises_its_own_weighted_cost(rng):
    """Two weightings of the same conflicting pair under the dynamics and both contacts: each
    answer minimises its own weighted cost over what the levels above allow (so it does at least as
    well as the other answer), the contacts are held the same, and the answers differ."""
    from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture
    from sotdrake.dynamics.robot_dyn import RobotDyn
    from sotdrake.robots import load_talos

    builder = DiagramBuilder()
    robot = RobotDyn(builder, load_talos("reduced"), "dynsimu")
    lf, rf = robot.add_contact("contactLF", "left-sole"), robot.add_contact("contactRF", "right-sole")
    com, hand, posture = MetaTaskDynCom(robot), MetaTaskDyn6d("rh", robot, "right-wrist"), MetaTaskDynPosture(robot)
    group = add_task_weight(robot, "comAndHand", [com, hand], [1.0, 1.0])
    robot.sot.addContact(lf)
    robot.sot.addContact(rf)
    robot.sot.push(group)
    robot.sot.push(posture.task)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    com.featureDes.setReference(com.initial_com() + [0.08, 0.05, -0.06], context)
    pose = hand.initial_pose()
    hand.featureDes.setPosition(pose.__class__(pose.rotation(), pose.translation() + [0.3, -0.2, 0.2]), context)
    sot = robot.sot
    own = sot.GetMyContextFromRoot(context)
    assert set(sot.GetOutputPort("stack").Eval(own)) == {"comAndHand", "taskcom", "taskrh", "taskposture"}
    rows = [rows_in(m.task, context) for m in (com, hand)]

    def cost(weights, a):
        return sum(w * np.sum((J @ a - r) ** 2) for w, (J, r) in zip(weights, rows, strict=True))

    answers = {}
    for weights in ((1.0, 0.01), (0.01, 1.0)):
        group.setWeights(weights, context)
        solution = sot._solution.Eval(own)
        assert solution.diagnostics.failure == ""
        answers[weights] = sot.GetOutputPort("control").Eval(own).copy()
    (w1, a1), (w2, a2) = answers.items()
    assert cost(w1, a1) <= cost(w1, a2) * (1 + 1e-6) + 1e-9
    assert cost(w2, a2) <= cost(w2, a1) * (1 + 1e-6) + 1e-9
    assert np.abs(a1 - a2).max() > 1e-2


def test_live_commands_set_a_weight_and_an_acceleration_limit(talos_model):
    from sotdrake.live.grammar import parse_command
    from sotdrake.live.vocabulary import Vocabulary

    robot, sot, feet, (hand, posture), group, diagram = build_kinematic(talos_model, "hqp")
    vocabulary = Vocabulary(diagram, None)
    context = diagram.CreateDefaultContext()
    vocabulary.prepare(parse_command("handAndPosture.setWeight('taskposture', 0.25)"))(context)
    assert group.weights(context) == {"taskrh": 1.0, "taskposture": 0.25}
    assert "0.25" in str(vocabulary.prepare(parse_command("handAndPosture.weights()"))(context))
    vocabulary.prepare(parse_command("sot.setAccelerationLimit(40)"))(context)
    assert (sot.acceleration_limit(context)[6:] == 40.0).all()
    with pytest.raises(InvalidInput):
        vocabulary.prepare(parse_command("sot.setAccelerationLimit(-1)"))(context)
    with pytest.raises(InvalidInput):
        vocabulary.prepare(parse_command("handAndPosture.setWeight('taskposture', -1)"))(context)
    assert group.weights(context)["taskposture"] == 0.25
