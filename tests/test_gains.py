import math

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource

from sotdrake.exceptions import InvalidInput, SotWarning
from sotdrake.gains import GainAdaptive, constant, from_numbers, from_point, from_slope


def test_adaptive_set_matches_sot_core():
    gain = from_slope(4, 1, 5)  # a = 3, b = 5/3, c = 1
    assert (gain.a, gain.b, gain.c) == (3, 5 / 3, 1)
    assert gain(np.linalg.norm([3, 3, 3])) == pytest.approx(1 + 3 * math.exp(-5 / 3 * math.sqrt(27)))
    assert gain(np.linalg.norm([3, 3, 3])) == pytest.approx(1.00052, abs=1e-5)
    assert gain(0.0) == pytest.approx(4.0)


def test_set_by_point_is_the_tutorial_gain():
    gain = from_point(4.9, 0.9, 0.01, 0.9)
    assert gain.a == pytest.approx(4.0) and gain.c == pytest.approx(0.9)
    assert gain.b == pytest.approx(-math.log(0.9) / 0.01) and gain.b == pytest.approx(10.536, abs=1e-3)
    assert gain(0.01) == pytest.approx(0.9 + 0.9 * 4.0)  # at e_ref, the exponential part is p·a
    assert from_numbers((4.9, 0.9, 0.01, 0.9)) == gain


def test_gain_numbers_dispatch():
    assert from_numbers(10) == constant(10) and from_numbers([10]) == constant(10)
    assert from_numbers((4, 1, 5)) == from_slope(4, 1, 5)
    assert from_slope(2, 2, 5) == constant(2)  # a = 0: constant, no division by zero
    assert from_slope(5, 1, 0)(float("inf")) == 5.0  # b = 0: the constant a + c, even for an overflowed ‖e‖ (no 0·∞)


@pytest.mark.parametrize(
    "numbers", [(1, 2), (1, 2, 3, 4, 5), (float("nan"),), (-1,), (1, 2, 5), (4, 1, 0.01, 1.5), (4, 1, 0.0, 0.5)]
)
def test_bad_gains_are_rejected(numbers):
    with pytest.raises(InvalidInput):
        from_numbers(numbers)


def test_gain_entity_output_and_commands():
    builder = DiagramBuilder()
    gain = builder.AddSystem(GainAdaptive("gain"))
    source = builder.AddSystem(ConstantValueSource(AbstractValue.Make(np.array([3.0, 3.0, 3.0]))))
    builder.Connect(source.get_output_port(), gain.GetInputPort("error"))
    gain.set(4, 1, 5)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    port = gain.GetOutputPort("gain")
    assert port.Eval(gain.GetMyContextFromRoot(context))[0] == pytest.approx(1.00052, abs=1e-5)
    gain.setConstant(7.0, context)
    assert port.Eval(gain.GetMyContextFromRoot(context))[0] == 7.0
    # The context's command left the defaults alone: a new context starts from set(4, 1, 5) ...
    fresh = diagram.CreateDefaultContext()
    assert port.Eval(gain.GetMyContextFromRoot(fresh))[0] == pytest.approx(1.00052, abs=1e-5)
    # ... and a build-time command changes the defaults, not the contexts already made (and says so).
    with pytest.warns(SotWarning, match="NOT changed"):
        gain.setConstant(2.0)
    assert port.Eval(gain.GetMyContextFromRoot(context))[0] == 7.0
    assert port.Eval(gain.GetMyContextFromRoot(fresh))[0] == pytest.approx(1.00052, abs=1e-5)
    assert port.Eval(gain.GetMyContextFromRoot(diagram.CreateDefaultContext()))[0] == 2.0


def test_constant_gain_does_not_read_its_error_and_adaptive_gains_do():
    """A constant λ needs no error: with ``error`` unconnected it still gives λ, while an adaptive
    gain reads it (an unconnected error is then an error, not a silent λ(0))."""
    builder = DiagramBuilder()
    gain = builder.AddSystem(GainAdaptive("gain"))
    gain.setConstant(3.5)
    context = builder.Build().CreateDefaultContext()
    port, own = gain.GetOutputPort("gain"), gain.GetMyContextFromRoot(context)
    assert port.Eval(own)[0] == 3.5
    gain.set(4, 1, 5, context)
    with pytest.raises(RuntimeError, match="error"):
        port.Eval(own)
