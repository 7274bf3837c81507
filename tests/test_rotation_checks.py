"""One rule for a rotation given by the user: ``lie.check_rotation`` (finite, ``RᵀR = I`` to 1e-6,
``det R > 0``), whether it comes as a task's target (``as_transform``), a contact's kept pose
(``Contact6d.keep``) or an obstacle's pose (``add_obstacle``): each refuses the same matrices,
naming the argument, and takes a rotation up to round-off."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from sotdrake.collision import CollisionWorld, add_obstacle
from sotdrake.dynamics.contact import Contact6d
from sotdrake.exceptions import InvalidInput
from sotdrake.features.feature6d import as_transform
from sotdrake.lie import check_rotation

SOLE = (-0.1, 0.1, -0.05, 0.05)
TURNED = RollPitchYaw(0.3, -0.2, 1.1).ToRotationMatrix().matrix()
NOT_ROTATIONS = {
    "reflection": np.diag([1.0, 1.0, -1.0]),
    "turned reflection": TURNED @ np.diag([-1.0, 1.0, 1.0]),
    "scaled by 1 + 1e-5": TURNED * (1 + 1e-5),
    "sheared by 1e-5": TURNED + 1e-5 * np.outer([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
    "zero": np.zeros((3, 3)),
    "NaN": np.full((3, 3), np.nan),
}


def _homogeneous(R: np.ndarray) -> np.ndarray:
    X = np.eye(4)
    X[:3, :3] = R
    X[:3, 3] = (0.5, 0.2, 1.0)
    return X


@pytest.fixture(scope="module")
def world(talos_model):
    return CollisionWorld(talos_model)


@pytest.mark.parametrize("name", list(NOT_ROTATIONS))
def test_every_entry_point_refuses_the_same_matrices(name, world):
    R = NOT_ROTATIONS[name]
    with pytest.raises(InvalidInput, match="the rotation"):
        check_rotation("the rotation", R)
    with pytest.raises(InvalidInput, match="target"):
        as_transform(_homogeneous(R), "target")
    if np.isfinite(R).all():  # (a RigidTransform holds finite numbers)
        contact = Contact6d("c", 6, SOLE, dt=1e-3)
        with pytest.raises(InvalidInput, match="kept rotation"):
            contact.keep(RigidTransform(RotationMatrix(R), [0.0, 0.0, 0.0]))
    with pytest.raises(InvalidInput, match="X_WO"):
        add_obstacle(world, ("sphere", 0.1), _homogeneous(R), "ball")
    assert world.obstacles == {}


def test_a_rotation_up_to_round_off_is_taken_everywhere(talos_model):
    world = CollisionWorld(talos_model)
    R = TURNED + 1e-9
    np.testing.assert_array_equal(check_rotation("R", R), R)
    np.testing.assert_allclose(as_transform(_homogeneous(R), "target").rotation().matrix(), R, atol=1e-8)
    Contact6d("c", 6, SOLE, dt=1e-3).keep(RigidTransform(RotationMatrix(R), [0.1, 0.0, 0.0]))
    add_obstacle(world, ("sphere", 0.1), _homogeneous(R), "ball")
    assert list(world.obstacles) == ["ball"]
