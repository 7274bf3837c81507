import numpy as np
import pytest

from sotdrake.exceptions import FrameNotFound, RobotNotFound
from sotdrake.robots import OPERATIONAL_POINTS, load_talos
from sotdrake.robots.mesh_cache import obj_for_stl
from sotdrake.robots.talos import example_robot_data_dir


@pytest.mark.parametrize("variant, nq, nv", [("reduced", 39, 38), ("full_v2", 51, 50), ("left_arm", 7, 7)])
def test_variants_load_with_every_joint_actuated(variant, nq, nv):
    model = load_talos(variant)
    plant = model.plant
    assert (model.nq, model.nv) == (nq, nv)
    actuated = {plant.get_joint_actuator(i).joint().name() for i in plant.GetJointActuatorIndices()}
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        if (joint.num_velocities() == 1 and "gripper" not in joint.name()) or joint.name().endswith("gripper_left_joint"):
            assert joint.name() in actuated, joint.name()
    for name in ("torso_1_joint", "head_2_joint", "arm_right_7_joint"):  # differential transmissions
        if plant.HasJointNamed(name):
            assert name in actuated


def test_half_sitting_and_frames(talos_model):
    plant, q = talos_model.plant, talos_model.half_sitting
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    legs = [-0.0, 0.0, -0.411354, 0.859395, -0.448041, -0.001708]
    for side in ("left", "right"):
        for i, value in enumerate(legs, start=1):
            assert plant.GetJointByName(f"leg_{side}_{i}_joint").get_angle(context) == pytest.approx(value)
    assert plant.GetJointByName("arm_right_1_joint").get_angle(context) == pytest.approx(-0.25847)
    for sole in ("left-sole", "right-sole"):
        z = plant.CalcRelativeTransform(context, plant.world_frame(), talos_model.frame(sole)).translation()[2]
        assert abs(z) < 1e-3
    assert plant.CalcTotalMass(context) == pytest.approx(90.27, abs=0.05)
    for name in OPERATIONAL_POINTS:
        talos_model.frame(name)
    assert talos_model.frame("right-wrist").body().name() == "arm_right_7_link"
    assert talos_model.frame("left-ankle").body().name() == "leg_left_6_link"


def test_limits(talos_model):
    limits = talos_model.joint_limits()
    assert np.all(np.isinf(limits["position_lower"][:7]))
    joint = talos_model.plant.GetJointByName("gripper_right_joint")
    assert limits["position_upper"][joint.position_start()] == 0.0
    assert np.all(limits["velocity_upper"][6:] > 0) and np.all(np.isfinite(limits["effort"]))


def test_unknown_names_list_what_exists(talos_model):
    with pytest.raises(FrameNotFound, match="right-wrist"):
        talos_model.frame("rigth-wrist")
    with pytest.raises(RobotNotFound, match="reduced"):
        load_talos("talos_mini")


def test_mesh_cache_converts_once(tmp_path, monkeypatch):
    monkeypatch.setenv("SOTDRAKE_CACHE", str(tmp_path))
    stl = example_robot_data_dir() / "robots/talos_data/meshes/arm/arm_7.STL"
    obj = obj_for_stl(stl)
    assert obj.is_file() and obj.read_text().count("\nf ") > 10
    stamp = obj.stat().st_mtime_ns
    assert obj_for_stl(stl) == obj and obj.stat().st_mtime_ns == stamp
    assert not list(obj.parent.glob("*.tmp"))


def test_missing_robot_package_is_a_clear_error(monkeypatch):
    import importlib.metadata

    from sotdrake.exceptions import SotError

    def missing(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "distribution", missing)
    with pytest.raises(SotError, match="pip install example-robot-data"):
        load_talos("reduced")
