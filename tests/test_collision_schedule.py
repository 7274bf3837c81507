"""The collision pair schedule never misses a pair in range, and a cloned context replays it.

Every tick of random walks through the configuration space (the base translated and rotated, the
joints moved much faster than any stack moves them) is compared with Drake's full broad-phase query:
the scheduled pairs in range are exactly the query's, with the same distances, and every pair's
bound stays below its exact signed distance.
"""

from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from sotdrake.collision import CollisionWorld, add_obstacle, kernels
from sotdrake.collision.distance import distances_of, signed_distance_pairs
from sotdrake.collision.reach import TABLE, build_collision_reach
from sotdrake.collision.schedule import PairSchedule, ScheduleState
from sotdrake.collision.shapes import bounding_sphere
from sotdrake.collision.task import INFLUENCE_DISTANCE, one_tick_influence
from sotdrake.exceptions import InvalidInput
from sotdrake.meta_tasks import gotoNd


@pytest.fixture(scope="module")
def scheduled(talos_model):
    world = CollisionWorld(talos_model)
    add_obstacle(world, ("box", TABLE[0]), RigidTransform(list(TABLE[1])), "table")
    context = world.new_context()
    return world, context, PairSchedule(world)


def _walk(model, rng, ticks, step):
    """A random walk from the reference posture: joints within their limits, base moved and turned."""
    q = model.half_sitting.copy()
    lower, upper = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()
    for _ in range(ticks):
        q = q.copy()
        q[7:] = np.clip(q[7:] + step * rng.standard_normal(len(q) - 7), lower[7:], upper[7:])
        q[4:7] += 0.2 * step * rng.standard_normal(3)
        quaternion = q[:4] + 0.2 * step * rng.standard_normal(4)
        q[:4] = quaternion / np.linalg.norm(quaternion)
        yield q


def _in_range(results):
    return {frozenset((r.id_A, r.id_B)): r.distance for r in results}


@pytest.mark.parametrize("step", [2e-3, 2e-2])
def test_the_schedule_finds_every_pair_the_full_query_finds(scheduled, talos_model, step):
    world, context, schedule = scheduled
    rng = np.random.default_rng(7)
    state, queried = ScheduleState(), []
    for k, q in enumerate(_walk(talos_model, rng, 150, step)):
        world.plant.SetPositions(world.plant_context(context), q)
        out = schedule.step(state, context, q, INFLUENCE_DISTANCE)
        state = out.state
        full = _in_range(world.query(context).ComputeSignedDistancePairwiseClosestPoints(INFLUENCE_DISTANCE))
        mine = _in_range(out.in_range)
        assert mine.keys() == full.keys(), f"tick {k}: missed {full.keys() - mine.keys()}, extra {mine.keys() - full.keys()}"
        assert all(abs(mine[p] - full[p]) < 1e-9 for p in full)
        queried.append(out.queried)
        if k % 30 == 0:
            query = world.query(context)
            exact = np.array([query.ComputeSignedDistancePairClosestPoints(a, b).distance for a, b in schedule.pairs])
            assert np.all(state.lower <= exact + 1e-12)
    assert queried[0] == len(schedule.pairs)
    assert np.median(queried[1:]) < len(schedule.pairs)  # (the bound is not vacuous)


def test_a_pair_fixed_together_keeps_its_bound(scheduled, talos_model):
    world, context, schedule = scheduled
    q = talos_model.half_sitting.copy()
    moved = q.copy()
    moved[4:7] += 0.05  # the whole robot translated: no self pair moves, every table pair may
    table = np.array([world.obstacles["table"] in pair for pair in schedule.pairs])
    decrease = schedule.coefficients @ schedule.motion(q, moved)
    assert np.all(decrease[~table] == 0.0)
    assert np.all(decrease[table] >= 0.05 - 1e-12)


@pytest.mark.parametrize("seed", range(20))
def test_the_compiled_bounds_after_a_motion_are_the_plain_ones(seed):
    """:func:`kernels.lowered` against ``lower − coefficients · motion`` of the plain
    :meth:`PairSchedule.motion`, with quaternion and roll-pitch-yaw floating joints, one of them
    moving no bound."""
    rng = np.random.default_rng(seed)
    kinds = ["quaternion_floating", "rpy_floating", "quaternion_floating"]
    starts, nq = [], 0
    for kind in kinds:
        starts.append(nq)
        nq += 7 if kind == "quaternion_floating" else 6
    one_dof = np.arange(nq, nq + 12, dtype=np.int64)
    nq += 12
    q0, q1 = rng.normal(size=nq), rng.normal(size=nq)
    for s, kind in zip(starts, kinds, strict=True):
        if kind == "quaternion_floating":
            q0[s:s + 4] /= np.linalg.norm(q0[s:s + 4])
            q1[s:s + 4] = q0[s:s + 4] + 0.1 * rng.normal(size=4)
            q1[s:s + 4] /= np.linalg.norm(q1[s:s + 4])
    joint = SimpleNamespace
    floating = [joint(position_start=lambda s=s: s, type_name=lambda k=k: k) for s, k in zip(starts, kinds, strict=True)]
    bounding = np.array([True, True, False])
    plain = SimpleNamespace(_one_dof_q=one_dof, _floating=floating, _bounding=bounding)
    coefficients = rng.uniform(0, 2, size=(30, 12 + 2 * len(kinds)))
    lower = rng.normal(size=30)
    expected = lower - coefficients @ PairSchedule.motion(plain, q0, q1)
    compiled = kernels.lowered(lower, coefficients, q0, q1, one_dof, np.array(starts, dtype=np.int64),
                               np.array([k == "quaternion_floating" for k in kinds]), bounding)
    np.testing.assert_allclose(compiled, expected, rtol=1e-13, atol=1e-13)


def test_bounding_spheres_hold_the_shapes():
    from pydrake.geometry import Box, Capsule, Cylinder, Sphere

    assert bounding_sphere(Sphere(0.2))[1] == pytest.approx(0.2)
    assert bounding_sphere(Box(2.0, 2.0, 1.0))[1] == pytest.approx(1.5)
    assert bounding_sphere(Cylinder(0.3, 0.8))[1] == pytest.approx(0.5)
    assert bounding_sphere(Capsule(0.1, 0.4))[1] == pytest.approx(0.3)


def _ordered(a, b):
    return (a, b) if a.get_value() < b.get_value() else (b, a)


def test_the_task_rows_are_the_full_query_rows_and_a_clone_replays_them():
    reach = build_collision_reach(collision=True, table=True)
    simulator = Simulator(reach.diagram)
    context = simulator.get_mutable_context()
    gotoNd(reach.hand, np.array([0.5, -0.3, 0.70]), "111", 10.0, context=context)  # under the table top
    simulator.Initialize()
    task, device = reach.collision.task, reach.robot.device
    world = task.world
    check = world.new_context()
    dt = device.dt
    # Each pair's influence: d_i, or farther for a pair one tick within the solver's step bound may
    # bring within d_t (computed here from the schedule's bound, the task's own numbers left aside).
    step = reach.sot.GetOutputPort("step_bound").Eval(reach.sot.GetMyContextFromRoot(context))
    schedule = PairSchedule(world)
    influence = dict(zip(schedule.pairs, one_tick_influence(task.settings(), schedule.tick_approach(step)), strict=True))
    assert max(influence.values()) > INFLUENCE_DISTANCE
    for k in range(1, 61):
        simulator.AdvanceTo(k * dt)
        q = device.GetOutputPort("state").Eval(device.GetMyContextFromRoot(context))
        world.plant.SetPositions(world.plant_context(check), q)
        results = signed_distance_pairs(world, check, max(influence.values()))
        full = distances_of(world, check, [r for r in results if r.distance < influence[_ordered(r.id_A, r.id_B)]])
        mine = task.GetOutputPort("distances").Eval(task.GetMyContextFromRoot(context))
        assert sorted(mine.names) == sorted(full.names)
        assert np.allclose(np.sort(mine.distance), np.sort(full.distance), atol=1e-9)
        by_name = {name: row for name, row in zip(full.names, full.jacobian, strict=True)}
        assert all(np.allclose(row, by_name[name], atol=1e-9) for name, row in zip(mine.names, mine.jacobian, strict=True))
    clone = context.Clone()
    replay = Simulator(reach.diagram, clone)
    for k in range(61, 81):
        simulator.AdvanceTo(k * dt)
        replay.AdvanceTo(k * dt)
    q = device.GetOutputPort("state").Eval(device.GetMyContextFromRoot(context))
    q_replay = device.GetOutputPort("state").Eval(device.GetMyContextFromRoot(clone))
    assert np.array_equal(q, q_replay)
    memory = task.GetMyContextFromRoot(clone).get_abstract_state(task._schedule_index).get_value()
    original = task.GetMyContextFromRoot(context).get_abstract_state(task._schedule_index).get_value()
    assert memory is not original and np.array_equal(memory.state.q, original.state.q)
    assert memory.state.lower.tolist() == original.state.lower.tolist()
    copied = copy.deepcopy(memory)
    assert copied is not memory and copied.state is memory.state
    # Shared by the copies, never changed: a tick makes a new state, its arrays read-only.
    state = memory.state
    assert not any(a.flags.writeable for a in (state.q, state.lower, state.in_range_pairs))


def test_the_schedule_memory_is_a_warm_start_the_run_does_not_depend_on():
    """The bounds only decide which pairs are queried: a run whose memory is emptied or set back
    to an earlier tick's (any earlier configuration gives true lower bounds) commands the same
    motion, bit for bit, and queries more pairs."""
    from sotdrake.collision.schedule import ScheduleMemory

    reach = build_collision_reach(collision=True, table=True)
    simulator = Simulator(reach.diagram)
    context = simulator.get_mutable_context()
    gotoNd(reach.hand, np.array([0.5, -0.3, 0.70]), "111", 10.0, context=context)
    simulator.Initialize()
    task, device = reach.collision.task, reach.robot.device
    dt = device.dt
    simulator.AdvanceTo(dt)
    early = task.GetMyContextFromRoot(context).get_abstract_state(task._schedule_index).get_value().state
    simulator.AdvanceTo(40 * dt)
    runs = {}
    for name, memory in (("kept", None), ("emptied", ScheduleMemory()), ("early", ScheduleMemory(early))):
        clone = context.Clone()
        if memory is not None:
            task.GetMyContextFromRoot(clone).get_mutable_abstract_state(task._schedule_index).set_value(memory)
        replay = Simulator(reach.diagram, clone)
        queried = 0
        for k in range(41, 61):
            replay.AdvanceTo(k * dt)
            queried += task.GetMyContextFromRoot(clone).get_abstract_state(task._schedule_index).get_value().state.queried
        runs[name] = (device.GetOutputPort("state").Eval(device.GetMyContextFromRoot(clone)).copy(), queried)
    assert np.array_equal(runs["emptied"][0], runs["kept"][0])
    assert np.array_equal(runs["early"][0], runs["kept"][0])
    assert runs["emptied"][1] > runs["kept"][1] and runs["early"][1] > runs["kept"][1]


def _shape_world(shapes):
    """A collision world of the robot and one obstacle per ``(name, shape)``, far from it and from
    each other: pairs of obstacles are not candidates, so each obstacle is paired with the robot."""
    from sotdrake import load_talos

    world = CollisionWorld(load_talos("reduced"))
    for k, (name, shape) in enumerate(shapes):
        add_obstacle(world, shape, RigidTransform([1.0 + 0.6 * k, 0.8, 0.9]), name)
    return world


@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_support_gaps_are_the_python_reference_and_lower_bounds(seed, talos_model):
    """:func:`.kernels.gaps` against the plain-Python support functions (every kind: hull vertices,
    box corners, ellipsoid, sphere, cylinder, capsule), and against Drake's signed distance: along a
    random direction the gap is at most the distance, along the query's own normal it equals it."""
    from pydrake.geometry import Box, Capsule, Cylinder, Ellipsoid, Sphere

    from sotdrake.collision.shapes import support, support_data

    shapes = [("box", Box(0.3, 0.2, 0.1)), ("ball", Sphere(0.12)), ("can", Cylinder(0.1, 0.4)),
              ("pill", Capsule(0.08, 0.3)), ("egg", Ellipsoid(0.1, 0.15, 0.2))]
    world = _shape_world(shapes)
    names = {world.obstacles[name] for name, _ in shapes}
    rng = np.random.default_rng(seed)
    context = world.new_context()
    q = talos_model.half_sitting.copy()
    q[7:] += 0.2 * rng.standard_normal(len(q) - 7)
    q[4:7] += [0.0, 0.0, 0.1] + 0.05 * rng.standard_normal(3)
    world.plant.SetPositions(world.plant_context(context), q)
    schedule = PairSchedule(world)
    chosen = [p for p, pair in enumerate(schedule.pairs) if names & set(pair)]  # robot links against each shape
    chosen += list(rng.choice(len(schedule.pairs), 60, replace=False))  # and self pairs (meshes)
    pairs = np.array(chosen, dtype=np.int64)
    query = world.query(context)
    inspector = world.scene_graph.model_inspector()
    directions = rng.standard_normal((len(pairs), 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    exact = [query.ComputeSignedDistancePairClosestPoints(*schedule.pairs[p]) for p in pairs]
    normals = np.array([r.nhat_BA_W if r.id_A == schedule.pairs[p][0] else -r.nhat_BA_W
                        for r, p in zip(exact, pairs, strict=True)])
    for n, tight in ((directions, False), (normals, True)):
        gaps = schedule.gaps(context, pairs, n)
        for gap, u, p, r in zip(gaps, n, pairs, exact, strict=True):
            a, b = schedule.pairs[p]
            X_WA, X_WB = query.GetPoseInWorld(a), query.GetPoseInWorld(b)
            low = u @ X_WA.translation() - support(support_data(inspector.GetShape(a)), -(X_WA.rotation().matrix().T @ u))
            high = u @ X_WB.translation() + support(support_data(inspector.GetShape(b)), X_WB.rotation().matrix().T @ u)
            assert gap == pytest.approx(low - high, abs=1e-12)
            assert gap <= r.distance + 1e-9
        if tight:  # (GJK converged on these separated pairs: its normal is the separating direction)
            distances = np.array([r.distance for r in exact])
            assert np.median(np.abs(gaps - distances)) < 1e-6


def test_the_schedule_takes_pairs_in_either_order(talos_model):
    """User pairs given as (b, a) where Drake answers for (a, b): the same pairs in range as the full
    query along a walk, and bounds below the exact distances."""
    world = CollisionWorld(talos_model)
    add_obstacle(world, ("box", TABLE[0]), RigidTransform(list(TABLE[1])), "table")
    context = world.new_context()
    reversed_pairs = [(b, a) for a, b in world.scene_graph.model_inspector().GetCollisionCandidates()]
    schedule = PairSchedule(world, reversed_pairs)
    state = ScheduleState()
    for k, q in enumerate(_walk(talos_model, np.random.default_rng(11), 60, 2e-2)):
        world.plant.SetPositions(world.plant_context(context), q)
        out = schedule.step(state, context, q, INFLUENCE_DISTANCE)
        state = out.state
        full = _in_range(world.query(context).ComputeSignedDistancePairwiseClosestPoints(INFLUENCE_DISTANCE))
        assert _in_range(out.in_range).keys() == full.keys(), f"tick {k}"
        if k % 20 == 0:
            query = world.query(context)
            exact = np.array([query.ComputeSignedDistancePairClosestPoints(a, b).distance for a, b in schedule.pairs])
            assert np.all(state.lower <= exact + 1e-12)
        if k == 0:  # every pair queried: the bounds of those out of range are their distances (tight gaps)
            far = exact >= INFLUENCE_DISTANCE
            assert np.median(exact[far] - state.lower[far]) < 1e-6


def test_gaps_refuse_pairs_without_support_and_bad_normals(scheduled):
    world, context, schedule = scheduled
    pairs = np.arange(3, dtype=np.int64)
    with pytest.raises(InvalidInput, match="normal"):
        schedule.gaps(context, pairs, np.zeros((2, 3)))
    saved = schedule._gapped.copy()
    try:
        schedule._gapped[1] = False  # (a shape without a support function: a half-space, a mesh without a hull)
        with pytest.raises(InvalidInput, match=r"without: \[1\]"):
            schedule.gaps(context, pairs, np.tile([0.0, 0.0, 1.0], (3, 1)))
    finally:
        schedule._gapped[:] = saved
