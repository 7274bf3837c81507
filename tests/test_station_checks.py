"""The physics station, the target marker, the dynamic device and TALOS' ``full_v2`` meshes: a bad
argument is refused as a :class:`SotError` naming it, with the builder left as it was (no Drake
``RuntimeError``, ``TypeError`` or process exit), and the catalog's variants load with their meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydrake.geometry import Meshcat, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from sotdrake import InvalidInput, MetaTaskKine6d, RobotDynSimu, SotError, add_target_marker, load_robot, robot
from sotdrake.exceptions import RobotDescriptionError, VariantNotFound
from sotdrake.physics import add_physical_talos, add_talos_station
from sotdrake.robots import load_talos
from sotdrake.robots.loader import robot_urdf_text
from sotdrake.robots.urdf_text import prepare_urdf
from sotdrake.target_marker import TargetMarker


def _names(builder: DiagramBuilder) -> list[str]:
    return sorted(system.get_name() for system in builder.GetSystems())


def _built() -> DiagramBuilder:
    builder = DiagramBuilder()
    builder.AddSystem(ConstantVectorSource([0.0]))
    builder.Build()
    return builder


@pytest.mark.parametrize("variant, error", [("left_arm", "no soles"), (["reduced"], "variant"), (None, "variant"),
                                            (3, "variant")])
def test_the_physics_refuses_a_variant_without_soles_or_that_is_not_a_name(variant, error):
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput, match=error):
        add_physical_talos(builder, variant)
    assert builder.GetSystems() == []
    with pytest.raises(VariantNotFound, match="variant"):
        add_physical_talos(builder, "halfbody")
    assert builder.GetSystems() == []


def test_the_physics_refuses_a_builder_that_is_none_or_built(talos_model):
    for call in (lambda b: add_physical_talos(b), lambda b: add_talos_station(b, talos_model.half_sitting)):
        with pytest.raises(InvalidInput, match="builder"):
            call(None)
        built = _built()
        with pytest.raises(InvalidInput, match="already built"):  # (was Drake's RuntimeError)
            call(built)


def test_a_second_simulated_talos_in_one_builder_is_refused_when_added(talos_model):
    """Drake accepted the second plant and ended the process at ``Build()`` on the duplicate names."""
    q0 = talos_model.half_sitting
    builder = DiagramBuilder()
    add_talos_station(builder, q0)
    names = _names(builder)
    for second in (lambda: add_talos_station(builder, q0), lambda: add_physical_talos(builder),
                   lambda: add_talos_station(builder, q0, push_force=[0.0, 0.0, 1.0])):
        with pytest.raises(InvalidInput, match="one simulated TALOS per DiagramBuilder"):
            second()
        assert _names(builder) == names
    builder = DiagramBuilder()
    add_physical_talos(builder)
    with pytest.raises(InvalidInput, match="talos_plant"):
        add_physical_talos(builder)
    assert _names(builder) == ["scene_graph", "talos_plant"]
    builder.Build()


@pytest.mark.parametrize("change, error", [
    (lambda q: q.__setitem__(slice(0, 4), 0.0), "quaternion"),
    (lambda q: q.__setitem__(slice(0, 4), [2.0, 0.0, 0.0, 0.0]), "quaternion"),
    (lambda q: q.__setitem__(slice(7, None), q[7:] + 1e6), "100"),
])
def test_the_station_checks_q0_as_the_device_does(talos_model, change, error):
    q0 = talos_model.half_sitting.copy()
    change(q0)
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput, match=error):
        add_talos_station(builder, q0)
    assert builder.GetSystems() == []


@pytest.mark.parametrize("options, error", [({"stifness": 30.0}, "stiffness"), ({"body_collision": "no"}, "body_collision"),
                                            ({"pd_gains": 1}, "pd_gains"), ({"stiffness": -1.0}, "stiffness")])
def test_the_station_refuses_an_option_the_plant_does_not_take(talos_model, options, error):
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput, match=error):
        add_talos_station(builder, talos_model.half_sitting, **options)
    assert builder.GetSystems() == []


@pytest.mark.parametrize("options, error", [
    ({"meshcat": None}, "meshcat"), ({"path": None}, "path"), ({"path": ""}, "path"), ({"radius": -1.0}, "radius"),
    ({"radius": float("nan")}, "radius"), ({"radius": True}, "radius"), ({"publish_period": -1.0}, "publish_period"),
    ({"publish_period": float("nan")}, "publish_period"), ({"opmodif": 3}, "opmodif"),
    ({"opmodif": RigidTransform([np.nan, 0.0, 0.0])}, "opmodif"), ({"rgba": "red"}, "rgba"),
])
def test_the_target_marker_checks_its_arguments_before_drawing(options, error):
    """A negative or NaN radius made Drake's ``Sphere`` end the process (a ``SystemExit``)."""
    meshcat = Meshcat()
    arguments = {"meshcat": meshcat, "path": "/checked", **options}
    with pytest.raises(InvalidInput, match=error):
        TargetMarker(**arguments)
    assert not meshcat.HasPath("/checked")


def test_a_task_marker_with_a_colour_that_is_not_one_adds_nothing():
    bot = robot(DiagramBuilder(), "ur5")
    hand = MetaTaskKine6d("hand", bot, "tool", bot.OperationalPointsMap["tool"])
    names = _names(bot.builder)
    with pytest.raises(InvalidInput, match="rgba"):
        add_target_marker(Meshcat(), "/hand", hand, rgba="red")
    assert _names(bot.builder) == names


def test_a_point_marker_with_a_colour_that_is_not_one_draws_nothing():
    meshcat = Meshcat()
    with pytest.raises(InvalidInput, match="rgba"):
        add_target_marker(meshcat, "/point", (0.1, 0.2, 0.3), rgba="red")
    assert not meshcat.HasPath("/point")


@pytest.fixture(scope="module")
def ur5_plant():
    return load_robot("ur5").plant


@pytest.mark.parametrize("options, error", [
    ({"dt": "0.001"}, "dt"), ({"dt": None}, "dt"), ({"dt": True}, "dt"), ({"dt": 2.0}, "dt"), ({"dt": 1e-7}, "dt"),
    ({"q0": np.full(6, 1e6)}, "q0"), ({"q0": np.zeros(5)}, "q0"), ({"name": ""}, "name"), ({"name": None}, "name"),
])
def test_the_dynamic_device_checks_dt_and_q0_as_the_kinematic_device(ur5_plant, options, error):
    arguments = {"plant": ur5_plant, "dt": 1e-3, "q0": np.zeros(6), **options}
    with pytest.raises(InvalidInput, match=error):
        RobotDynSimu(**arguments)
    assert RobotDynSimu(ur5_plant, 1.0, np.full(6, 100.0)).dt == 1.0  # the bounds themselves are accepted


def test_talos_full_v2_loads_with_its_meshes():
    """Its URDF defines ``DarkGrey`` at the top level and again, lighter, in a visual: Drake refused
    the second definition. The top level's is the model's, as ROS reads the file."""
    model = load_talos("full_v2", meshes=True)
    assert model.scene_graph is not None and model.nq == 51
    text = robot_urdf_text("talos", "full_v2", meshes=True)
    assert text.count('<material name="DarkGrey">') == 1 and '<color rgba="0.5 0.5 0.5 1"/>' not in text
    physical = add_physical_talos(DiagramBuilder(), "full_v2")
    assert physical.plant.num_positions() == 51


def _urdf(top: str, visuals: list[str]) -> str:
    links = "".join(f'<link name="l{k}"><visual><geometry><box size="1 1 1"/></geometry>{material}</visual></link>'
                    for k, material in enumerate(visuals))
    joints = "".join(f'<joint name="j{k}" type="fixed"><parent link="l0"/><child link="l{k}"/></joint>'
                     for k in range(1, len(visuals)))
    return f'<robot name="r">{top}{links}{joints}</robot>'


def _material(rgba: str) -> str:
    return f'<material name="grey"><color rgba="{rgba}"/></material>'


def _parses(text: str) -> bool:
    plant, scene_graph = MultibodyPlant(0.0), SceneGraph()  # (the plant does not keep its SceneGraph alive)
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    Parser(plant).AddModelsFromString(text, "urdf")
    return plant.num_bodies() > 1


@pytest.mark.parametrize("top, visuals", [
    (_material("0.5 0.5 0.5 1") * 2, ['<material name="grey"/>']),  # the same top-level definition twice
    (_material("0.2 0.2 0.2 1"), [_material("0.5 0.5 0.5 1"), '<material name="grey"/>']),  # the top level's wins
    ([_material("0.2 0.2 0.2 1")], [_material("0.5 0.5 0.5 1")]),  # a visual's before the top level's (TALOS full_v2)
])
def test_a_material_defined_twice_is_defined_once(top, visuals):
    if isinstance(top, list):  # (the top-level definition after the links)
        text = _urdf("", visuals).replace("</robot>", top[0] + "</robot>")
    else:
        text = _urdf(top, visuals)
    text = prepare_urdf(text, Path(), meshes=True)
    assert text.count('<material name="grey">') == 1
    assert _parses(text)


def test_a_material_defined_identically_in_two_visuals_is_defined_once():
    text = prepare_urdf(_urdf("", [_material("0.5 0.5 0.5 1"), _material("0.5 0.5 0.5 1.0")]), Path(), meshes=True)
    assert text.count('<material name="grey">') == 1
    assert _parses(text)


@pytest.mark.parametrize("top, visuals", [
    (_material("0.5 0.5 0.5 1") + _material("0.2 0.2 0.2 1"), []),
    ("", [_material("0.5 0.5 0.5 1"), _material("0.2 0.2 0.2 1")]),  # (Drake refuses it too)
])
def test_two_different_definitions_of_a_material_are_refused_by_name(top, visuals):
    with pytest.raises(RobotDescriptionError, match="material 'grey' is defined twice"):
        prepare_urdf(_urdf(top, visuals), Path(), meshes=True, source="robot.urdf")


def test_every_talos_variant_still_loads_with_meshes():
    for variant in ("reduced", "left_arm"):
        assert load_talos(variant, meshes=True).scene_graph is not None
    with pytest.raises(SotError):
        add_physical_talos(DiagramBuilder(), "left_arm")
