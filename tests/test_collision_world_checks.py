"""The collision world's arguments are checked before anything is added or changed: obstacle and
scene names as Drake stores them, the ``meshcat`` to draw in, the distance queries' arguments, and
scenes whose joints could move."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.geometry import GeometryId, Meshcat
from pydrake.math import RigidTransform

from sotdrake import InvalidInput, NotFound
from sotdrake.collision import CollisionWorld, add_obstacle, add_scene, draw_obstacles, minimum_distance, pair_distances, scene_shapes
from sotdrake.collision.distance import signed_distance_pairs

BALL = ("sphere", 0.1)
FAR = RigidTransform([2.0, 0.0, 0.5])
TABLE_URDF = """<robot name="table">
  <link name="top"><collision name="top"><origin xyz="0 0 0.7"/><geometry><box size="0.6 1.0 0.04"/></geometry></collision></link>
</robot>"""


def jointed_urdf(kind: str, lower: float = 1.0, upper: float = 2.0) -> str:
    """A base and an arm 0.5 m along the arm's x, the joint 1 m above the base, about (or along) y."""
    return f"""<robot name="r"><link name="base"><collision name="basec"><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
<link name="arm"><collision name="armc"><origin xyz="0.5 0 0"/><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
<joint name="j" type="{kind}"><parent link="base"/><child link="arm"/><origin xyz="0 0 1"/><axis xyz="0 1 0"/>
<limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/></joint></robot>"""


@pytest.fixture(scope="module")
def world(talos_model):
    """A world that obstacles are added to (no context is made of it)."""
    return CollisionWorld(talos_model)


@pytest.fixture(scope="module")
def checked(talos_model):
    """A world with one obstacle and a context, for the distance queries."""
    world = CollisionWorld(talos_model)
    add_obstacle(world, BALL, FAR, "ball")
    return world, world.new_context()


@pytest.fixture(scope="module")
def meshcat():
    return Meshcat()


# Names (as Drake stores them)

@pytest.mark.parametrize("name", ["table ", " table", "table\t", "\ntable"])
def test_an_obstacle_name_drake_would_strip_is_refused_and_the_plain_name_stays_free(world, name):
    before = dict(world.obstacles)
    with pytest.raises(InvalidInput, match=r"add_obstacle: name .* whitespace"):
        add_obstacle(world, BALL, FAR, name)
    assert world.obstacles == before
    plain = f"{name.strip()}_{len(before)}"
    add_obstacle(world, BALL, FAR, plain)
    assert plain in world.obstacles


def test_a_scene_name_drake_would_strip_is_refused_and_nothing_is_added(world):
    before = dict(world.obstacles)
    with pytest.raises(InvalidInput, match=r"add_scene: name .* whitespace"):
        add_scene(world, TABLE_URDF, None, " table_scene")
    assert world.obstacles == before


# meshcat

def test_an_obstacle_with_a_meshcat_that_is_not_one_is_refused_before_it_is_added(world):
    with pytest.raises(InvalidInput, match=r"add_obstacle: meshcat must be None or a pydrake Meshcat.*str"):
        add_obstacle(world, BALL, FAR, "drawn_ball", meshcat="not a meshcat")
    assert "drawn_ball" not in world.obstacles
    add_obstacle(world, BALL, FAR, "drawn_ball")  # (a retry is not refused as a duplicate)


def test_a_scene_with_a_meshcat_that_is_not_one_is_refused_before_anything_is_added(world):
    before = dict(world.obstacles)
    with pytest.raises(InvalidInput, match=r"add_scene: meshcat must be None or a pydrake Meshcat"):
        add_scene(world, TABLE_URDF, None, "drawn_table", meshcat=object())
    assert world.obstacles == before


def test_draw_obstacles_names_what_it_cannot_draw(checked, meshcat):
    world, _ = checked
    with pytest.raises(NotFound, match=r"draw_obstacles: names: .*'nope'.*'ball'"):
        draw_obstacles(meshcat, world, ["nope"])
    with pytest.raises(InvalidInput, match=r"draw_obstacles: meshcat must be a pydrake Meshcat.*NoneType"):
        draw_obstacles(None, world)
    with pytest.raises(InvalidInput, match=r"draw_obstacles: names must be None or a list"):
        draw_obstacles(meshcat, world, "ball")
    draw_obstacles(meshcat, world, ["ball"])


# Distance queries

def test_a_max_distance_that_would_hide_every_pair_is_refused_and_zero_or_infinity_is_a_query(checked, talos_model):
    world, context = checked
    q = talos_model.half_sitting
    for max_distance in (math.nan, -1.0, -math.inf, "1", True, None):
        with pytest.raises(InvalidInput, match="minimum_distance: max_distance must be a number ≥ 0"):
            minimum_distance(world, context, q, max_distance)
        world.plant.SetPositions(world.plant_context(context), q)
        with pytest.raises(InvalidInput, match="pair_distances: max_distance must be a number ≥ 0"):
            pair_distances(world, context, max_distance)
        with pytest.raises(InvalidInput, match="signed_distance_pairs: max_distance must be a number ≥ 0"):
            signed_distance_pairs(world, context, max_distance)
    d = minimum_distance(world, context, q, math.inf)  # (the grippers, about 1 cm apart)
    assert 0.0 < d < 0.05 and minimum_distance(world, context, q, np.float64(1.0)) == d
    assert minimum_distance(world, context, q, 0) == math.inf


def test_a_zero_quaternion_is_refused_and_the_context_left_as_it_was(checked, talos_model):
    world, context = checked
    plant_context = world.plant_context(context)
    world.plant.SetPositions(plant_context, talos_model.half_sitting)
    q = talos_model.half_sitting.copy()
    start = world.quaternion_starts[0]
    q[start : start + 4] = 0.0
    with pytest.raises(InvalidInput, match=r"minimum_distance: q: the floating base's quaternion .* is no rotation"):
        minimum_distance(world, context, q)
    np.testing.assert_array_equal(world.plant.GetPositions(plant_context), talos_model.half_sitting)
    world.plant.SetPositions(plant_context, q)  # (set by a caller: pair_distances reads the context's)
    try:
        with pytest.raises(InvalidInput, match=r"pair_distances: the positions in context: the floating base's quaternion"):
            pair_distances(world, context, 1.0)
    finally:
        world.plant.SetPositions(plant_context, talos_model.half_sitting)


@pytest.mark.parametrize(("pairs", "word"), [
    ("ab", "geometry_pairs must be None or a list"),
    (3, "geometry_pairs must be None or a list"),
    ([1, 2], r"geometry_pairs\[0\] must be a pair"),
    ([("arm_right_7_link", "ball")], r"geometry_pairs\[0\] must be a pair"),
    ([(GeometryId.get_new_id(), GeometryId.get_new_id())], r"geometry_pairs\[0\] .* not a collision geometry of this world"),
])
def test_geometry_pairs_that_are_not_the_worlds_are_refused(checked, talos_model, pairs, word):
    world, context = checked
    with pytest.raises(InvalidInput, match=f"minimum_distance: {word}"):
        minimum_distance(world, context, talos_model.half_sitting, 1.0, pairs)
    good = world.geometry_pairs([("arm_right_7_link", "ball")])
    assert minimum_distance(world, context, talos_model.half_sitting, 10.0, good) > 0.5


def test_a_collision_world_of_something_else_than_a_model_is_refused(talos_model):
    with pytest.raises(InvalidInput, match=r"CollisionWorld: model: expected a RobotModel .*NoneType"):
        CollisionWorld(None)  # type: ignore[arg-type]
    with pytest.raises(InvalidInput, match="CollisionWorld: use_srdf"):
        CollisionWorld(talos_model, use_srdf="no")  # type: ignore[arg-type]


# Scenes whose joints could move

@pytest.mark.parametrize(("kind", "lower", "upper", "expected"), [
    ("revolute", 1.0, 2.0, [0.5 * math.cos(1.0), 0.0, 1.0 - 0.5 * math.sin(1.0)]),  # at its lower limit, 1 rad
    ("revolute", -2.0, -1.5, [0.5 * math.cos(-1.5), 0.0, 1.0 - 0.5 * math.sin(-1.5)]),  # at its upper limit
    ("prismatic", 1.0, 2.0, [0.5, 1.0, 1.0]),
])
def test_a_scene_joint_stands_at_its_default_clipped_into_its_limits(kind, lower, upper, expected):
    for limits, where in (((lower, upper), expected), ((-1.0, 1.0), [0.5, 0.0, 1.0])):  # (0 within the limits: 0)
        shapes = {name: pose for name, _, pose in scene_shapes(jointed_urdf(kind, *limits), None, kind)}
        np.testing.assert_allclose(shapes[f"{kind}/armc"].translation(), where, atol=1e-12)
        np.testing.assert_allclose(shapes[f"{kind}/basec"].translation(), [0.0, 0.0, 0.0], atol=1e-12)


def test_a_floating_scene_joint_is_refused_naming_it_and_nothing_is_added(world):
    before = dict(world.obstacles)
    with pytest.raises(InvalidInput, match=r"add_scene\('floating'\): joint 'j' is floating.*link 'arm'"):
        add_scene(world, jointed_urdf("floating"), None, "floating")
    assert world.obstacles == before


def test_an_sdf_model_that_is_not_static_keeps_its_links_poses():
    links = "".join(f"<link name='{n}'><pose>{p}</pose><collision name='c{n}'><geometry><box><size>0.1 0.1 0.1</size></box>"
                    "</geometry></collision></link>" for n, p in (("a", "1 0 0 0 0 0"), ("b", "0 2 0 0 0 0")))
    for static in ("true", "false"):
        text = f"<sdf version='1.7'><model name='m'><static>{static}</static><pose>0 0 0.5 0 0 0</pose>{links}</model></sdf>"
        shapes = {name: pose.translation() for name, _, pose in scene_shapes(text, RigidTransform([0.0, 0.0, 1.0]), "m")}
        np.testing.assert_allclose(shapes["m/ca"], [1.0, 0.0, 1.5], atol=1e-12)
        np.testing.assert_allclose(shapes["m/cb"], [0.0, 2.0, 1.5], atol=1e-12)
