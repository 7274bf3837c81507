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
    from sotdrake.configuration import Layout, integrate

    q = integrate(model.half_sitting, rng.normal(scale=spread, size=model.nv), 1.0, Layout.of(model.plant))
    lo, up = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()
    return np.clip(q, lo, up)


def load_diagram(script: str):
    """Import ``diagrams/<script>.py`` as a module (registered, so that its dataclasses work)."""
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "diagrams" / f"{script}.py"
    spec = importlib.util.spec_from_file_location(script, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
