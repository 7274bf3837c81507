"""Every robot the loader claims: it loads with its mass, DoF and op points; the humanoids'
kinematics agree with Pinocchio's on the same URDF at random configurations."""

import numpy as np
import pytest
from pydrake.multibody.tree import PlanarJoint

from sotdrake.exceptions import InvalidInput, RobotNotFound, VariantNotFound
from sotdrake.kinematics import Dynamic
from sotdrake.robots import ROBOTS, load_robot
from sotdrake.robots.loader import PLANAR_BASE_JOINT, urdf_path

# (robot, variant): (nq, nv, mass in kg to 0.01, base). Masses are the URDF's, summed by Drake.
EXPECTED = {
    ("talos", "reduced"): (39, 38, 90.27, "free"),
    ("talos", "full_v2"): (51, 50, 93.34, "free"),
    ("talos", "left_arm"): (7, 7, 9.46, "fixed"),
    ("romeo", "full"): (62, 61, 40.53, "free"),
    ("romeo", "small"): (38, 37, 40.53, "free"),
    ("icub", "full"): (39, 38, 28.35, "free"),
    ("icub", "reduced"): (36, 35, 28.35, "free"),
    ("g1", "29dof"): (36, 35, 33.34, "free"),
    ("g1", "29dof_with_hand"): (50, 49, 34.39, "free"),
    ("pr2", "default"): (33, 33, 257.16, "planar"),
    ("tiago", "default"): (51, 51, 65.89, "planar"),
    ("tiago", "no_hand"): (15, 15, 64.96, "planar"),
    ("ur3", "default"): (6, 6, 10.63, "fixed"),
    ("ur3", "limited"): (6, 6, 10.63, "fixed"),
    ("ur3", "gripper"): (6, 6, 10.63, "fixed"),
    ("ur5", "default"): (6, 6, 20.99, "fixed"),
    ("ur5", "limited"): (6, 6, 20.99, "fixed"),
    ("ur5", "gripper"): (6, 6, 20.99, "fixed"),
    ("ur10", "default"): (6, 6, 32.70, "fixed"),
    ("ur10", "limited"): (6, 6, 32.70, "fixed"),
    ("panda", "default"): (9, 9, 17.45, "fixed"),
    ("z1", "default"): (7, 7, 5.22, "fixed"),
    ("anymal", "default"): (19, 18, 30.48, "free"),
    ("go1", "default"): (19, 18, 13.10, "free"),
    ("solo12", "default"): (19, 18, 2.50, "free"),
}

HUMANOID_OP_POINTS = {"left-wrist", "right-wrist", "left-ankle", "right-ankle", "gaze", "waist", "chest"}


def test_the_table_covers_every_variant_the_loader_claims():
    claimed = {(name, variant) for name, spec in ROBOTS.items() for variant in spec.variants}
    assert claimed == set(EXPECTED)


@pytest.mark.parametrize("name, variant", sorted(EXPECTED))
def test_robot_loads_with_mass_dof_and_op_points(name, variant):
    nq, nv, mass, base = EXPECTED[(name, variant)]
    model = load_robot(name, variant)
    plant = model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, model.half_sitting)
    assert (model.nq, model.nv, model.base) == (nq, nv, base)
    assert plant.CalcTotalMass(context) == pytest.approx(mass, abs=0.005)
    assert len(list(plant.GetFloatingBaseBodies())) == (base == "free")
    planar = plant.HasJointNamed(PLANAR_BASE_JOINT) and isinstance(plant.GetJointByName(PLANAR_BASE_JOINT), PlanarJoint)
    assert planar == (base == "planar")
    # The reference posture is within the joint limits, with a unit quaternion.
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    assert np.all(model.half_sitting >= lower) and np.all(model.half_sitting <= upper)
    if base == "free":
        (body,) = plant.GetFloatingBaseBodies()
        start = plant.get_body(body).floating_positions_start()
        assert np.linalg.norm(model.half_sitting[start : start + 4]) == pytest.approx(1, abs=1e-12)
    spec = ROBOTS[name]
    if spec.kind == "humanoid" and variant != "left_arm":
        assert HUMANOID_OP_POINTS <= set(model.OperationalPointsMap)
        X = {op: plant.CalcRelativeTransform(context, plant.world_frame(), model.frame(op)).translation()
             for op in HUMANOID_OP_POINTS}
        # Standing: head above chest above waist above the ankles; left on the left (+y).
        assert X["gaze"][2] > X["chest"][2] >= X["waist"][2] - 1e-9 > X["left-ankle"][2]
        assert X["left-wrist"][1] > X["right-wrist"][1] and X["left-ankle"][1] > X["right-ankle"][1]
        soles = [model.frame(s) for s in spec.soles]
        z_soles = [plant.CalcRelativeTransform(context, plant.world_frame(), s).translation()[2] for s in soles]
        assert all(abs(z) < 0.01 for z in z_soles)  # on the ground (the SRDF's base pose, or put there)
    elif variant == "left_arm":
        assert set(model.OperationalPointsMap) == {"left-wrist"}  # the one op point on the arm
    else:
        assert set(model.OperationalPointsMap) == set(spec.op_points)
    for op in model.OperationalPointsMap:
        model.frame(op)


def test_unknown_robot_lists_the_available_ones():
    with pytest.raises(RobotNotFound, match=r"romeo.*pr2|pr2.*romeo") as error:
        load_robot("rome")
    assert "did you mean 'romeo'" in str(error.value)
    with pytest.raises(VariantNotFound, match="'full', 'small'"):
        load_robot("romeo", "tiny")
    with pytest.raises(InvalidInput, match="planar"):
        load_robot("ur5", base="planar")


def test_pr2_bases():
    free = load_robot("pr2", base="free")
    fixed = load_robot("pr2", base="fixed")
    assert (free.nq, free.nv, fixed.nq, fixed.nv) == (37, 36, 30, 30)
    planar = load_robot("pr2")
    joint = planar.plant.GetJointByName(PLANAR_BASE_JOINT)
    assert isinstance(joint, PlanarJoint) and joint.num_positions() == 3
    assert planar.frame("waist").body().name() == "base_link"


# --- kinematics against Pinocchio -----------------------------------------------------------

HUMANOIDS = [("talos", "reduced"), ("romeo", "full"), ("romeo", "small"), ("icub", "full"), ("g1", "29dof")]


def _pinocchio_model(name, variant):
    pin = pytest.importorskip("pinocchio")
    text = urdf_path(name, variant).read_text()
    # G1's URDF has a "floating" joint of its own; Pinocchio's URDF parser drops it (a root joint is
    # given here instead), Drake's makes it the free flyer: both are the same pelvis pose.
    return pin, pin.buildModelFromXML(text, pin.JointModelFreeFlyer())


def _maps(model, pin_model):
    """Index maps Drake → Pinocchio: q_pin = f(q_drake) and v_pin = T(q) v_drake.

    Pinocchio's free flyer: q = (x, y, z, qx, qy, qz, qw), v = (v_B, ω_B) in the base frame B;
    Drake's: q = (qw, qx, qy, qz, x, y, z), v = (ω_WB, v_WB) in the world frame W.
    """
    plant = model.plant
    (body,) = plant.GetFloatingBaseBodies()
    base_q = plant.get_body(body).floating_positions_start()
    base_v = plant.get_body(body).floating_velocities_start_in_v()
    joints = []
    for j in range(1, pin_model.njoints):
        pin_joint = pin_model.joints[j]
        if pin_joint.nq == 7:
            continue
        drake_joint = plant.GetJointByName(pin_model.names[j])
        assert (drake_joint.num_positions(), drake_joint.num_velocities()) == (pin_joint.nq, pin_joint.nv)
        joints.append((pin_joint.idx_q, pin_joint.idx_v, drake_joint.position_start(), drake_joint.velocity_start()))
    (free,) = [pin_model.joints[j] for j in range(1, pin_model.njoints) if pin_model.joints[j].nq == 7]

    def q_pin(q):
        out = np.zeros(pin_model.nq)
        qw, qx, qy, qz, x, y, z = q[base_q : base_q + 7]
        out[free.idx_q : free.idx_q + 7] = (x, y, z, qx, qy, qz, qw)
        for iq, _, dq, _ in joints:
            out[iq] = q[dq]
        return out

    def T(q, R_WB):
        T = np.zeros((pin_model.nv, model.nv))
        T[free.idx_v : free.idx_v + 3, base_v + 3 : base_v + 6] = R_WB.T  # v_B = R_WBᵀ v_WB
        T[free.idx_v + 3 : free.idx_v + 6, base_v : base_v + 3] = R_WB.T  # ω_B = R_WBᵀ ω_WB
        for _, iv, _, dv in joints:
            T[iv, dv] = 1.0
        return T

    return q_pin, T, body


def _random_q(model, rng):
    plant = model.plant
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    lower = np.where(np.isfinite(lower), lower, -np.pi)
    upper = np.where(np.isfinite(upper), upper, np.pi)
    q = rng.uniform(lower, upper)
    (body,) = plant.GetFloatingBaseBodies()
    start = plant.get_body(body).floating_positions_start()
    quaternion = rng.normal(size=4)
    q[start : start + 4] = quaternion / np.linalg.norm(quaternion)
    q[start + 4 : start + 7] = rng.uniform(-1, 1, 3)
    return q


@pytest.mark.parametrize("name, variant", HUMANOIDS)
def test_humanoid_kinematics_match_pinocchio(name, variant, rng):
    """The ``dynamic`` entity's op-point poses, Jacobians, CoM and CoM Jacobian equal Pinocchio's
    on the same URDF to 1e-12 at random configurations within the joint limits."""
    model = load_robot(name, variant)
    pin, pin_model = _pinocchio_model(name, variant)
    data = pin_model.createData()
    q_pin, T, base_body = _maps(model, pin_model)
    dynamic = Dynamic(model)
    ports = {op: dynamic.createOpPoint(op, op) for op in model.OperationalPointsMap}
    context = dynamic.CreateDefaultContext()
    frames = {op: model.frame(op).name() for op in ports}
    for op, frame in frames.items():
        assert pin_model.existFrame(frame), (op, frame)
    world_aligned = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for _ in range(4):
        q = _random_q(model, rng)
        dynamic.GetInputPort("position").FixValue(context, q)
        qp = q_pin(q)
        pin.forwardKinematics(pin_model, data, qp)
        pin.updateFramePlacements(pin_model, data)
        plant_context = model.plant.CreateDefaultContext()
        model.plant.SetPositions(plant_context, q)
        R_WB = model.plant.EvalBodyPoseInWorld(plant_context, model.plant.get_body(base_body)).rotation().matrix()
        Tq = T(q, R_WB)
        for op, (pose_port, jacobian_port) in ports.items():
            fid = pin_model.getFrameId(frames[op])
            X_WF = pose_port.Eval(context).GetAsMatrix4()
            np.testing.assert_allclose(X_WF, data.oMf[fid].homogeneous, atol=1e-12, err_msg=op)
            J_pin = pin.computeFrameJacobian(pin_model, data, qp, fid, world_aligned)  # rows (v; ω)
            J_WF = jacobian_port.Eval(context)  # rows (ω; v)
            np.testing.assert_allclose(J_WF, np.vstack([J_pin[3:], J_pin[:3]]) @ Tq, atol=1e-12, err_msg=op)
        np.testing.assert_allclose(dynamic.GetOutputPort("com").Eval(context), pin.centerOfMass(pin_model, data, qp), atol=1e-12)
        Jcom = pin.jacobianCenterOfMass(pin_model, data, qp)
        np.testing.assert_allclose(dynamic.GetOutputPort("Jcom").Eval(context), Jcom @ Tq, atol=1e-12)


def test_collada_meshes_convert_to_obj(tmp_path, monkeypatch):
    """Romeo's meshes are COLLADA: converted once to an OBJ Drake reads, in metres, no material file."""
    from pydrake.geometry import ReadObjToTriangleSurfaceMesh

    from sotdrake.robots import example_robot_data_dir
    from sotdrake.robots.mesh_cache import obj_for_mesh

    monkeypatch.setenv("SOTDRAKE_CACHE", str(tmp_path))
    dae = example_robot_data_dir() / "robots/romeo_description/meshes/V1/visual/RWristPitch.dae"
    obj = obj_for_mesh(dae)
    assert "mtllib" not in obj.read_text()
    mesh = ReadObjToTriangleSurfaceMesh(str(obj))
    extent = np.ptp(np.array([mesh.vertex(i) for i in range(mesh.num_vertices())]), axis=0)
    assert mesh.num_triangles() > 100 and 0.03 < extent.max() < 0.3  # a wrist, in metres
    assert obj_for_mesh(dae) == obj


def test_a_collada_mesh_the_converter_reads_nothing_from_is_reported_not_refused(tmp_path, monkeypatch, caplog):
    """ANYmal's foot: its COLLADA holds nothing the converter reads; the robot loads, the foot not drawn."""
    import logging

    monkeypatch.setenv("SOTDRAKE_CACHE", str(tmp_path))
    with caplog.at_level(logging.WARNING, logger="sotdrake.robots.mesh_cache"):
        assert load_robot("anymal", meshes=True).nq == 19
    assert any("anymal_foot.dae" in r.getMessage() and "not drawn" in r.getMessage() for r in caplog.records)


def test_add_robot_refuses_a_finalized_plant_a_second_copy_and_a_non_plant():
    from pydrake.multibody.plant import MultibodyPlant

    from sotdrake.exceptions import InvalidInput, RobotDescriptionError
    from sotdrake.robots.loader import add_robot

    finalized = MultibodyPlant(0.0)
    finalized.Finalize()
    with pytest.raises(InvalidInput, match="the plant is finalized"):  # (Drake ended the process on it)
        add_robot(finalized, "ur5")
    plant = MultibodyPlant(0.0)
    add_robot(plant, "ur5")
    with pytest.raises(RobotDescriptionError, match=r"robot 'ur5'.*already contains a model instance named 'ur5'"):
        add_robot(plant, "ur5")
    with pytest.raises(InvalidInput, match="plant must be a Drake MultibodyPlant"):
        add_robot(None, "ur5")


def test_a_catalog_robots_reference_posture_changes_its_own_and_stays_on_the_ground():
    """Naming the default group state gives the default posture (the soles on the ground); a
    ``{joint: value}`` changes only that joint of the robot's own reference posture."""
    romeo = load_robot("romeo")
    np.testing.assert_allclose(load_robot("romeo", reference_posture="half_sitting").reference_posture,
                               romeo.reference_posture, atol=1e-12)
    crouched = load_robot("romeo", reference_posture={"LKneePitch": 1.2, "RKneePitch": 1.2})
    plant = crouched.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, crouched.reference_posture)
    soles = [plant.CalcRelativeTransform(context, plant.world_frame(), crouched.frame(sole)).translation()[2]
             for sole in ROBOTS["romeo"].soles]
    np.testing.assert_allclose(soles, 0.0, atol=1e-12)  # set down again after the knees bend
    talos = load_robot("talos")
    bent = load_robot("talos", reference_posture={"arm_right_4_joint": -1.0})
    joint = talos.plant.GetJointByName("arm_right_4_joint").position_start()
    assert bent.reference_posture[joint] == -1.0
    others = np.arange(talos.nq) != joint
    np.testing.assert_array_equal(bent.reference_posture[others], talos.reference_posture[others])
