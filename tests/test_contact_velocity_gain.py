"""A contact's velocity damping on the physics plant's compliant soles: its default ``K_v`` is at
most ``COMPLIANT_CONTACT_RATE / dt`` (at a 10 ms tick the former default, 30 /s, made TALOS fall
within 0.2 s), and a larger one set on the physics device is logged as a warning."""

from __future__ import annotations

import logging

import pytest
from pydrake.systems.framework import DiagramBuilder

from sotdrake import InvalidInput
from sotdrake.dynamics.checks import COMPLIANT_CONTACT_RATE, CONTACT_VELOCITY_GAIN
from sotdrake.dynamics.contact import Contact6d
from sotdrake.dynamics.robot_dyn import RobotDyn

SOLE = (-0.1, 0.1, -0.05, 0.05)


@pytest.mark.parametrize(("dt", "expected"), [(None, 30.0), (1e-3, 30.0), (5e-3, 30.0), (1e-2, 15.0), (0.05, 3.0)])
def test_the_default_velocity_gain_is_capped_by_the_tick(dt, expected):
    contact = Contact6d("c", 6, SOLE, dt=dt)
    assert contact.settings().velocity_gain == pytest.approx(expected)
    assert expected == pytest.approx(CONTACT_VELOCITY_GAIN if dt is None else min(CONTACT_VELOCITY_GAIN, COMPLIANT_CONTACT_RATE / dt))


def test_compliant_must_be_a_flag():
    with pytest.raises(InvalidInput, match="compliant"):
        Contact6d("c", 6, SOLE, dt=1e-3, compliant="yes")  # type: ignore[arg-type]


@pytest.mark.parametrize("device", ["physics", "dynsimu"])
def test_a_large_gain_on_the_compliant_soles_is_warned(talos_model, device, caplog):
    robot = RobotDyn(DiagramBuilder(), talos_model, device, 1e-2)
    contact = robot.add_contact("contactLF", "left-sole")
    with caplog.at_level(logging.WARNING, logger="sotdrake.dynamics.contact"):
        contact.setVelocityGain(15.0)  # K_v dt = 0.15: measured stable
        assert not caplog.records
        contact.setVelocityGain(30.0)
    warned = [r.getMessage() for r in caplog.records]
    if device == "physics":
        assert len(warned) == 1 and "K_v dt = 0.3" in warned[0] and "K_v ≤ 15" in warned[0]
    else:  # (the rigid model: stable up to K_v dt < 2, which the gain check enforces)
        assert not warned
    assert contact.settings().velocity_gain == 30.0  # (a warning, not a refusal)


@pytest.mark.slow
def test_talos_stands_at_a_10_ms_tick():
    """The push scenario's stack (a soft CoM task) at a 10 ms tick on the physics plant, without a
    push: with the contacts' K_v at 30 /s the load jumped from one sole to the other at every tick
    and TALOS fell at 0.2 s; with the capped default (15 /s) it stands."""
    from sotdrake.scenarios import talos_dynamics

    run = talos_dynamics.build_diagram("push", "physics", dt=1e-2, pushes=())
    simulator, times = talos_dynamics.simulate_ticks(run, 0.6, progress=False)
    summary, _ = talos_dynamics.summarize(run, simulator, times, 0.6)
    assert not summary["fell"]
    assert summary["com_max_error_m"] < 1e-3 and summary["max_foot_slip_m"] < 1e-4
    assert summary["torque_at_limit_ticks"] == 0
