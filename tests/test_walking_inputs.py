"""The pattern generator's inputs: a start it cannot plan from is refused when it is made (a CoM
at the ground used to end the process inside Drake's planner), and feet turned about ±π walk
forward (their yaws read −π + ε and π − ε are close, not 2π apart)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix

from sotdrake.exceptions import InvalidInput
from sotdrake.walking import GaitParameters, PatternGenerator, Start, WalkCommand, initial_plan, replan
from sotdrake.walking.pattern_generator import start_of

FEET = {"left": RigidTransform([0.0, 0.1, 0.0]), "right": RigidTransform([0.0, -0.1, 0.0])}
WAIST = RigidTransform([0.0, 0.0, 1.0])


@pytest.mark.parametrize(("feet", "com", "waist", "named"), [
    (FEET, [0.0, 0.0, 0.0], WAIST, "above the ground"),
    (FEET, [0.0, 0.0, -0.5], WAIST, "above the ground"),
    (FEET, [np.nan, 0.0, 0.87], WAIST, "com"),
    (FEET, [0.0, 0.87], WAIST, "com"),
    ({"left": FEET["left"]}, [0.0, 0.0, 0.87], WAIST, "'left' and 'right'"),
    ({**FEET, "right": "sole"}, [0.0, 0.0, 0.87], WAIST, "right pose"),
    (FEET, [0.0, 0.0, 0.87], None, "waist pose"),
])
def test_a_start_that_cannot_be_planned_from_is_refused_when_made(feet, com, waist, named):
    with pytest.raises(InvalidInput, match=named):
        Start(feet, np.array(com), waist)


@pytest.mark.parametrize("dt", [0.0, -0.01, float("inf"), float("nan"), "0.01", None, True, 2.0])
def test_the_pattern_generator_refuses_a_bad_period(dt):
    start = Start(FEET, np.array([0.0, 0.0, 0.87]), WAIST)
    with pytest.raises(InvalidInput, match="dt must be a number"):
        PatternGenerator(start, dt)


def test_the_pattern_generator_refuses_what_is_not_a_start():
    with pytest.raises(InvalidInput, match="start must be a Start"):
        PatternGenerator({"left": FEET["left"]}, 0.01)


def test_start_of_needs_both_soles():
    with pytest.raises(InvalidInput, match="two names"):
        start_of(None, np.zeros(0), feet=("left-sole",))


@pytest.mark.parametrize("heading", [np.pi, -np.pi + 1e-3, np.pi / 2])
def test_feet_turned_about_pi_step_forward_without_turning(heading):
    """Soles splayed by ±0.02 rad about ``heading``: one step of 0.2 m forward lands 0.2 m along
    the heading, at the heading's yaw, and neither foot turns by more than the splay on the way."""

    def sole(dy: float, splay: float) -> RigidTransform:
        return RigidTransform(RotationMatrix.MakeZRotation(heading + splay),
                              RotationMatrix.MakeZRotation(heading).multiply(np.array([0.0, dy, 0.0])))

    start = Start({"left": sole(0.1, 0.02), "right": sole(-0.1, -0.02)}, np.array([0.0, 0.0, 0.87]),
                  RigidTransform(RotationMatrix.MakeZRotation(heading), [0.0, 0.0, 1.0]))
    gait = GaitParameters()
    plan = replan(initial_plan(start, gait), WalkCommand(steps=((0.2, 0.0, 0.0),)), 0.0, gait)
    forward = np.array([np.cos(heading), np.sin(heading)])
    first = plan.steps[0]
    assert float(np.dot([first.x, first.y], forward)) == pytest.approx(0.2, abs=1e-9)
    for step in plan.steps:
        assert abs(np.angle(np.exp(1j * (step.yaw - heading)))) < 1e-9
    for side in ("left", "right"):
        trajectory = plan.feet[side]
        yaws = [trajectory.value(t)[3, 0] for t in np.linspace(trajectory.start_time(), trajectory.end_time(), 200)]
        assert max(yaws) - min(yaws) <= 0.02 + 1e-9, side
