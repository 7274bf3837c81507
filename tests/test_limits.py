"""Joint limits as velocity bounds over one tick (:mod:`sotdrake.solvers.limits`): the formula on
chosen cases, and the compiled bounds against their numpy reference on random ones."""

import numpy as np
import pytest

from sotdrake.configuration import Layout
from sotdrake.solvers.limits import VelocityBounds
from tests.oracles import velocity_bounds


@pytest.fixture(scope="module")
def talos(talos_model):
    limits = talos_model.joint_limits()
    layout = Layout.of(talos_model.plant)
    bounds = VelocityBounds(limits["position_lower"], limits["position_upper"], limits["velocity_lower"],
                            limits["velocity_upper"], layout)
    return talos_model, limits, layout, bounds


def _joint(model, layout, name):
    joint = model.plant.GetJointByName(name)
    return joint.position_start(), joint.velocity_start()


def test_the_bound_of_one_joint_far_from_inside_and_beyond_its_limit(talos):
    """Upper bound of a knee: (q_max − m − q)/dt while farther than m, 0 inside the margin, (q_max − q)/dt
    < 0 beyond the limit, each capped by the velocity limit; the lower side by symmetry."""
    model, limits, layout, bounds = talos
    iq, iv = _joint(model, layout, "leg_left_4_joint")
    q_max, q_min, v_max = limits["position_upper"][iq], limits["position_lower"][iq], limits["velocity_upper"][iv]
    dt, margin = 1e-2, 1e-2
    q = model.half_sitting.copy()
    q[iq] = q_max - margin - 0.3 * v_max * dt  # reachable within the velocity limit
    lower, upper = bounds(q, dt, margin)
    assert upper[iv] == pytest.approx(0.3 * v_max)
    q[iq] = q_max - margin - 5 * v_max * dt  # far: the velocity limit binds
    assert bounds(q, dt, margin)[1][iv] == v_max
    q[iq] = q_max - 0.5 * margin  # inside the margin: stays
    assert bounds(q, dt, margin)[1][iv] == 0.0
    q[iq] = q_max + 0.2 * v_max * dt  # beyond: brought back in one tick
    lower, upper = bounds(q, dt, margin)
    assert upper[iv] == pytest.approx(-0.2 * v_max) and lower[iv] <= upper[iv]
    q[iq] = q_max + 3 * v_max * dt  # beyond and too far for one tick: as fast as allowed, the bounds meet
    lower, upper = bounds(q, dt, margin)
    assert upper[iv] == lower[iv] == -v_max
    q[iq] = q_min + margin + 0.3 * v_max * dt
    assert bounds(q, dt, margin)[0][iv] == pytest.approx(-0.3 * v_max)


def test_unselected_components_are_held_and_the_base_is_bounded_only_when_asked(talos):
    model, _, layout, bounds = talos
    selection = np.ones(model.nv, dtype=bool)
    selection[[0, 7, 20]] = False
    lower, upper = bounds(model.half_sitting, 1e-3, 1e-3, selection, (2.0, 3.0))
    assert (lower[~selection] == 0).all() and (upper[~selection] == 0).all()
    assert upper[1] == 2.0 and upper[4] == 3.0
    assert np.isinf(bounds(model.half_sitting, 1e-3, 1e-3)[1][: 6]).all()


def test_compiled_bounds_equal_their_reference(talos, rng):
    model, _, _, bounds = talos
    for k in range(500):
        q = model.half_sitting + rng.normal(size=model.nq) * rng.choice([0.01, 0.5, 3.0])
        selection = None if k % 3 else rng.random(model.nv) < 0.8
        base = None if k % 2 else (float(rng.uniform(0.1, 5)), float(rng.uniform(0.1, 5)))
        dt, margin = float(rng.choice([1e-3, 1e-2])), float(rng.choice([0.0, 1e-3, 0.1]))
        got, want = bounds(q, dt, margin, selection, base), velocity_bounds(bounds, q, dt, margin, selection, base)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
    q = model.half_sitting.copy()
    q[10] = np.nan  # a NaN position gives NaN bounds, as numpy does
    got, want = bounds(q, 1e-3, 1e-3), velocity_bounds(bounds, q, 1e-3, 1e-3)
    np.testing.assert_array_equal(got[1], want[1])
    assert np.isnan(got[1]).any()
    with pytest.raises(ValueError, match="positions"):
        bounds(q[:-1], 1e-3, 1e-3)
