"""The physics' speed: real-time factor of the physics runs and the plant's share of their tick.

Three runs, each with every contact model of :func:`sotdrake.physics.add_physical_talos`:

* ``reach``: ``diagrams/talos_physics.py --scenario reach`` (the kinematic SoT at 1 kHz, PD
  actuators, the plant stepping every :data:`~sotdrake.physics.PLANT_STEP`);
* ``reach_plant_1ms``: the same with the plant stepping at the SoT's 1 ms tick, the comparison that
  chose ``PLANT_STEP`` (its outcome figures beside ``reach``'s);
* ``stand_dynamics``: ``diagrams/talos_dynamics.py --scenario stand --device physics`` (the
  dynamic SoT, torque control, the torque-driven plant at the control step, Drake's SAP contact
  solver); ``stand_dynamics_tamsi``: the same with ``--contact-solver tamsi``;

and the plant alone (``plant``). For the reaches: the station of
:func:`sotdrake.physics.add_talos_station` with its PD references held at half-sitting, no
controller, standing, at the run's plant step: the floor of any physics run. For the torque-driven
stand (a plant that cannot stand without its controller): the torque-driven plant fed the torques
the run's controller sent it, from the same initial state.

Times are CPU times (``time.process_time``) of ``Simulator.AdvanceTo`` over the run, the best of
``--repeat`` turns (the machine may be shared: CPU time, and the minimum, are the least disturbed).
Reported per run: ``cpu_per_sim_s`` (CPU seconds per simulated second), ``realtime_factor`` (its
inverse: ≥ 1 is faster than real time), and ``plant_share``, the plant alone's CPU per simulated
second over the run's, both measured in the same turn. The outcome figures of each run (hand error,
slip, base drop, fall) are kept next to the timings, to show that the faster model keeps them.

    python bench/physics.py --duration 2 --repeat 2          # bench/results/physics.json
    python bench/physics.py --duration 2 --repeat 2 --save   # and bench/reference/physics.json
"""

from __future__ import annotations

import argparse
import functools
import platform
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent), str(HERE)]

from output import add_output_arguments, write_json
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from sotdrake import load_talos
from sotdrake.dynamics.station import add_torque_driven_talos
from sotdrake.physics import CONTACT_MODELS, PLANT_STEP, add_talos_station
from sotdrake.scenarios import talos_dynamics, talos_physics


@contextmanager
def contact_model(contact: str):
    """The station ``talos_physics`` builds inside uses ``contact`` (its script takes the default,
    point contact)."""
    saved = talos_physics.add_talos_station
    talos_physics.add_talos_station = functools.partial(saved, contact=contact)
    try:
        yield
    finally:
        talos_physics.add_talos_station = saved


def _advance(simulator: Simulator, duration: float) -> float:
    simulator.Initialize()
    start = time.process_time()
    simulator.AdvanceTo(duration)
    return time.process_time() - start


def plant_alone(contact: str, duration: float, plant_step: float) -> float:
    """CPU seconds per simulated second of the station alone, standing on its PD actuators."""
    model = load_talos("reduced")
    builder = DiagramBuilder()
    station = add_talos_station(builder, model.half_sitting, plant_step, contact=contact)
    builder.ExportInput(station.position, "position")
    builder.ExportInput(station.velocity, "velocity")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.get_input_port(0).FixValue(context, model.half_sitting)
    diagram.get_input_port(1).FixValue(context, np.zeros(model.nv))
    return _advance(simulator, duration) / duration


def reach(contact: str, duration: float, plant_step: float = PLANT_STEP) -> tuple[float, dict, float, float]:
    with contact_model(contact):
        run = talos_physics.build_diagram("reach", plant_step=plant_step)
    simulator = Simulator(run.diagram)
    cpu = _advance(simulator, duration)
    summary, _ = talos_physics.summarize(run, simulator, duration, cpu)
    keys = ("hand_error_m", "hand_initial_error_m", "base_drift_m", "base_height_drop_m", "min_normal_force_n",
            "max_foot_slip_m", "min_cop_margin_m", "fell")
    return cpu / duration, {k: summary[k] for k in keys}, plant_step, plant_alone(contact, duration, plant_step)


def stand_dynamics(contact: str, duration: float, contact_solver: str = "sap") -> tuple[float, dict, float, float]:
    run = talos_dynamics.build_diagram("stand", "physics", contact=contact, contact_solver=contact_solver)
    simulator = Simulator(run.diagram)
    cpu = _advance(simulator, duration)
    times = np.full(round(duration / run.robot.dt), cpu / round(duration / run.robot.dt))
    summary, _ = talos_dynamics.summarize(run, simulator, times, duration)
    keys = ("com_drift_m", "max_foot_slip_m", "max_torque_ratio", "max_friction_ratio", "fell")
    plant, _ = torque_replay(run, run.tracer.data(simulator.get_context()), contact, contact_solver, duration)
    return cpu / duration, {k: summary[k] for k in keys}, run.robot.dt, plant


def torque_replay(run, trace: dict, contact: str, contact_solver: str, duration: float) -> tuple[float, np.ndarray]:
    """CPU seconds per simulated second of the torque-driven plant alone, fed the torques the
    controller sent it in ``run`` (held over each tick, from the same initial state): the plant's
    part of that run; and the replay's final state (the run's, bit for bit)."""
    builder = DiagramBuilder()
    physical = add_torque_driven_talos(builder, run.robot.model.variant, run.robot.dt, contact, contact_solver)
    physical.plant.SetDefaultPositions(run.robot.q0)
    torques = PiecewisePolynomial.ZeroOrderHold(trace["time"], trace["torque"].T)
    source = builder.AddSystem(TrajectorySource(torques))
    builder.Connect(source.get_output_port(), physical.plant.get_actuation_input_port(physical.instance))
    simulator = Simulator(builder.Build())
    cpu = _advance(simulator, duration) / duration
    plant_context = physical.plant.GetMyContextFromRoot(simulator.get_context())
    return cpu, physical.plant.GetPositionsAndVelocities(plant_context)


RUNS = {"reach": reach, "reach_plant_1ms": functools.partial(reach, plant_step=1e-3), "stand_dynamics": stand_dynamics,
        "stand_dynamics_tamsi": functools.partial(stand_dynamics, contact_solver="tamsi")}


def measure(duration: float, repeat: int, contacts: tuple[str, ...]) -> dict:
    results: dict = {}
    for contact in contacts:
        entry: dict = {}
        for name, run in RUNS.items():
            best = None
            for _ in range(repeat):
                cpu, outcome, plant_step, plant = run(contact, duration)
                if best is None or cpu < best["cpu_per_sim_s"]:
                    best = {"cpu_per_sim_s": cpu, "plant_cpu_per_sim_s": plant, "plant_step_s": plant_step,
                            "outcome": outcome}
            best.update(realtime_factor=1.0 / best["cpu_per_sim_s"],
                        plant_share=best["plant_cpu_per_sim_s"] / best["cpu_per_sim_s"])
            entry[name] = best
            print(f"{contact:12s} {name:15s} {best['realtime_factor']:.2f}x real time, "
                  f"plant share {best['plant_share']:.2f} (plant alone {1 / best['plant_cpu_per_sim_s']:.2f}x)",
                  flush=True)
        results[contact] = entry
    return results


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=3.0, help="simulated seconds per run")
    parser.add_argument("--repeat", type=int, default=3, help="turns per run (the fastest is kept)")
    parser.add_argument("--contact", choices=[*CONTACT_MODELS, "all"], default="all")
    add_output_arguments(parser, "physics.json")
    args = parser.parse_args(argv)
    contacts = CONTACT_MODELS if args.contact == "all" else (args.contact,)
    results = {
        "command": "python bench/physics.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "clock": "time.process_time (CPU), best of repeat",
        "duration_s": args.duration,
        "repeat": args.repeat,
        "machine": {"cpus": __import__("os").cpu_count(), "python": platform.python_version()},
        "runs": measure(args.duration, args.repeat, contacts),
    }
    for path in write_json(results, args.out, args.save):
        print(f"wrote {path}")
    return results


if __name__ == "__main__":
    main()
