"""Collision avoidance: distance Jacobians, pairs, bad inputs, the collision level under SolverKine and SolverDyn, the script.

The distances are checked against finite differences of Drake's own signed distance, stepping the
configuration on its manifold; the runs are checked tick by tick with Drake's query on a collision
world of their own (not the task's numbers).
"""

from __future__ import annotations

import importlib
import json

import numpy as np
import pytest
from pydrake.geometry import Cylinder, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder

from sotdrake import InvalidInput, SotError, StackError, add_sot, talos
from sotdrake.collision import (
    CollisionWorld,
    MetaTaskKineCollision,
    NoCollisionGeometry,
    TaskCollision,
    add_obstacle,
    check_margins,
    damper_rows,
    pair_distances,
    srdf_disabled_pairs,
)
from sotdrake.collision.distance import minimum_distance, signed_distance_pairs
from sotdrake.collision.reach import TABLE, build_collision_reach, run_collision_reach
from sotdrake.collision.targets import random_targets
from sotdrake.collision.task import SAFETY_DISTANCE, CollisionMargins
from sotdrake.configuration import Layout, integrate
from sotdrake.exceptions import FrameNotFound
from sotdrake.robots import load_robot

TOLERANCE = 1e-4  # m


@pytest.fixture(scope="module")
def world(talos_model):
    world = CollisionWorld(talos_model)
    add_obstacle(world, ("box", TABLE[0]), RigidTransform(list(TABLE[1])), "table")
    return world


def _random_configuration(model, rng, spread=0.3):
    q = model.half_sitting.copy()
    lower, upper = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()
    joints = np.isfinite(lower) & np.isfinite(upper)
    q[joints] = np.clip(q[joints] + spread * (rng.random(joints.sum()) - 0.5) * (upper - lower)[joints], lower[joints], upper[joints])
    q[4:7] += 0.1 * rng.standard_normal(3)  # the free flyer moves the whole robot, the table stays
    return q


def test_distance_jacobian_matches_finite_differences(world, talos_model, rng):
    """``J_d v`` against central differences of Drake's signed distance of each pair along random
    directions ``v``, stepping ``q ⊕ h v`` on the manifold, at random configurations. Where two step
    sizes disagree (a witness switch, where the distance has a kink, or the iterative distance's own
    round-off) the pair is skipped; at least 60 pairs and directions are checked."""
    context = world.new_context()
    plant_context = world.plant_context(context)
    layout = Layout.of(talos_model.plant)
    checked = 0
    for _ in range(6):
        q = _random_configuration(talos_model, rng)
        world.plant.SetPositions(plant_context, q)
        distances = pair_distances(world, context, 0.08)
        pairs = [(r.id_A, r.id_B) for r in signed_distance_pairs(world, context, 0.08)]  # the same order
        assert len(pairs) == len(distances.names)
        inspector = world.scene_graph.model_inspector()
        curved = np.array([any(isinstance(inspector.GetShape(g), (Cylinder, Sphere)) for g in pair) for pair in pairs])

        def distance_of(q_, pairs=pairs):
            world.plant.SetPositions(plant_context, q_)
            query = world.query(context)
            return np.array([query.ComputeSignedDistancePairClosestPoints(a, b).distance for a, b in pairs])

        for _ in range(3):
            v = rng.standard_normal(talos_model.nv)
            fd = {h: (distance_of(integrate(q, v, h, layout)) - distance_of(integrate(q, v, -h, layout))) / (2 * h)
                  for h in (1e-5, 1e-6)}
            smooth = np.abs(fd[1e-5] - fd[1e-6]) <= 1e-7
            # Polytopes (mesh hulls, boxes): exact. A curved side (the wrists' force-sensor
            # cylinders): Drake's iterative (GJK) distance gives the normal and the witness points to
            # its convergence tolerance, measured here at up to 2e-3 m/s on |J_d v| ~ 0.5 m/s.
            tolerance = np.where(curved, 5e-3, 1e-6)
            error = np.abs(distances.jacobian @ v - fd[1e-6])
            wrong = smooth & (error > tolerance)
            assert not wrong.any(), [(distances.names[i], distances.distance[i], error[i]) for i in np.flatnonzero(wrong)]
            checked += int(smooth.sum())
    assert checked >= 60


def test_one_tick_within_the_step_bound_never_brings_a_pair_closer_than_its_approach(world, talos_model, rng):
    """``PairSchedule.tick_approach``: random configurations, random per-velocity step bounds (some
    joints unbounded), random ticks within them (on the manifold, each velocity at ±its bound or
    inside): every pair's signed distance falls by at most its approach (inf for a pair whose path
    has an unbounded step). Checked with Drake's query of every pair."""
    from sotdrake.collision.schedule import PairSchedule

    schedule = PairSchedule(world)
    context = world.new_context()
    plant_context = world.plant_context(context)
    layout = Layout.of(talos_model.plant)

    def distances(q):
        world.plant.SetPositions(plant_context, q)
        query = world.query(context)
        return np.array([query.ComputeSignedDistancePairClosestPoints(a, b).distance for a, b in schedule.pairs])

    for trial in range(4):
        q = _random_configuration(talos_model, rng)
        step = rng.uniform(0.0, 0.03, talos_model.nv)
        if trial == 3:
            step[rng.choice(talos_model.nv, 3, replace=False)] = np.inf
        approach = schedule.tick_approach(step)
        assert approach.shape == (len(schedule.pairs),) and (approach >= 0).all()
        before = distances(q)
        for _ in range(2):
            v = np.where(np.isinf(step), rng.uniform(-0.5, 0.5, step.size),
                         np.where(rng.random(step.size) < 0.5, np.sign(rng.standard_normal(step.size)), rng.uniform(-1, 1, step.size))
                         * np.where(np.isinf(step), 0.0, step))
            after = distances(integrate(q, v, 1.0, layout))
            assert (after >= before - approach - 1e-9).all()
        if trial == 3:
            assert np.isinf(approach).any() and np.isfinite(approach).any()


def test_the_bias_acceleration_of_the_witness_points_matches_finite_differences(world, talos_model, rng):
    """``J̇_d v`` (the witness points fixed in their bodies, the normal held) against a central
    difference of ``n̂ᵀ (v_Ca − v_Cb)`` along ``q ⊕ h v`` at a constant ``v``, each point's velocity
    from Drake's own Jacobian of that body-fixed point, and ``J_d`` against those Jacobians: at
    random configurations and velocities, every pair in range, the table's pairs included."""
    from pydrake.multibody.tree import JacobianWrtVariable

    plant = world.plant
    context = world.new_context()
    plant_context = world.plant_context(context)
    layout = Layout.of(plant)
    world_frame = plant.world_frame()
    checked = 0
    for _ in range(4):
        q = _random_configuration(talos_model, rng)
        q[6] -= 0.25  # the hands near the table top
        v = rng.standard_normal(talos_model.nv)
        plant.SetPositions(plant_context, q)
        plant.SetVelocities(plant_context, v)
        distances = pair_distances(world, context, 0.3, bias=True)
        frames = [[plant.GetBodyByName(name).body_frame() if plant.HasBodyNamed(name) else None for name in pair]
                  for pair in distances.names]
        # The witness points in their bodies' frames, fixed from here on.
        fixed = []
        for (fa, fb), pa, pb in zip(frames, distances.p_WCa, distances.p_WCb, strict=True):
            fixed.append([None if f is None else plant.CalcRelativeTransform(plant_context, f, world_frame) @ p
                          for f, p in ((fa, pa), (fb, pb))])

        def jacobians(q_, frames=frames, fixed=fixed):
            plant.SetPositions(plant_context, q_)
            rows = []
            for (fa, fb), (pa, pb) in zip(frames, fixed, strict=True):
                sides = [np.zeros((3, talos_model.nv)) if f is None else
                         plant.CalcJacobianTranslationalVelocity(plant_context, JacobianWrtVariable.kV, f, p, world_frame, world_frame)
                         for f, p in ((fa, pa), (fb, pb))]
                rows.append(sides[0] - sides[1])
            return np.array(rows)  # k × 3 × nv

        n = distances.normal
        J_here = jacobians(q)
        np.testing.assert_allclose(distances.jacobian, np.einsum("ki,kin->kn", n, J_here), atol=1e-12)
        h = 1e-6
        fd = (np.einsum("ki,kin,n->k", n, jacobians(integrate(q, v, h, layout)), v)
              - np.einsum("ki,kin,n->k", n, jacobians(integrate(q, v, -h, layout)), v)) / (2 * h)
        np.testing.assert_allclose(distances.bias, fd, rtol=1e-5, atol=1e-5 * (1 + np.abs(fd).max()))
        checked += len(fd)
    assert checked >= 20


def test_the_schedules_rows_are_those_of_drakes_results_looked_up_one_by_one(world, talos_model, rng):
    """The collision task's rows (:meth:`PairTable.distances`, over the schedule's pairs) equal the
    rows :func:`distances_of` builds from the same results, looking each geometry up, at random
    configurations and velocities with the table: names, distances, normals, witness points,
    Jacobians and biases; and Drake answers every scheduled pair in the schedule's order."""
    from sotdrake.collision.distance import distances_of
    from sotdrake.collision.schedule import PairSchedule, ScheduleState

    schedule = PairSchedule(world)
    context = world.new_context()
    plant_context = world.plant_context(context)
    query_pairs = 0
    for _ in range(5):
        q = _random_configuration(talos_model, rng)
        q[6] -= 0.25  # the hands near the table top
        world.plant.SetPositions(plant_context, q)
        world.plant.SetVelocities(plant_context, rng.standard_normal(talos_model.nv))
        step = schedule.step(ScheduleState(), context, q, 0.3)
        assert [schedule.pairs[p][0] for p in step.state.in_range_pairs] == [r.id_A for r in step.in_range]
        mine = schedule.table.distances(world, context, step.in_range, step.state.in_range_pairs, bias=True)
        reference = distances_of(world, context, step.in_range, bias=True)
        assert mine.names == reference.names and any("table" in pair for pair in mine.names)
        for field in ("distance", "normal", "p_WCa", "p_WCb", "jacobian", "bias"):
            np.testing.assert_allclose(getattr(mine, field), getattr(reference, field), rtol=0, atol=1e-12, err_msg=field)
        query_pairs += len(mine.names)
    assert query_pairs >= 50


def test_each_body_gets_a_leaf_below_it_and_no_leaf_is_above_another(talos_model, rng):
    """:func:`kernels.cover` on random sets of TALOS' bodies (sides of random pairs, obstacles among
    them): each side's slot names its body, each body's leaf has it on its way to the world, and no
    leaf is on another's way (the fewest Jacobians)."""
    from sotdrake.collision.distance import _kernels, body_tree

    tree = body_tree(CollisionWorld(talos_model))
    nb = len(tree.bodies)
    for _ in range(200):
        k = int(rng.integers(1, 30))
        bodies = rng.integers(-1, nb, size=(2, k))
        needed, slots = np.empty(2 * k, dtype=np.int64), np.empty((2, k), dtype=np.int64)
        leaves, leaf_of = np.empty(2 * k, dtype=np.int64), np.empty(2 * k, dtype=np.int64)
        m, count = _kernels().cover(bodies, tree.depth, tree.ancestors, needed, slots, leaves, leaf_of)
        assert needed[:m].tolist() == sorted(set(bodies[bodies >= 0].tolist()))
        assert (np.where(slots >= 0, needed[slots], -1) == bodies).all()
        top = needed[leaves[:count]]
        assert all(tree.ancestors[top[leaf_of[j]], needed[j]] for j in range(m))
        assert not any(tree.ancestors[a, b] for a in top for b in top if a != b)


def test_obstacle_side_is_b_and_witness_points_are_apart_by_the_distance(world, talos_model):
    context = world.new_context()
    q = talos_model.half_sitting.copy()
    q[6] -= 0.25  # lower the robot: the hands come close to the table top
    world.plant.SetPositions(world.plant_context(context), q)
    distances = pair_distances(world, context, 0.3)
    rows = [i for i, (a, b) in enumerate(distances.names) if "table" in (a, b)]
    assert rows, "no link near the table"
    for i in rows:
        assert distances.names[i][1] == "table"
        gap = distances.p_WCa[i] - distances.p_WCb[i]
        assert np.isclose(gap @ distances.normal[i], distances.distance[i], atol=1e-6)


def test_self_pairs_leave_out_the_srdf_and_adjacent_pairs(world, talos_model):
    disabled = srdf_disabled_pairs(talos_model.srdf_path)
    assert frozenset(("arm_left_1_link", "arm_left_3_link")) in disabled
    pairs = {frozenset(pair) for pair in world.self_pairs()}
    assert pairs and not pairs & disabled and not pairs & world.adjacent
    plant = world.plant
    for a, b in map(tuple, pairs):  # never two bodies welded together: their distance cannot change
        assert b not in {body.name() for body in plant.GetBodiesWeldedTo(plant.GetBodyByName(a))}
    assert frozenset(("gripper_left_motor_single_link", "gripper_left_inner_single_link")) in world.adjacent  # (welded siblings)
    context = world.new_context()
    for _ in range(3):
        world.plant.SetPositions(world.plant_context(context), talos_model.half_sitting)
        found = {frozenset(names) for names in pair_distances(world, context, 0.2).names}
        assert found and not found & (disabled | world.adjacent)


def test_damper_rows_and_margins():
    from sotdrake.collision.distance import PairDistances

    d = np.array([0.05, 0.03, 0.011, 0.01095, 0.01, 0.0])
    distances = PairDistances([("a", "b")] * 6, d, np.zeros((6, 3)), np.zeros((6, 3)), np.zeros((6, 3)), np.ones((6, 4)))
    rows = damper_rows(distances, CollisionMargins(0.01, 0.05, 0.4), dt=1e-3)
    # −ξ(d − d_t)/(d_i − d_t) beyond d_t = d_s + 1 mm; inside, a small shortfall undone in one tick, at most ξ
    np.testing.assert_allclose(rows.lower, [-0.4, -0.4 * 0.019 / 0.039, 0.0, 0.05, 0.4, 0.4])
    assert np.all(np.isinf(rows.upper)) and not rows.is_equality


@pytest.mark.parametrize(("safety", "influence", "xi", "word"), [
    (-0.01, 0.05, 0.5, "safety"), (0.05, 0.05, 0.5, "influence"), (0.06, 0.05, 0.5, "influence"),
    (0.01, 0.05, 0.0, "xi"), (0.01, 0.05, -1.0, "xi"), (0.01, 0.05, float("nan"), "xi"), (0.01, 0.05, 50.0, "xi"),
    (0.01, 0.011, 0.5, "influence"), (0.01, 0.015, 5.0, "too stiff"),
])
def test_bad_margins_are_refused(safety, influence, xi, word):
    with pytest.raises(InvalidInput, match=word):
        check_margins(safety, influence, xi, 1e-3)


def test_a_task_s_size_tick_and_margins_of_the_wrong_kind_are_refused(world):
    for dt in (0.0, -1.0, float("nan"), "1e-3"):
        with pytest.raises(InvalidInput, match="dt"):
            check_margins(0.01, 0.05, 0.5, dt)  # type: ignore[arg-type]
    nv = world.plant.num_velocities()
    for bad in ({"nv": float(nv)}, {"nv": True}, {"margins": (0.01, 0.05, 0.5)}):
        arguments = {"nv": nv, "margins": None, **bad}
        with pytest.raises(InvalidInput, match=r"nv|margins"):
            TaskCollision("taskc", world, arguments["nv"], 1e-3, margins=arguments["margins"])


def test_bad_pairs_are_refused(world):
    nv = world.plant.num_velocities()
    for pairs, error, word in [
        ([("arm_right_7_link", "torso_3_link")], FrameNotFound, "torso_3_link"),
        ([("arm_right_7_link", "arm_right_7_link")], InvalidInput, "same body"),
        ([("arm_right_6_link", "arm_right_7_link")], InvalidInput, "joined by a joint"),
        ([("gripper_right_base_link", "gripper_right_fingertip_1_link")], InvalidInput, "welded"),
        ([("table", "table2")], FrameNotFound, "table2"),
        ([("arm_right_7_link",)], InvalidInput, "two names"),
        ([("arm_right_7_link", "torso_2_link"), ("torso_2_link", "arm_right_7_link")], InvalidInput, "given twice"),
        ([], InvalidInput, "empty"),
    ]:
        with pytest.raises(error, match=word):
            TaskCollision("c", world, nv, 1e-3, pairs)


def test_bad_obstacles_are_refused_and_nothing_is_added(talos_model, tmp_path):
    world = CollisionWorld(talos_model)
    flat = tmp_path / "flat.obj"
    flat.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    garbage = tmp_path / "garbage.obj"
    garbage.write_text("not a mesh")
    tetrahedron = "v 0 0 0\nv {} 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
    nan, huge = tmp_path / "nan.obj", tmp_path / "huge.obj"
    nan.write_text("v nan 0 0\n" + tetrahedron.format(1))  # (the hull left the NaN vertex out: accepted)
    huge.write_text(tetrahedron.format(1e6))  # (a described shape beyond 100 m is refused; this was not)
    for shape, pose, word in [
        (("mesh", str(nan)), RigidTransform(), "line 1"),
        (("mesh", str(huge)), RigidTransform(), "spans"),
        (("box", (0.0, 1.0, 1.0)), RigidTransform(), "box size x"),
        (("sphere", -0.1), RigidTransform(), "sphere radius"),
        (("cylinder", 0.1, float("inf")), RigidTransform(), "cylinder length"),
        (("box", (1.0, 1.0, 1.0)), np.full((4, 4), np.nan), "X_WO"),
        (("box", (1.0, 1.0, 1.0)), np.diag([2.0, 1.0, 1.0, 1.0]), "rigid transform"),
        (("mesh", str(tmp_path / "missing.obj")), RigidTransform(), "does not exist"),
        (("mesh", str(garbage)), RigidTransform(), "no face"),
        (("mesh", str(flat)), RigidTransform(), "no volume"),
        (("cone", 1.0), RigidTransform(), "unknown shape"),
        (("box", (1e-300, 0.1, 0.1)), RigidTransform(), "box size x"),
    ]:
        with pytest.raises(InvalidInput, match=word):
            add_obstacle(world, shape, pose, "obstacle")
    for taken in ("torso_2_link", "world", "imu_link"):  # (a body without collision geometry too: its name is taken)
        with pytest.raises(InvalidInput, match="link"):
            add_obstacle(world, ("sphere", 0.1), RigidTransform(), taken)
    for taken in ("right-wrist", "arm_right_7_joint", "root_joint", "leg_right_sole_fix_joint"):  # a pair would mean the obstacle
        with pytest.raises(InvalidInput, match="frame, joint or op point"):
            add_obstacle(world, ("sphere", 0.1), RigidTransform(), taken)
    assert world.obstacles == {}
    add_obstacle(world, ("sphere", 0.1), RigidTransform([1.0, 0, 1.0]), "ball")
    world.new_context()
    with pytest.raises(SotError, match="before building"):
        add_obstacle(world, ("sphere", 0.1), RigidTransform([2.0, 0, 1.0]), "late")
    assert list(world.obstacles) == ["ball"]


@pytest.mark.parametrize("faces, word", [("", "no face"), ("l 1 2\nl 2 3\n", "no face"), ("f 1 2 9\n", "line 5"),
                                         ("f 1 2\n", "line 5"), ("f 1 2 -5\n", "line 5"), ("f 1 2 3.5\n", "line 5"),
                                         ("f 0 1 2\n", "line 5"), ("f 1/1 2/2 nan\n", "line 5")])
def test_an_obj_mesh_drake_would_register_halfway_is_refused_and_a_retry_works(talos_model, tmp_path, faces, word):
    """Vertices without faces, or a face index out of range: the convex hull (vertices only) exists, but
    Drake's registration fails halfway (the name stays taken) or stops the process. Read first, refused."""
    world = CollisionWorld(talos_model)
    mesh = tmp_path / "mesh.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n" + faces)
    geometries = world.scene_graph.model_inspector().num_geometries()
    with pytest.raises(InvalidInput, match=word):
        add_obstacle(world, ("mesh", str(mesh)), RigidTransform([1.0, 0, 1.0]), "o1")
    assert world.obstacles == {} and world.scene_graph.model_inspector().num_geometries() == geometries
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf -3 -2 -1\n")
    add_obstacle(world, ("mesh", str(mesh)), RigidTransform([1.0, 0, 1.0]), "o1")
    assert list(world.obstacles) == ["o1"]


def test_robot_without_collision_geometry_is_named(tmp_path):
    urdf = tmp_path / "stick.urdf"
    urdf.write_text("""<robot name="stick"><link name="base"/><link name="arm"><inertial><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
      <visual><geometry><box size="0.1 0.1 0.5"/></geometry></visual></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1" effort="10" velocity="1"/></joint></robot>""")
    with pytest.raises(NoCollisionGeometry, match="no collision geometry"):
        CollisionWorld(load_robot(str(urdf)))


def test_set_margins_checks_everything_first():
    builder = DiagramBuilder()
    robot = talos(builder)
    add_sot(robot, solver="hqp")
    meta = MetaTaskKineCollision(robot)
    before = CollisionMargins(**vars(meta.task.settings()))
    with pytest.raises(InvalidInput, match="influence"):
        meta.setMargins(0.02, 0.01, 0.5)
    assert meta.task.settings() == before
    meta.setMargins(0.02, 0.06, 0.3)
    assert meta.task.settings() == CollisionMargins(0.02, 0.06, 0.3)


def test_the_basic_sot_refuses_the_collision_level_naming_the_solvers():
    builder = DiagramBuilder()
    robot = talos(builder)
    sot = add_sot(robot)
    meta = MetaTaskKineCollision(robot)
    with pytest.raises(StackError, match=r"SolverKine.*SolverDyn"):
        sot.push(meta)


@pytest.fixture(scope="module")
def reach():
    return build_collision_reach(collision=True, table=True)


def test_random_targets_never_cross_the_safety_distance(reach):
    """A fast subset of bench/collision_runs.py: targets inside the torso, across the body, inside
    and under the table; every tick: distance ≥ d_s − 1e-4 m, ankles within 1e-4 m, limits, no NaN,
    no solver failure."""
    for _family, target in random_targets(4, np.random.default_rng(7)):
        report = run_collision_reach(reach, target, duration=0.25, gain=10.0)
        assert report.min_distance >= SAFETY_DISTANCE - TOLERANCE, report
        assert report.feet_drift <= TOLERANCE and report.limit_excess <= 1e-9, report
        assert not report.nan and not report.failures, report


def test_the_collision_level_is_strict_above_the_hand():
    """The hand point sent to the centre of a ball of radius 0.15 m: reaching it would put the wrist
    (0.1 m from the point) inside the ball. Without the level the hand gets there through the ball;
    with it, no pair ever comes closer than d_s and the hand gives way (stops short)."""
    centre = np.array([0.45, -0.35, 1.0])
    ball = [(("sphere", 0.15), RigidTransform(list(centre)), "ball")]
    free = build_collision_reach(collision=False, table=False, obstacles=ball)
    through = run_collision_reach(free, centre, duration=0.8, check_every=20, gain=10.0)
    assert through.min_distance < -0.05 and through.hand_error < 0.01
    kept_reach = build_collision_reach(collision=True, table=False, obstacles=ball)
    kept = run_collision_reach(kept_reach, centre, duration=0.8, gain=10.0)
    assert kept.min_distance >= SAFETY_DISTANCE - TOLERANCE
    assert kept.hand_error > 0.05
    assert not kept.failures and kept.feet_drift <= TOLERANCE


def test_a_pair_one_tick_can_bring_within_reach_has_its_row_before_the_influence_distance():
    """The hand flung at a target high above the table (gain 8 /s from 0.7 m away, 5 ms ticks): the
    level reads the solver's step bound (the reach map's step limit), so that a pair one tick may
    bring within d_s has its row before d_i, and every pair stays beyond d_s (with an unlimited step
    and rows only within d_i, a gripper link went from 5 cm above the table to 5.8 mm in one tick)."""
    from sotdrake.scenarios import reach_map

    reach = reach_map.build_diagram(0.005, "reduced", "table", True)
    task = next(s for s in reach.diagram.GetSystems() if isinstance(s, TaskCollision))
    assert task.GetInputPort("step_bound").HasValue(task.GetMyContextFromRoot(reach.diagram.CreateDefaultContext()))
    simulator = reach_map.simulate_target(reach, (0.575, 0.1, 1.8), 0.1)
    assert reach_map.summarize(reach, simulator, (0.575, 0.1, 1.8))["min_signed_distance_m"] >= SAFETY_DISTANCE - TOLERANCE


def test_a_braking_reach_at_a_coarse_tick_keeps_the_safety_distance():
    """A fast reach (gain 50) by the torso at a 10 ms tick, stiff damper (ξ dt just under d_i − d_s):
    the arm brakes at the table, and no row may be loosened by the last tick's faster motion or by
    another pair's correction (the pairs in range change from tick to tick)."""
    coarse = build_collision_reach(collision=True, table=True, safety=0.0, influence=0.05, xi=4.8, dt=0.01)
    report = run_collision_reach(coarse, np.array([-0.049, 0.079, 1.245]), duration=0.4, gain=50.0)
    assert report.min_distance >= -TOLERANCE, report
    assert not report.nan and not report.failures, report


@pytest.mark.slow
def test_the_acceleration_level_keeps_the_safety_distance_under_solver_dyn(talos_model):
    """The dynamic SoT (SolverDyn, both soles in contact, the CoM, the collision level at the
    acceleration level, the hand, the posture): the hand point sent to the centre of the ball, as
    above. Every tick, by Drake's query: no pair closer than d_s − 1e-4 m; the hand stops short."""
    from sotdrake import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture, RobotDyn
    from sotdrake.collision import MetaTaskDynCollision, minimum_distance
    from sotdrake.robots import TALOS_GRIPPERS

    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, "dynsimu", 1e-3)
    sot = robot.sot
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    for name, op in (("contactLF", "left-sole"), ("contactRF", "right-sole")):
        sot.addContact(robot.add_contact(name, op))
    sot.push(MetaTaskDynCom(robot).task.name)
    centre = np.array([0.45, -0.35, 1.0])
    ball = (("sphere", 0.15), RigidTransform(list(centre)), "ball")
    checker = CollisionWorld(talos_model)
    for world in (robot, checker):
        add_obstacle(world, *ball)
    sot.push(MetaTaskDynCollision(robot).task.name)
    hand = MetaTaskDyn6d("rh", robot, "right-wrist", kp=100.0)
    hand.feature.setOpmodif(RigidTransform([0.1, 0.0, 0.0]))
    hand.feature.selec("000111")
    hand.featureDes.setPosition(RigidTransform(list(centre)))
    sot.push(hand.task.name)
    sot.push(MetaTaskDynPosture(robot, kp=25.0).task.name)
    from pydrake.systems.analysis import Simulator

    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    simulator.Initialize()
    checker_context = checker.new_context()
    device_context = robot.device.GetMyContextFromRoot(context)
    smallest = np.inf
    for k in range(1, 601):
        simulator.AdvanceTo(k * 1e-3)
        x = robot.device.GetOutputPort("state").Eval(device_context)
        assert np.all(np.isfinite(x))
        smallest = min(smallest, minimum_distance(checker, checker_context, x[: talos_model.nq], 0.05))
    assert smallest >= SAFETY_DISTANCE - TOLERANCE
    plant_context = talos_model.plant.CreateDefaultContext()
    talos_model.plant.SetPositions(plant_context, x[: talos_model.nq])
    p_hand = talos_model.plant.CalcRelativeTransform(plant_context, talos_model.plant.world_frame(),
                                                     talos_model.frame("right-wrist")) @ np.array([0.1, 0.0, 0.0])
    assert np.linalg.norm(p_hand - centre) > 0.05


@pytest.mark.slow
def test_talos_collisions_script_keeps_the_safety_distance_with_the_level(tmp_path):
    script = importlib.import_module("sotdrake.scenarios.talos_collisions")
    summary = script.main(["--duration", "0.3", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    assert json.loads((tmp_path / "summary.json").read_text()) == json.loads(json.dumps(summary))
    assert set(summary["runs"]) == {"across_torso", "into_torso", "under_table"}
    for run in summary["runs"].values():
        assert run["with"]["min_signed_distance_m"] >= SAFETY_DISTANCE - TOLERANCE
        assert run["with"]["solver_failures"] == 0 and run["with"]["feet_drift_m"] <= TOLERANCE
    assert min(run["without"]["min_signed_distance_m"] for run in summary["runs"].values()) < 0.0


@pytest.mark.parametrize("script", ["talos_collisions", "pr2_shelf"])
def test_the_scripts_refuse_a_run_shorter_than_a_tick(tmp_path, script):
    main = importlib.import_module(f"sotdrake.scenarios.{script}").main
    with pytest.raises(SystemExit, match="at least one tick"):
        main(["--duration", "0.0004", "--out", str(tmp_path / "out"), "--quiet", "--no-meshcat"])
    assert not (tmp_path / "out").exists()


def test_a_check_of_a_run_refuses_what_drake_would_abort_on(world, reach):
    context = world.new_context()
    for q in (np.zeros(3), np.full(world.plant.num_positions(), np.nan)):
        with pytest.raises(InvalidInput, match="minimum_distance: q"):
            minimum_distance(world, context, q)
    for duration in (0.0004, 0.0, float("nan")):
        with pytest.raises(InvalidInput, match="duration: expected at least one tick"):
            run_collision_reach(reach, np.array([0.5, -0.2, 1.0]), duration=duration)


def test_acceleration_rows_are_a_second_order_damper_that_keeps_its_set():
    """The acceleration rows ``d̈ ≥ −λ ḋ − (ḋ + λ (d − d_t))/T − J̇_d v`` (λ = ξ/(d_i − d_t)), and a
    pair driven at the least acceleration they allow (semi-implicit Euler at 1 ms, the device's
    scheme), from inside the damper's set (ḋ ≥ −λ (d − d_t)) at speeds up to 3 m/s, never crosses
    d_t by more than a micrometre; from outside it (a pair taken late), it returns within a few T."""
    from sotdrake.collision.distance import PairDistances
    from sotdrake.collision.task import RECOVERY_TIME, TICK_ALLOWANCE, acceleration_rows, damper_rate

    margins, dt = CollisionMargins(0.01, 0.05, 0.5), 1e-3
    lam, d_t = damper_rate(margins), 0.01 + TICK_ALLOWANCE
    assert lam == pytest.approx(0.5 / (0.05 - d_t))
    d, J = np.array([0.3, 0.05, 0.02, 0.005]), np.eye(4, 5)
    v, bias = np.array([-2.0, -0.3, 0.1, 0.0, 9.0]), np.array([0.5, -1.0, 0.0, 2.0])
    distances = PairDistances([("a", "b")] * 4, d, np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 3)), J, bias=bias)
    rows = acceleration_rows(distances, margins, dt, v)
    rate = J @ v
    np.testing.assert_allclose(rows.lower, -lam * rate - (rate + lam * (d - d_t)) / RECOVERY_TIME - bias)
    assert np.all(np.isinf(rows.upper)) and not rows.is_equality
    for speed in (0.05, 0.5, 1.0, 3.0):
        h = speed / lam  # on the edge of the damper's set: e = ḋ + λ h = 0
        for start_excess in (0.0, -0.2):
            x, xdot = d_t + h, -speed + start_excess
            lowest = x
            for _ in range(3000):
                one = PairDistances([("a", "b")], np.array([x]), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)),
                                    np.ones((1, 1)), bias=np.zeros(1))
                xddot = acceleration_rows(one, margins, dt, np.array([xdot])).lower[0]
                xdot += dt * xddot
                x += dt * xdot
                lowest = min(lowest, x)
            if start_excess == 0.0:
                assert lowest >= d_t - 1e-6, speed
            else:
                assert lowest >= d_t - 0.2 * 2 * RECOVERY_TIME, speed  # at most |e₀| T of extra approach


def test_speed_aware_influence_takes_fast_pairs_before_the_influence_distance():
    from sotdrake.collision.task import TICK_ALLOWANCE, damper_rate, speed_aware_influence

    margins = CollisionMargins(0.01, 0.05, 0.5)
    reach = speed_aware_influence(margins, np.array([0.0, 0.5, 1.8]))
    assert reach[0] == reach[1] == pytest.approx(0.05)  # at ξ or slower: d_i
    assert reach[2] == pytest.approx(0.01 + TICK_ALLOWANCE + 1.8 / damper_rate(margins))


def test_approach_bound_holds_the_pairs_approach_speed(world, talos_model, rng):
    """``PairSchedule.approach_bound`` against ``|J_d v|`` of Drake's closest points, per pair, at
    random configurations and velocities (self pairs and link–table pairs)."""
    from sotdrake.collision.distance import pair_distances
    from sotdrake.collision.schedule import PairSchedule

    schedule = PairSchedule(world)
    context = world.new_context()
    plant = world.plant
    checked = 0
    for _ in range(4):
        plant.SetPositions(world.plant_context(context), _random_configuration(talos_model, rng))
        plant.SetVelocities(world.plant_context(context), 2.0 * rng.standard_normal(plant.num_velocities()))
        bound = schedule.approach_bound(context)
        v = plant.GetVelocities(world.plant_context(context))
        for p in rng.choice(len(schedule.pairs), size=60, replace=False):
            rows = pair_distances(world, context, np.inf, geometry_pairs=[schedule.pairs[p]])
            speed = abs(float(rows.jacobian[0] @ v))
            assert speed <= bound[p] * (1 + 1e-9) + 1e-12, (schedule.pairs[p], speed, bound[p])
            checked += speed > 0.05
    assert checked > 100  # the bound was tested on pairs that do move
