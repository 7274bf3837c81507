"""The centroidal momentum: ``A_G(q) v`` against Drake's spatial momentum about the CoM, ``A_G``
against finite differences of Drake's momentum in ``v``, ``Ȧ_G v`` against finite differences in
time (stepping on the manifold), on the small floating arm and on TALOS; the feature, the kinematic
and the acceleration tasks give the rows they promise; a fixed base and bad references are refused."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from sotdrake import (
    FeatureMomentum,
    InvalidInput,
    MetaTaskDynMomentum,
    MetaTaskKineMomentum,
    Robot,
    add_sot,
    load_talos,
)
from sotdrake.centroidal import centroidal_momentum_matrix, centroidal_momentum_terms
from sotdrake.configuration import Layout, integrate
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.features import momentum_error_and_jacobian
from tests.conftest import random_configuration
from tests.test_feature_functions import Arm


class Model:
    """A plant, its layout and a context, with Drake's momentum and the centroidal terms at (q, v)."""

    def __init__(self, plant, half_sitting=None):
        self.plant, self.layout = plant, Layout.of(plant)
        self.context = plant.CreateDefaultContext()
        self.nq, self.nv = plant.num_positions(), plant.num_velocities()
        self.q0 = plant.GetDefaultPositions() if half_sitting is None else half_sitting

    def set(self, q, v):
        self.plant.SetPositions(self.context, q)
        self.plant.SetVelocities(self.context, v)
        return self.plant.CalcCenterOfMassPositionInWorld(self.context)

    def drake_momentum(self, q, v) -> np.ndarray:
        p_WG = self.set(q, v)
        h = self.plant.CalcSpatialMomentumInWorldAboutPoint(self.context, p_WG)
        return np.concatenate([h.rotational(), h.translational()])

    def terms(self, q, v):
        p_WG = self.set(q, v)
        return centroidal_momentum_terms(self.plant.CalcMassMatrix(self.context), self.plant.CalcBiasTerm(self.context), q, v,
                                         p_WG, self.layout)


@pytest.fixture(scope="module", params=["arm", "talos"])
def model(request, talos_model):
    if request.param == "arm":
        return Model(Arm().plant)
    return Model(talos_model.plant, talos_model.half_sitting)


def random_state(model, rng):
    q = integrate(model.q0, rng.normal(scale=0.4, size=model.nv), 1.0, model.layout)
    q = np.clip(q, model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits())
    return q, rng.normal(size=model.nv)


def test_the_momentum_is_drakes_about_the_com(model, rng):
    for _ in range(5):
        q, v = random_state(model, rng)
        A, _, h = model.terms(q, v)
        reference = model.drake_momentum(q, v)
        np.testing.assert_allclose(h, reference, atol=1e-10 * max(1.0, np.abs(reference).max()))
        np.testing.assert_allclose(A @ v, h)


def test_the_matrix_is_the_momentums_jacobian_in_v(model, rng):
    q, v = random_state(model, rng)
    A = model.terms(q, v)[0]
    step = 1e-3  # the momentum is linear in v: central differences are exact up to round-off
    numeric = np.column_stack([(model.drake_momentum(q, v + step * e) - model.drake_momentum(q, v - step * e)) / (2 * step)
                               for e in np.eye(model.nv)])
    np.testing.assert_allclose(A, numeric, atol=1e-8 * max(1.0, np.abs(A).max()))


def test_the_drift_is_the_matrixs_rate_along_the_motion(model, rng):
    for _ in range(3):
        q, v = random_state(model, rng)
        _, drift, _ = model.terms(q, v)
        eps = 1e-6
        ahead = model.terms(integrate(q, v, eps, model.layout), v)[0]
        behind = model.terms(integrate(q, v, -eps, model.layout), v)[0]
        numeric = (ahead - behind) @ v / (2 * eps)
        np.testing.assert_allclose(drift, numeric, atol=1e-6 * max(1.0, np.abs(numeric).max()))
        assert np.abs(drift).max() > 1e-3  # not trivially zero


def test_a_fixed_base_is_refused_by_name():
    model = load_talos("left_arm")
    layout = Layout.of(model.plant)
    with pytest.raises(InvalidInput, match="floating base"):
        centroidal_momentum_matrix(np.eye(model.nv), model.half_sitting, np.zeros(3), layout)
    builder = DiagramBuilder()
    robot = Robot(builder, model)
    with pytest.raises(InvalidInput, match="floating base"):
        MetaTaskKineMomentum(robot)
    assert "featuremomentum" not in robot._names  # nothing was added


def test_the_feature_is_rate_only():
    A = np.arange(12.0).reshape(6, 2)
    h_star = np.arange(6.0)
    e, J, e_dot = momentum_error_and_jacobian(A, h_star, np.array([0, 1, 2]))
    assert not e.any() and e.shape == (3,)
    np.testing.assert_array_equal(J, A[:3])
    np.testing.assert_array_equal(e_dot, -h_star[:3])
    feature = FeatureMomentum("m", 2)
    for bad in ([np.nan] * 6, [1.0] * 5, [1e5] * 6, "zero"):
        with pytest.raises(InvalidInput, match=r"m.reference"):
            feature.setReference(bad)
    assert not feature.settings().reference.any()


def test_the_kinematic_task_sets_the_momentum(talos_model, rng):
    """A stack of the angular momentum alone (``h* = k*``): the command's momentum is ``k*``, as
    Drake computes it for the robot moving at that velocity."""
    builder = DiagramBuilder()
    robot = Robot(builder, talos_model)
    sot = add_sot(robot, solver="hqp")
    momentum = MetaTaskKineMomentum(robot)
    sot.push(momentum.task)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    k_star = np.array([0.3, -0.2, 0.5])
    momentum.feature.setReference(np.concatenate([k_star, np.zeros(3)]), context)
    v = sot.GetOutputPort("control").Eval(sot.GetMyContextFromRoot(context))
    h = Model(talos_model.plant).drake_momentum(robot.device.initial_position, v)
    np.testing.assert_allclose(h[:3], k_star, atol=1e-8)


def test_the_acceleration_task_damps_the_momentum(talos_model, rng):
    """The task's rows are ``A_G q̈ = −K_v (h − h*) − Ȧ_G v`` (angular rows) at a random state, from
    the terms computed independently here."""
    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, "dynsimu")
    momentum = MetaTaskDynMomentum(robot, kv=7.0)
    with pytest.raises(InvalidInput, match="Kv"):
        MetaTaskDynMomentum(robot, "other", kv=-1.0)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    model = Model(talos_model.plant, talos_model.half_sitting)
    q, v = random_configuration(talos_model, rng, 0.2), rng.normal(size=talos_model.nv)
    robot.device.GetMyContextFromRoot(context).SetDiscreteState(np.concatenate([q, v]))
    k_star = np.array([0.1, 0.2, -0.3])
    momentum.feature.setReference(np.concatenate([k_star, np.zeros(3)]), context)
    level = momentum.task.GetOutputPort("task").Eval(momentum.task.GetMyContextFromRoot(context))
    A, drift, h = model.terms(q, v)
    np.testing.assert_allclose(level.jacobian, A[:3], atol=1e-9 * np.abs(A).max())
    np.testing.assert_allclose(level.lower, -7.0 * (h[:3] - k_star) - drift[:3], atol=1e-8 * max(1.0, np.abs(h).max()))


@pytest.mark.slow
def test_the_push_script_brackets_each_settings_largest_push(tmp_path):
    """Both settings survive a 100 N push and fall under a 900 N one (0.1 s on the torso)."""
    from sotdrake.scenarios import push_momentum

    summary = push_momentum.main(["--forces", "100,900", "--steps", "0", "--duration", "2", "--damping", "10",
                                                  "--out", str(tmp_path), "--quiet"])
    for setting in ("without", "with"):
        assert summary[setting]["survived_n"] == 100.0 and summary[setting]["fell_n"] == 900.0
    assert (tmp_path / "summary.json").exists()
