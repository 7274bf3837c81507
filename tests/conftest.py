import numpy as np
import pytest

from sotdrake.robots import load_talos


@pytest.fixture(scope="session")
def talos_model():
    return load_talos("reduced")


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


def random_configuration(model, rng, spread: float = 0.5) -> np.ndarray:
    """Half-sitting moved by a random velocity: joints within their limits, any base pose."""
    from sotdrake.device import Layout, integrate

    q = integrate(model.half_sitting, rng.normal(scale=spread, size=model.nv), 1.0, Layout.of(model.plant))
    lo, up = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()
    return np.clip(q, lo, up)
