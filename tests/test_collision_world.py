"""The collision world beyond single shapes: scenes from URDF/SDF, obstacles in the physics plant.

Scenes are checked against the shapes their files give (poses, names), the controller's collision
world (a link's distance to a scene obstacle by Drake's query) and bad input (nothing added). The
physics side: the obstacles are anchored collision and visual geometry of the simulated plant, and the
simulated robot touching one is pushed by it (a contact force on that geometry).
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from pydrake.geometry import Box, Role, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import InvalidInput, SotError
from sotdrake.collision import SHELF, CollisionWorld, add_obstacle, add_scene, minimum_distance, obstacle_geometries, scene_shapes

TABLE_URDF = """<robot name="table">
  <link name="top"><collision><origin xyz="0 0 0.7"/><geometry><box size="0.6 1.0 0.04"/></geometry></collision></link>
  <link name="leg"><collision name="leg"><geometry><cylinder radius="0.02" length="0.68"/></geometry></collision></link>
  <joint name="leg_joint" type="fixed"><parent link="top"/><child link="leg"/><origin xyz="0.25 0.45 0.34"/></joint>
</robot>"""


@pytest.fixture(scope="module")
def world(talos_model):
    return CollisionWorld(talos_model)


def test_shelf_scene_gives_every_board_at_its_pose():
    X_WS = RigidTransform([1.0, 0.2, 0.0])
    shapes = {name: (shape, pose) for name, shape, pose in scene_shapes(SHELF, X_WS, "shelf")}
    assert set(shapes) == {f"shelf/{p}" for p in ("bottom", "board_low", "board_middle", "top", "side_left", "side_right", "back")}
    shape, pose = shapes["shelf/back"]
    assert isinstance(shape, Box) and np.allclose([shape.width(), shape.depth(), shape.height()], [0.02, 0.76, 1.18])
    np.testing.assert_allclose(pose.translation(), [1.19, 0.2, 0.59], atol=1e-12)


def test_urdf_text_scene_welds_its_root_and_places_child_links(world, talos_model):
    names = add_scene(world, TABLE_URDF, RigidTransform([0.6, -0.2, 0.0]), "table_scene")
    assert len(names) == 2 and all(n in world.obstacles for n in names)
    poses = {n: world.obstacle_shapes[n][1].translation() for n in names}
    np.testing.assert_allclose(poses["table_scene/leg"], [0.85, 0.25, 0.34], atol=1e-12)
    # The top is in the controller's collision world: the right hand's distance to it by Drake's query.
    context = world.new_context()
    top = next(n for n in names if n != "table_scene/leg")
    pairs = world.geometry_pairs([("arm_right_7_link", top)])
    d = minimum_distance(world, context, talos_model.half_sitting, 5.0, pairs)
    assert 0.0 < d < 1.0


@pytest.mark.parametrize("source, word", [
    ("/nonexistent/shelf.sdf", "not an existing"),
    ("<robot name='r'><link name='a'/></robot>", "no collision geometry"),
    ("<robot name='r'><link name='a'><collision><geometry><mesh filename='/nonexistent/m.obj'/></geometry></collision>"
     "</link></robot>", "m.obj"),
    ("<robot name='r'><link name='a'>", "could not parse"),
    # (SDFormat replaces these by its 1 m defaults, with a warning only)
    ("<sdf version='1.7'><model name='m'><static>true</static><link name='l'><collision name='c'><geometry><box>"
     "<size>0 1 1</size></box></geometry></collision></link></model></sdf>", "box's size"),
    ("<sdf version='1.7'><model name='m'><static>true</static><link name='l'><collision name='c'><geometry><sphere>"
     "<radius>-1</radius></sphere></geometry></collision></link></model></sdf>", "sphere's radius"),
])
def test_bad_scenes_are_refused_and_nothing_is_added(talos_model, source, word):
    world = CollisionWorld(talos_model)
    with pytest.raises(SotError, match=word):
        add_scene(world, source, None, "bad")
    assert world.obstacles == {}


def test_a_scene_name_taken_is_refused_before_anything_is_added(talos_model):
    world = CollisionWorld(talos_model)
    add_obstacle(world, ("sphere", 0.1), RigidTransform([2.0, 0.0, 0.5]), "shelf/back")
    with pytest.raises(InvalidInput, match="taken"):
        add_scene(world, SHELF, None, "shelf")
    assert list(world.obstacles) == ["shelf/back"]
    with pytest.raises(InvalidInput, match="X_WS"):
        add_scene(world, SHELF, np.full((4, 4), np.nan), "other")


def _wrist_position(talos_model) -> np.ndarray:
    plant = talos_model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, talos_model.half_sitting)
    return plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("arm_right_7_link")).translation()


def test_obstacles_are_in_the_physics_plant_and_push_the_robot(talos_model):
    """A ball around the right wrist and the shelf: both anchored collision and visual geometry
    of the simulated plant; the wrist's box touching the ball feels a contact force from it."""
    from sotdrake.physics import add_talos_station

    world = CollisionWorld(talos_model)
    add_obstacle(world, ("sphere", 0.03), RigidTransform(_wrist_position(talos_model)), "ball")
    add_scene(world, SHELF, RigidTransform([1.5, 0.0, 0.0]), "shelf")
    obstacles = obstacle_geometries(world)
    builder = DiagramBuilder()
    station = add_talos_station(builder, talos_model.half_sitting, obstacles=obstacles)
    builder.ExportInput(station.position, "position")
    builder.ExportInput(station.velocity, "velocity")
    diagram = builder.Build()
    physical = station.physical
    inspector = physical.scene_graph.model_inspector()
    names = {inspector.GetName(g): g for g in inspector.GetAllGeometryIds(Role.kProximity)}
    ball = names["obstacle/ball"]
    assert isinstance(inspector.GetShape(ball), Sphere)
    assert inspector.GetFrameId(ball) == inspector.world_frame_id()
    assert len([n for n in names if n.startswith("obstacle/shelf/")]) == 7
    visuals = {inspector.GetName(g) for g in inspector.GetAllGeometryIds(Role.kIllustration)}
    assert {"obstacle/ball_visual", "obstacle/shelf/back_visual"} <= visuals
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.get_input_port(0).FixValue(context, talos_model.half_sitting)
    diagram.get_input_port(1).FixValue(context, np.zeros(talos_model.nv))
    simulator.AdvanceTo(0.01)
    plant = physical.plant
    results = plant.get_contact_results_output_port().Eval(plant.GetMyContextFromRoot(context))
    forces = [np.linalg.norm(results.point_pair_contact_info(i).contact_force())
              for i in range(results.num_point_pair_contacts())
              if ball in (results.point_pair_contact_info(i).point_pair().id_A, results.point_pair_contact_info(i).point_pair().id_B)]
    assert forces and max(forces) > 1.0


@pytest.mark.parametrize("obstacles, word", [
    ("table", "list of"),
    ([("a", Box(1, 1, 1))], "each must be"),
    ([("a", Box(1, 1, 1), RigidTransform()), ("a", Sphere(1), RigidTransform())], "twice"),
    ([("", Box(1, 1, 1), RigidTransform())], "each must be"),
])
def test_bad_physics_obstacles_are_refused(obstacles, word):
    from sotdrake.physics import add_physical_talos

    with pytest.raises(InvalidInput, match=word):
        add_physical_talos(DiagramBuilder(), obstacles=obstacles)


@pytest.mark.slow
def test_pr2_shelf_script_keeps_the_arm_off_the_boards_and_reaches(tmp_path):
    """PR2 into the shelf's compartments: without the level the arm goes through a board (a negative
    distance by Drake's query); with it no arm–shelf pair comes closer than d_s − 1e-4 m, and every
    target is still reached."""
    script = importlib.import_module("sotdrake.scenarios.pr2_shelf")
    summary = script.main(["--duration", "2.5", "--out", str(tmp_path), "--quiet", "--no-meshcat"])
    runs = summary["runs"]
    assert set(runs) == {"low", "middle", "high"}
    assert min(run["without"]["min_signed_distance_m"] for run in runs.values()) < 0.0
    for run in runs.values():
        assert run["with"]["min_signed_distance_m"] >= 0.01 - 1e-4
        assert run["with"]["reached"] and run["with"]["hand_error_m"] < 0.01


@pytest.fixture(scope="module")
def reach_map():
    return importlib.import_module("sotdrake.scenarios.reach_map")


def test_reach_map_counts_a_colliding_path_as_not_reached(reach_map):
    """A target under the table top: with no obstacle the hand gets there; with the table its path
    goes through the top (a negative distance by Drake's query), so it is not reached although the
    hand ends on it; with the collision level the path stays clear and the hand stops short."""
    target = {"x": 0.5, "y": -0.3, "z": 0.7}
    free = reach_map.reach_case(target, duration=1.0, dt=0.02)
    assert free["reached"] and free["min_signed_distance_m"] >= 0.0
    through = reach_map.reach_case(target, duration=1.0, dt=0.02, obstacles="table")
    assert through["hand_error_m"] < reach_map.REACHED_M
    assert through["collides"] and through["min_signed_distance_m"] < -0.05 and not through["reached"]
    kept = reach_map.reach_case(target, duration=1.0, dt=reach_map.MAX_COLLISION_DT, obstacles="table", collision=True)
    assert not kept["collides"] and kept["min_signed_distance_m"] >= 0.01 - 1e-4
    assert not kept["reached"] and kept["hand_error_m"] > 0.05
    with pytest.raises(InvalidInput, match=r"at most 0\.01 s"):  # (one 20 ms tick can carry a link through the table)
        reach_map.build_diagram(0.02, obstacles="table", collision=True)


def test_reach_map_script_with_a_scene_and_the_level(reach_map, tmp_path):
    """A 2 × 2 × 2 grid with a table top in front of the robot (an SDF scene file, its model placed
    by its own pose) and the collision level: no path collides; a missing scene file stops the
    script with its name."""
    scene = tmp_path / "table.sdf"
    scene.write_text("""<sdf version="1.7"><model name="table"><static>true</static><pose>0.55 -0.25 0.8 0 0 0</pose>
      <link name="top"><collision name="top"><geometry><box><size>0.5 0.8 0.04</size></box></geometry></collision></link>
      </model></sdf>""")
    summary = reach_map.main(["--targets", "8", "--duration", "0.2", "--out", str(tmp_path), "--quiet",
                              "--obstacles", str(scene), "--collision"])
    assert summary["errors"] == 0 and summary["colliding_paths"] == 0 and summary["min_signed_distance_m"] > 0
    assert summary["obstacles"] == str(scene) and summary["collision_level"] is True
    with pytest.raises(SystemExit, match=r"at most 0\.01 s"):
        reach_map.main(["--targets", "8", "--out", str(tmp_path), "--quiet", "--collision", "--dt", "0.1"])
    with pytest.raises(SystemExit, match=r"missing\.sdf"):
        reach_map.main(["--targets", "8", "--out", str(tmp_path), "--quiet", "--obstacles", "/nonexistent/missing.sdf"])


def test_pairs_the_solver_cannot_move_get_no_row(talos_model):
    """TALOS' gripper links rest 10.19 mm apart, inside d_s + 1 mm: without the control selection
    their pair asks a recovery the solver (which does not drive the grippers) cannot give, an
    infeasible row at every tick; with it that pair gets no row, and every row left can be acted on."""
    from sotdrake import TALOS_GRIPPERS
    from sotdrake.collision import TaskCollision

    plant, nv = talos_model.plant, talos_model.nv
    controlled = np.ones(nv, dtype=bool)
    for name in TALOS_GRIPPERS:
        joint = plant.GetJointByName(name)
        controlled[joint.velocity_start(): joint.velocity_start() + joint.num_velocities()] = False
    world = CollisionWorld(talos_model)
    rows = {}
    for label, mask in (("all", None), ("selected", controlled)):
        task = TaskCollision(label, world, nv, 1e-3, controlled=mask)
        context = task.CreateDefaultContext()
        task.GetInputPort("position").FixValue(context, talos_model.half_sitting)
        rows[label] = task.GetOutputPort("task").Eval(context)
    unmovable = np.abs(rows["all"].jacobian[:, controlled]).max(axis=1) <= 1e-9
    assert unmovable.any() and (rows["all"].lower[unmovable] > 0).any()  # the infeasible recovery rows
    assert len(rows["selected"].lower) == len(rows["all"].lower) - unmovable.sum()
    assert (np.abs(rows["selected"].jacobian[:, controlled]).max(axis=1) > 1e-9).all()
    with pytest.raises(InvalidInput, match="controlled"):
        TaskCollision("bad", world, nv, 1e-3, controlled=np.ones(nv - 1, dtype=bool))


@pytest.mark.slow
def test_dynamic_random_targets_keep_the_distance_without_solver_failure(talos_model):
    """A fast subset of ``bench/collision_runs.py --dynamic``: SolverDyn, both soles in contact, the
    collision level at the acceleration level, the hand to random targets (the torso, across the
    body, the table, under it). Every tick by Drake's query: distance ≥ d_s − 1e-4 m, soles within
    1e-4 m, no joint limit crossed, no NaN, and not one tick on which the solver gave up."""
    from sotdrake.collision.reach import build_dyn_collision_reach, run_dyn_collision_reach
    from sotdrake.collision.targets import random_targets

    reach = build_dyn_collision_reach(talos_model, collision=True, table=True)
    for _family, target in random_targets(4, np.random.default_rng(20261126)):
        report = run_dyn_collision_reach(reach, target, duration=0.15)
        assert report.min_distance >= 0.01 - 1e-4, report
        assert report.feet_drift <= 1e-4 and report.limit_excess <= 1e-9 and not report.nan, report
        assert not report.failures, report.failures[:3]


@pytest.mark.slow
def test_a_fast_swing_across_the_body_keeps_the_soles_and_the_solver(talos_model):
    """Run 185 of ``bench/collision_runs.py --dynamic`` (the right hand across the body, the arm
    braked by the collision level at up to 1.8 m/s): without the soles' return to their pose they
    drifted by 0.157 mm in 0.3 s; on runs of this family the damping level's stage was a sliver that
    only the dual method's point answers. Soles within 1e-4 m and no tick given up."""
    from sotdrake.collision.reach import build_dyn_collision_reach, run_dyn_collision_reach

    reach = build_dyn_collision_reach(talos_model, collision=True, table=True)
    report = run_dyn_collision_reach(reach, np.array([0.31115483373788877, 0.16614737410651748, 1.2714382077736812]))
    assert report.ticks == 300 and not report.nan and not report.failures, report.failures[:3]
    assert report.min_distance >= 0.01 - 1e-4 and report.feet_drift <= 1e-4, report


@pytest.mark.slow
@pytest.mark.parametrize("target", [(0.55839861, -0.430768, 0.80793453), (0.702065, -0.54424894, 0.80298558)])
def test_a_long_dynamic_reach_keeps_the_distance(talos_model, target):
    """The hand held for 1 s on two table targets of ``bench/collision_runs.py --dynamic --runs 40
    --duration 1`` (runs 6 and 26): the torso and the shoulders reach their limits at speed. Braked
    there by more than their torques give, they left the legs (feet held) to absorb the rest: the
    pelvis turned and pairs went through each other (to −49 and −115 mm), the level's rows
    infeasible. With each joint's braking what its torque gives (``setTorqueBraking``) every pair
    stays ≥ d_s − 1e-4 m and no limit is crossed."""
    from sotdrake.collision.reach import build_dyn_collision_reach, run_dyn_collision_reach

    reach = build_dyn_collision_reach(talos_model, collision=True, table=True)
    report = run_dyn_collision_reach(reach, np.array(target), duration=1.0)
    assert report.ticks == 1000 and not report.nan, report
    assert report.min_distance >= 0.01 - 1e-4 and report.limit_excess <= 1e-9, report
    assert report.feet_drift <= 1e-4, report
