"""The dynamic SoT's robot on other robots than TALOS: sole rectangles from the robot model, and the
physics device refused where it does not exist."""

import pytest
from pydrake.systems.framework import DiagramBuilder

from sotdrake import InvalidInput, load_robot
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.station import sole_rectangle


@pytest.fixture(scope="module")
def romeo():
    return load_robot("romeo", "small")


def test_romeo_contacts_take_the_model_sole_rectangles(romeo):
    robot = RobotDyn(DiagramBuilder(), romeo, "dynsimu", 5e-3)
    left, right = robot.sole_rectangle("left-sole"), robot.sole_rectangle("right-sole")
    assert left == (-0.08, 0.11, -0.045, 0.07)
    assert right == (left[0], left[1], -left[3], -left[2])  # mirrored: the wider side outwards
    assert robot.add_contact("contactLF", "left-sole").rectangle == left
    assert robot.add_contact("contactRF", "right-sole", rectangle=None).rectangle is None  # a point contact
    with pytest.raises(InvalidInput, match="rectangle"):
        robot.add_contact("contactX", "left-sole", rectangle="soles")


def test_talos_keeps_its_physics_sole_box(talos_model):
    robot = RobotDyn(DiagramBuilder(), talos_model, "dynsimu")
    assert robot.sole_rectangle("left-sole") == sole_rectangle()


def test_a_robot_without_sole_rectangles_says_so():
    robot = RobotDyn(DiagramBuilder(), load_robot("icub", "reduced"), "dynsimu")
    with pytest.raises(InvalidInput, match="no sole rectangle known for icub"):
        robot.add_contact("contactLF", "left-sole")


def test_physics_device_is_talos_only_and_changes_nothing(romeo):
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput, match="TALOS' torque-driven plant"):
        RobotDyn(builder, romeo, "physics")
    assert builder.GetSystems() == []
