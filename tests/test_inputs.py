"""Bad inputs give clear errors at the call that made them."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from sotdrake.device import Device
from sotdrake.exceptions import FrameNotFound, InvalidInput, NotFound
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.selection import parse_selection


def test_selection_masks():
    assert list(parse_selection("000011", 6)) == [0, 1]
    assert list(parse_selection("111", 6)) == [0, 1, 2]
    assert list(parse_selection("100000", 6)) == [5]
    for bad in ("", "012", "1111111", "000", 11):
        with pytest.raises(InvalidInput):
            parse_selection(bad, 6)


@pytest.fixture
def robot(talos_model):
    return Robot(DiagramBuilder(), talos_model)


def test_meta_task_inputs(robot):
    with pytest.raises(FrameNotFound):
        MetaTaskKine6d("x", robot, "x", "right_wrist")
    task = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    with pytest.raises(InvalidInput):
        MetaTaskKine6d("rh", robot, "rh2", "left-wrist")  # duplicate entity names
    with pytest.raises(InvalidInput):
        robot.dynamic.createOpPoint("rh", "left-wrist")  # same op-point name, another frame
    for target in [(0.5, 0.2), (0.5, np.nan, 1.0), np.ones((3, 3))]:
        with pytest.raises(InvalidInput):
            gotoNd(task, target)
    with pytest.raises(InvalidInput):
        gotoNd(task, (0.5, -0.2, 1.0), "1111111")
    with pytest.raises(InvalidInput):
        gotoNd(task, (0.5, -0.2, 1.0), "111", (1, 2))
    with pytest.raises(InvalidInput):
        task.feature.frame("world")
    not_rotation = np.eye(4)
    not_rotation[0, 0] = 2
    with pytest.raises(InvalidInput):
        task.opmodif = not_rotation
    assert task.featureDes.settings().position.translation()[0] != 0.5  # nothing half-applied
    com = MetaTaskKineCom(robot)
    with pytest.raises(InvalidInput):
        gotoNd(com, (0.0, 0.1))


def test_solver_and_device_inputs(robot, talos_model):
    sot = add_sot(robot)
    with pytest.raises(InvalidInput):
        add_sot(robot, "sot2")  # one solver drives the device
    for bad in (np.ones(3, dtype=bool), np.ones(robot.dimension)):
        with pytest.raises(InvalidInput):
            sot.setControlSelection(bad)
    with pytest.raises(InvalidInput):
        sot.setDamping(-1.0)
    with pytest.raises(NotFound):
        robot.velocity_selection(["gripper_joint"])
    with pytest.raises(InvalidInput):
        Device(talos_model.plant, 1e-3, np.zeros(5))
    with pytest.raises(InvalidInput):
        Device(talos_model.plant, 0.0, talos_model.half_sitting)
