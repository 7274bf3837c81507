"""The collision pair schedule never misses a pair in range, and a cloned context replays it.

Every tick of random walks through the configuration space (the base translated and rotated, the
joints moved much faster than any stack moves them) is compared with Drake's full broad-phase query:
the scheduled pairs in range are exactly the query's, with the same distances, and every pair's
bound stays below its exact signed distance.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from sotdrake.collision import CollisionWorld, add_obstacle
from sotdrake.collision.distance import pair_distances
from sotdrake.collision.reach import TABLE, build_collision_reach
from sotdrake.collision.schedule import PairSchedule, ScheduleState, bounding_sphere
from sotdrake.collision.task import INFLUENCE_DISTANCE
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


def test_bounding_spheres_hold_the_shapes():
    from pydrake.geometry import Box, Capsule, Cylinder, Sphere

    assert bounding_sphere(Sphere(0.2))[1] == pytest.approx(0.2)
    assert bounding_sphere(Box(2.0, 2.0, 1.0))[1] == pytest.approx(1.5)
    assert bounding_sphere(Cylinder(0.3, 0.8))[1] == pytest.approx(0.5)
    assert bounding_sphere(Capsule(0.1, 0.4))[1] == pytest.approx(0.3)


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
    for k in range(1, 61):
        simulator.AdvanceTo(k * dt)
        q = device.GetOutputPort("state").Eval(device.GetMyContextFromRoot(context))
        world.plant.SetPositions(world.plant_context(check), q)
        full = pair_distances(world, check, INFLUENCE_DISTANCE)
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
    state = task.GetMyContextFromRoot(clone).get_abstract_state(task._schedule_index).get_value()
    assert copy.deepcopy(state).lower.tolist() == state.lower.tolist()
