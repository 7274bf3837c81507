"""A push delivers its impulse ``force · duration`` on a discrete plant of any step, wherever it
starts within a step (the plant reads the force once per step and holds it)."""

import numpy as np
import pytest
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake.physics.push import Push

MASS = 2.0  # kg


def _momentum_after(step: float, force: np.ndarray, start: float, duration: float) -> np.ndarray:
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, step)
    plant.AddRigidBody("ball", SpatialInertia(MASS, np.zeros(3), UnitInertia.SolidSphere(0.1)))
    plant.mutable_gravity_field().set_gravity_vector(np.zeros(3))
    plant.Finalize()
    push = builder.AddSystem(Push(plant, "ball", force, start, duration))
    builder.Connect(push.get_output_port(), plant.get_applied_spatial_force_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(start + duration + 3 * step + 0.01)
    v = plant.GetVelocities(plant.GetMyContextFromRoot(simulator.get_context()))
    return MASS * v[3:]


@pytest.mark.parametrize("step", [1e-3, 2e-3, 5e-3, 1e-2])
@pytest.mark.parametrize(("start", "duration"), [(0.1, 0.002), (0.1003, 0.005), (0.2, 0.1), (0.0517, 0.0231)])
def test_a_push_delivers_its_impulse_whatever_the_plant_step(step, start, duration):
    force = np.array([500.0, -120.0, 30.0])
    np.testing.assert_allclose(_momentum_after(step, force, start, duration), force * duration, rtol=1e-9, atol=1e-9)


def test_the_share_of_a_step_is_the_overlap():
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, 0.01)
    plant.AddRigidBody("ball", SpatialInertia(MASS, np.zeros(3), UnitInertia.SolidSphere(0.1)))
    plant.Finalize()
    push = Push(plant, "ball", [1.0, 0.0, 0.0], 0.013, 0.004)
    assert [push.share(t) for t in (0.0, 0.01, 0.02)] == [0.0, pytest.approx(0.4), 0.0]
    wide = Push(plant, "ball", [1.0, 0.0, 0.0], 0.005, 0.1)
    assert [wide.share(t) for t in (0.0, 0.05, 0.1, 0.11)] == [pytest.approx(0.5), 1.0, pytest.approx(0.5), 0.0]
