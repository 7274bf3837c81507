"""A model, plant, diagram, robot, system or flag of the wrong type is refused when given, as an
``InvalidInput`` naming the argument, with nothing added; a feature of another robot's builder, or a
second system under a name already taken, is refused before the meta task adds anything."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

import sotdrake as S
from sotdrake import InvalidInput


@pytest.fixture(scope="module")
def built(talos_model):
    builder = DiagramBuilder()
    robot = S.Robot(builder, talos_model)
    sot = S.add_sot(robot)
    diagram = builder.Build()
    return robot, sot, diagram, diagram.CreateDefaultContext()


def _names(builder: DiagramBuilder) -> list[str]:
    return sorted(system.get_name() for system in builder.GetSystems())


@pytest.mark.parametrize(("call", "says"), [
    (lambda m: S.Robot(DiagramBuilder(), None), "Robot: model"),
    (lambda m: S.Robot(DiagramBuilder(), "talos"), "Robot: model"),
    (lambda m: S.Robot(DiagramBuilder(), m, measured_position=5), "measured_position"),
    (lambda m: S.RobotDyn(DiagramBuilder(), None), "RobotDyn: model"),
    (lambda m: S.RobotDyn(None, m), "RobotDyn: builder"),
    (lambda m: S.MetaTaskDyn6d("rh", None, "rh", "right-wrist"), "robot"),
    (lambda m: S.FeaturePosture("p", None, m.half_sitting), "plant"),
    (lambda m: S.FeatureJointLimits("j", None), "plant"),
    (lambda m: S.JointLimitator(None, 1e-3), "plant"),
    (lambda m: S.Device(None, 1e-3, m.half_sitting), "plant"),
    (lambda m: S.velocity_names(None), "velocity_names: plant"),
    (lambda m: S.simulate(None, 1.0, progress=False), "simulate: diagram"),
    (lambda m: S.check_stack(None), "check_stack: diagram"),
    (lambda m: S.entity(None, "sot"), "entity: diagram"),
    (lambda m: S.entities(None), "entities: diagram"),
    (lambda m: S.run_script(None), "run_script: main"),
])
def test_a_wrong_type_is_refused_with_the_argument_named(talos_model, call, says):
    with pytest.raises(InvalidInput, match=says):
        call(talos_model)


def test_introspection_refuses_names_that_are_not_strings(built):
    robot, sot, diagram, context = built
    with pytest.raises(InvalidInput, match="entity: name"):
        S.entity(diagram, None)
    with pytest.raises(InvalidInput, match="signal: name"):
        S.signal(sot, None, context)
    with pytest.raises(InvalidInput, match="signal: system"):
        S.signal("sot", "control", context)
    assert S.entity(diagram, "sot") is sot and S.signal(sot, "control", context).shape == (robot.dimension,)


@pytest.mark.parametrize("kind", [S.Robot, S.RobotDyn])
def test_robot_add_refuses_what_is_not_a_system_and_renames_nothing_it_refuses(talos_model, kind):
    builder = DiagramBuilder()
    robot = kind(builder, talos_model)
    before = _names(builder)
    for system in (None, "feature", 3):
        with pytest.raises(InvalidInput, match="add: system"):
            robot.add(system)
    feature = S.FeatureGeneric("mine", 3, robot.dimension)
    with pytest.raises(InvalidInput, match="already exists"):
        robot.add(feature, "device")
    assert feature.get_name() == "mine" and _names(builder) == before
    assert robot.add(feature, "renamed") is feature and feature.get_name() == "renamed"


def test_a_feature_named_like_another_entity_is_refused_and_a_corrected_retry_works(talos_model):
    builder = DiagramBuilder()
    robot = S.Robot(builder, talos_model)
    S.MetaTaskKineCom(robot)  # (adds featurecom)
    before, tasks = _names(builder), dict(robot.tasks)
    with pytest.raises(InvalidInput, match="'featurecom' already exists"):
        S.MetaTaskKineFeature("mine", robot, S.FeatureGeneric("featurecom", 3, robot.dimension))
    assert _names(builder) == before and robot.tasks == tasks
    meta = S.MetaTaskKineFeature("mine", robot, S.FeatureGeneric("featuremine", 3, robot.dimension))
    assert meta.task.name == "taskmine" and "featuremine" in _names(builder)


def test_a_feature_of_another_robots_builder_is_refused(talos_model):
    first, second = DiagramBuilder(), DiagramBuilder()
    one, other = S.Robot(first, talos_model), S.Robot(second, talos_model)
    feature = other.add(S.FeatureGeneric("shared", 3, other.dimension))
    before = _names(first)
    with pytest.raises(InvalidInput, match="another robot's DiagramBuilder"):
        S.MetaTaskKineFeature("mine", one, feature)
    with pytest.raises(InvalidInput, match="another robot's DiagramBuilder"):
        one.add(feature)
    assert _names(first) == before
    S.MetaTaskKineFeature("mine", other, feature)  # (in its own robot: taken as it is)
    assert _names(second).count("shared") == 1


@pytest.mark.parametrize("flag", ["no", 1, None, [True]])
def test_a_meta_task_flag_that_is_not_a_bool_is_refused(talos_model, flag):
    builder = DiagramBuilder()
    robot = S.Robot(builder, talos_model)
    before = _names(builder)
    with pytest.raises(InvalidInput, match="inequality: expected True or False"):
        S.MetaTaskKine6d("rh", robot, "rh", "right-wrist", inequality=flag)
    with pytest.raises(InvalidInput, match="pd: expected True or False"):
        S.MetaTaskKineCom(robot, pd=flag)
    assert _names(builder) == before
    assert isinstance(S.MetaTaskKine6d("rh", robot, "rh", "right-wrist", inequality=np.True_).task, S.TaskInequality)
