"""The SoT on a physically simulated TALOS: standing, a short reach, the PD-gain check, the monitor."""

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import PdControllerGains
from pydrake.systems.framework import DiagramBuilder

from sotdrake.exceptions import InvalidInput, SotError
from sotdrake.physics import CONTACT_SOLVERS, Push, add_physical_talos, check_pd_gains, set_pd_gains
from sotdrake.robots import add_talos
from sotdrake.scenarios import talos_physics


@pytest.fixture(scope="module")
def physics():
    return talos_physics


def run(physics, scenario, duration, **kwargs):
    handles = physics.build_diagram(scenario, **kwargs)
    simulator, wall = physics.simulate(handles.diagram, duration, progress=False)
    return physics.summarize(handles, simulator, duration, wall)


@pytest.fixture(scope="module")
def stand_then_push(physics):
    """One standing run pushed by 150 N along +x at t = 2 s for 0.1 s, summarized at 2 s (before the
    push: the standing run, the push force being zero until then) and again at 2.6 s."""
    handles = physics.build_diagram("stand", push=150.0, push_start=2.0)
    simulator, wall = physics.simulate(handles.diagram, 2.0, progress=False)
    standing = physics.summarize(handles, simulator, 2.0, wall)
    simulator.AdvanceTo(2.6)
    pushed = physics.summarize(handles, simulator, 2.6, wall)
    return standing, pushed


def test_standing_holds(stand_then_push):
    (summary, trace), _ = stand_then_push
    assert summary["ticks"] == 2001 and trace["time"][-1] == pytest.approx(2.0)  # up to the push, not after
    assert summary["base_drift_m"] < 0.01 and summary["base_height_drop_m"] < 0.005
    assert summary["max_foot_slip_m"] < 1e-3
    assert summary["min_normal_force_n"] > 100.0  # both feet loaded from the first step on
    total = trace["feet"][-1, 2] + trace["feet"][-1, 5]
    assert total == pytest.approx(90.27 * 9.81, rel=0.03)  # the feet carry the robot's weight
    assert summary["min_cop_margin_m"] > 0.02
    assert not summary["fell"] and summary["max_other_contact_n"] == 0.0  # no link but the soles touches


@pytest.mark.slow
def test_short_reach_keeps_balance(physics):
    summary, trace = run(physics, "reach", 2.5)
    assert summary["hand_error_m"] < 0.5 * summary["hand_initial_error_m"]  # well on its way
    assert summary["base_height_drop_m"] < 0.05 and summary["min_normal_force_n"] > 0.0
    assert summary["max_foot_slip_m"] < 1e-3 and summary["min_cop_margin_m"] > 0.0


def test_a_push_is_applied_and_survived(stand_then_push):
    (_, before), (summary, trace) = stand_then_push
    base = trace["base_position"]
    moved = np.abs(base[:, 0] - base[0, 0]).max()
    assert moved > 0.005  # the push did something …
    at_push = len(before["time"]) - 1  # t = 2 s: the standing run settled the base by ~5 mm before it
    assert np.abs(base[at_push:, 0] - base[at_push, 0]).max() > 0.005  # … from t = 2 s on
    assert summary["min_normal_force_n"] > 0.0 and summary["max_foot_slip_m"] < 1e-3  # … and it stood


def test_pd_gains_are_checked():
    plant = MultibodyPlant(1e-3)
    add_talos(plant)
    plant.Finalize()
    with pytest.raises(SotError, match="no PD controller"):
        check_pd_gains(plant)  # gains never set: the desired state would be ignored
    set_pd_gains(plant, 30.0, 0.05)
    actuator = plant.get_joint_actuator(next(iter(plant.GetJointActuatorIndices())))
    actuator.set_controller_gains(PdControllerGains(p=0.0, d=1.0))
    with pytest.raises(SotError, match=actuator.name()):
        check_pd_gains(plant)
    with pytest.raises(InvalidInput):
        set_pd_gains(plant, -1.0, 0.05)


def test_physics_inputs():
    builder = DiagramBuilder()
    with pytest.raises(InvalidInput):
        add_physical_talos(builder, time_step=0.0)
    with pytest.raises(InvalidInput, match="contact"):
        add_physical_talos(builder, contact="mesh")
    for solver in ("SAP", "similar", None, 1):
        with pytest.raises(InvalidInput, match="contact_solver"):
            add_physical_talos(builder, contact_solver=solver)
    assert not builder.GetSystems()  # refused before anything was added
    for solver, approximation in CONTACT_SOLVERS.items():
        plant = add_physical_talos(DiagramBuilder(), contact_solver=solver).plant
        assert plant.get_discrete_contact_approximation() == approximation
    robot = add_physical_talos(DiagramBuilder())
    with pytest.raises(InvalidInput):
        Push(robot.plant, "torso_2_link", [np.nan, 0, 0], 1.0, 0.1)
    assert robot.plant.num_actuators() == 32 and len(robot.actuated_q) == 32


def test_a_refused_station_leaves_the_builder_as_it_was(talos_model):
    """A bad q0 used to end the process (Drake's failed check); a bad push body was found once the
    plant was in the builder. Each is now refused with the builder unchanged, and still usable."""
    from sotdrake.exceptions import NotFound
    from sotdrake.physics import add_talos_station

    builder = DiagramBuilder()
    q0 = talos_model.half_sitting
    for bad, error in (({"q0": q0[:3]}, "39 positions"), ({"q0": np.full_like(q0, np.nan)}, "q0"), ({"q0": "q"}, "q0"),
                       ({"push_force": [1.0, 2.0]}, "push"), ({"push_force": [0.0, 0.0, 1.0], "push_duration": -1.0}, "push"),
                       ({"time_step": -1.0}, "time_step"), ({"contact": "mesh"}, "contact")):
        with pytest.raises(InvalidInput, match=error):
            add_talos_station(builder, **{"q0": q0, **bad})
        assert not builder.GetSystems()
    with pytest.raises(NotFound, match="nobody"):
        add_talos_station(builder, q0, push_force=[0.0, 0.0, 1.0], push_body="nobody")
    assert not builder.GetSystems()
    station = add_talos_station(builder, q0, push_force=[0.0, 0.0, 1.0])
    diagram = builder.Build()
    assert diagram.GetSubsystemByName("push") is station.push


def test_the_estimator_and_the_hold_check_their_arguments(talos_model):
    from pydrake.systems.primitives import ConstantVectorSource

    from sotdrake.physics import KinematicBaseEstimator
    from sotdrake.physics.actuators import hold_one_tick

    for q0 in (talos_model.half_sitting[:3], np.full(talos_model.nq, np.nan), None):
        with pytest.raises(InvalidInput, match="q0"):
            KinematicBaseEstimator(talos_model, q0)
    builder = DiagramBuilder()
    source = builder.AddSystem(ConstantVectorSource(np.zeros(2)))
    for dt in (0.0, -1e-3, float("nan"), "1e-3", None):
        with pytest.raises(InvalidInput, match="dt"):
            hold_one_tick(builder, source.get_output_port(), "held", dt)
    assert len(builder.GetSystems()) == 1


def test_script_outputs(physics, tmp_path):
    summary = physics.main(["--scenario", "stand", "--duration", "0.2", "--out", str(tmp_path), "--no-meshcat", "--quiet"])
    for key in ("hand_error_m", "base_drift_m", "base_height_drop_m", "min_normal_force_n", "max_foot_slip_m", "realtime_factor"):
        assert key in summary
    assert (tmp_path / "plots.png").is_file() and (tmp_path / "trace.npz").is_file()


def test_base_estimator_is_leg_odometry(talos_model):
    """The measured joints pass through; the base comes from the soles staying where they started,
    whatever the measured base says."""
    from sotdrake.physics import KinematicBaseEstimator

    estimator = KinematicBaseEstimator(talos_model, talos_model.half_sitting)
    context = estimator.CreateDefaultContext()
    x = np.concatenate([talos_model.half_sitting, np.zeros(talos_model.nv)])
    x[4:7] += [0.3, -0.2, 0.1]  # the whole robot moved: the feet did not
    estimator.get_input_port().FixValue(context, x)
    np.testing.assert_allclose(estimator.get_output_port().Eval(context), talos_model.half_sitting, atol=1e-12)
    knee = talos_model.plant.GetJointByName("leg_left_4_joint").position_start()
    x[knee] += 0.1  # one knee bends: the joint is passed through, the base moves
    estimator.get_input_port().FixValue(context, x)
    q = estimator.get_output_port().Eval(context)
    assert q[knee] == x[knee] and np.linalg.norm(q[4:7] - talos_model.half_sitting[4:7]) > 1e-3
    assert np.linalg.norm(q[:4]) == pytest.approx(1.0)


@pytest.mark.slow
@pytest.mark.parametrize("body_collision", [True, False])
def test_a_fall_lands_on_the_ground(talos_model, body_collision):
    """Limp actuators: the robot collapses. With the links' boxes it lies on the ground (its base a
    few centimetres up, a link pressing on the ground: it fell); with the soles alone it sinks
    through the floor."""
    from pydrake.systems.analysis import Simulator

    from sotdrake.fall import fall_report, tilt_of_quaternions
    from sotdrake.physics import add_talos_station

    builder = DiagramBuilder()
    station = add_talos_station(builder, talos_model.half_sitting, stiffness=1e-3, body_collision=body_collision)
    builder.ExportInput(station.position, "position")
    builder.ExportInput(station.velocity, "velocity")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.get_input_port(0).FixValue(context, talos_model.half_sitting)
    diagram.get_input_port(1).FixValue(context, np.zeros(talos_model.nv))
    heights, tilts, other, times = [], [], [], []
    for t in np.arange(0.1, 1.51, 0.1):
        simulator.AdvanceTo(t)
        x = station.plant_state.Eval(station.physical.plant.GetMyContextFromRoot(context))
        heights.append(x[6])
        tilts.append(tilt_of_quaternions(x[None, :4])[0])
        other.append(station.other_contact.Eval(station.monitor.GetMyContextFromRoot(context))[0])
        times.append(t)
    if body_collision:
        assert 0.05 < heights[-1] < 0.6 and max(other) > 100.0
        report = fall_report(np.array(times), np.array(tilts), np.array(heights), other_contact=np.array(other))
        assert report["fell"] and report["fell_at_s"] < 1.5
    else:
        assert heights[-1] < -0.3  # through the floor


def test_the_plant_steps_at_its_own_rate(physics, tmp_path):
    """The plant's step is ``PLANT_STEP`` by default, set by ``plant_step`` (``--plant-step``): the
    SoT's tick stays 1 ms either way; a step out of (0, 0.01] s is refused with a message."""
    from sotdrake.physics import PLANT_STEP

    for step in (PLANT_STEP, 1e-3):
        handles = physics.build_diagram("stand", plant_step=step)
        assert handles.physical.plant.time_step() == step and handles.robot.dt == 1e-3
    for bad in ("0", "nan", "0.02"):
        with pytest.raises(SystemExit) as exited:
            physics.main(["--plant-step", bad, "--no-meshcat", "--quiet", "--out", str(tmp_path)])
        assert exited.value.code == 2
    with pytest.raises(InvalidInput, match="time_step"):
        physics.build_diagram("stand", plant_step=0.0)


@pytest.mark.parametrize("loop", ["open", "closed"])
def test_the_servos_velocity_moves_the_device_over_a_tick(physics, loop):
    """The servos' position and velocity references agree while the hand reaches: in the open loop
    the velocity is the command for the coming tick, ``q_des(t + dt) − q_des(t) = dt · v_des(t)``; in
    the closed loop (the SoT reads the stepped plant) the one the device integrated over the last
    tick, held, ``q_des(t) − q_des(t − dt) = dt · v_des(t)``. The traced velocity scale stays 1."""
    from pydrake.systems.analysis import Simulator

    handles = physics.build_diagram("reach", loop=loop)
    simulator = Simulator(handles.diagram)
    context = simulator.get_context()
    desired = handles.station.desired
    desired_context = desired.GetMyContextFromRoot(context)
    dt = handles.robot.dt
    simulator.AdvanceTo(1.2)  # the hand task pushed at 1 s: the joints are moving
    states = []
    for k in range(1, 22):
        simulator.AdvanceTo(1.2 + k * dt)
        states.append(desired.get_output_port().Eval(desired_context).copy())
    states = np.array(states)
    half = states.shape[1] // 2
    q, v = states[:, :half], states[:, half:]
    moved = q[1:] - q[:-1]
    expected = dt * (v[:-1] if loop == "open" else v[1:])
    np.testing.assert_allclose(moved, expected, rtol=0, atol=1e-12)
    assert np.abs(v).max() > 0.05
    summary, _ = physics.summarize(handles, simulator, simulator.get_context().get_time(), 1.0)
    assert summary["min_velocity_scale"] == 1.0
