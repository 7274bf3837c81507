"""The dynamic robot's contacts and the collision world: a refused contact, task or obstacle adds
nothing; gains the control tick cannot keep stable and shapes a described obstacle could not have
are refused; a scene Drake would abort on is an error."""

from __future__ import annotations

import pytest
from pydrake.geometry import Box, Capsule, Ellipsoid, Mesh, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder

from sotdrake import InvalidInput, NotFound, SotError, talos
from sotdrake.collision import MetaTaskKineCollision, add_obstacle, add_scene
from sotdrake.collision.world import collision_world
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDynCom
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.robots import load_talos


@pytest.fixture(scope="module")
def talos_model():
    return load_talos("reduced")


def _systems(robot) -> list[str]:
    return sorted(system.get_name() for system in robot.builder.GetSystems())


def test_a_refused_contact_adds_nothing(talos_model):
    robot = RobotDyn(DiagramBuilder(), talos_model, dt=1e-3)
    robot.add_contact("contactLF", "left-sole")
    before = (_systems(robot), sorted(robot._names), robot.sot.num_input_ports(), robot.dynamic.num_output_ports())
    for name, frame in (("LF", "left-sole"), ("contactLF", "right-sole"), ("com", "right-sole"), (5, "left-sole")):
        with pytest.raises(SotError):
            robot.add_contact(name, frame)
        assert (_systems(robot), sorted(robot._names), robot.sot.num_input_ports(), robot.dynamic.num_output_ports()) == before
    MetaTaskDynCom(robot)  # (a clash left in the solver would make Drake abort here)
    with pytest.raises(NotFound):
        robot.velocity_selection(["nope"])


def test_gains_the_tick_cannot_hold(talos_model):
    robot = RobotDyn(DiagramBuilder(), talos_model, dt=0.01)
    contact = robot.add_contact("contactLF", "left-sole")
    with pytest.raises(InvalidInput, match="unstable at dt"):
        contact.setVelocityGain(1000.0)  # K_v dt = 10
    contact.setVelocityGain(30.0)
    with pytest.raises(InvalidInput, match="K_d dt"):
        robot.sot.setDampingGain(1000.0)
    robot.sot.setDampingGain(10.0)


def test_after_the_build_a_dynamic_robot_refuses_with_a_sot_error(talos_model):
    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, dt=1e-3)
    builder.Build()
    names = sorted(robot._names)
    with pytest.raises(SotError, match="already built"):
        MetaTaskDynCom(robot, name="late")
    with pytest.raises(SotError, match="already built"):
        robot.add_contact("cRF", "right-sole")
    assert sorted(robot._names) == names


@pytest.mark.parametrize("shape", [Sphere(1e9), Box(1e6, 1.0, 1.0), Capsule(0.1, 500.0), Ellipsoid(0.1, 0.1, 1e3)])
def test_drake_shapes_have_the_described_shapes_sizes(shape):
    robot = talos(DiagramBuilder())
    with pytest.raises(InvalidInput, match=r"\[1e-06, 100\] m"):
        add_obstacle(robot, shape, RigidTransform([1.0, 0.0, 0.0]), "big")
    assert "big" not in collision_world(robot).obstacles


def test_a_mirrored_mesh_is_refused(tmp_path):
    mesh = tmp_path / "tet.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    robot = talos(DiagramBuilder())
    with pytest.raises(InvalidInput, match="mesh scale"):
        add_obstacle(robot, Mesh(str(mesh), -1.0), RigidTransform([1.0, 0.0, 0.0]), "mirror")


def test_a_scene_drake_would_abort_on(tmp_path):
    robot = talos(DiagramBuilder())
    for geometry in ("<box size='0 1 1'/>", "<sphere radius='-1'/>"):
        source = f"<robot name='x'><link name='a'><collision><geometry>{geometry}</geometry></collision></link></robot>"
        with pytest.raises(InvalidInput, match="could not parse"):
            add_scene(robot, source, name="bad")
    assert collision_world(robot).obstacles == {}


def test_wrongly_typed_collision_arguments():
    robot = talos(DiagramBuilder())
    with pytest.raises(InvalidInput, match="expected the robot"):
        add_obstacle("talos", ("sphere", 0.1), RigidTransform(), "ball")
    with pytest.raises(InvalidInput, match="name"):
        MetaTaskKineCollision(robot, name=3)  # type: ignore[arg-type]


def test_a_start_in_collision_is_reported(caplog):
    """An obstacle through the arm: the level cannot part what already overlaps; it says so, once."""
    import logging

    import numpy as np

    from sotdrake.collision import build_collision_reach, run_collision_reach

    crate = [(("box", (0.3, 0.3, 0.3)), RigidTransform([0.0, -0.35, 0.85]), "crate")]
    reach = build_collision_reach(collision=True, table=False, obstacles=crate)
    with caplog.at_level(logging.WARNING, logger="sotdrake.collision.task"):
        run_collision_reach(reach, np.array([0.3, -0.4, 1.0]), duration=0.01, gain=10.0)
    warned = [r.getMessage() for r in caplog.records if "inside the safety distance" in r.getMessage()]
    assert len(warned) == 1 and "crate" in warned[0]
