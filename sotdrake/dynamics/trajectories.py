"""Reference trajectories for the dynamic scripts: minimum-jerk moves between held values, as
Drake trajectories, and the ports that feed them (value, velocity, acceleration) to a task."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from pydrake.systems.framework import OutputPort
from pydrake.systems.primitives import Demultiplexer, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ..exceptions import InvalidInput, check_count, check_finite, check_name, check_number, check_type
from .robot_dyn import RobotDyn

#: The most points :func:`minimum_jerk_moves` samples per move.
MAX_SAMPLES = 10_000
#: The latest ``end`` (s) of :func:`minimum_jerk_moves`.
MAX_END = 1e6
#: The shortest move, and the shortest hold between moves or after the last (s): the shortest
#: control tick (a spline's times closer than 2.2e-16 s are refused by Drake). Checked to 1 ns,
#: so that ``t0 + MIN_MOVE`` passes whatever its round-off.
MIN_MOVE = 1e-6
_SHORTEST = MIN_MOVE - 1e-9


def minimum_jerk_moves(start: np.ndarray, moves: Sequence[tuple[float, float, np.ndarray]], end: float = 1e3,
                       samples: int = 24) -> PiecewisePolynomial:
    """From ``start``, each move ``(t0, t1, target)`` a minimum-jerk profile
    ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` (``τ = (t − t0)/(t1 − t0)``), held still between the moves and
    after the last until ``end`` (s), as Drake's cubic Hermite spline through ``samples`` points of
    each move with their exact velocities (so the acceleration follows the profile closely and
    starts and ends near 0). Each move must last at least :data:`MIN_MOVE` s and start at the
    previous one's end (or at 0) or at least :data:`MIN_MOVE` s after it; the values are finite
    vectors of ``start``'s size (at least one number); ``end`` in ``(0, MAX_END]`` s, the last move's
    end or at least :data:`MIN_MOVE` s after it; ``samples``: an integer ≥ 2 (the move's two ends
    and the points between).
    Anything else is an :class:`InvalidInput` naming it, before Drake sees any."""
    samples = check_count("minimum-jerk moves: samples", samples, 2, MAX_SAMPLES)
    if not check_number("minimum-jerk moves: end", end, 0.0, MAX_END, " s") > 0:
        raise InvalidInput(f"minimum-jerk moves: end must be > 0 s (the trajectory holds until then), got {end!r}")
    end = float(end)
    start = check_finite("minimum-jerk moves: start", start)
    if start.ndim != 1 or not start.size:
        raise InvalidInput(f"minimum-jerk moves: start must be a vector of at least one number, got shape {start.shape}")
    times, values, rates = [0.0], [start], [np.zeros_like(start)]
    current = start
    for t0, t1, target in _moves(moves):
        t0 = check_number("minimum-jerk move: t0", t0, times[-1], end, " s")
        t1 = check_number("minimum-jerk move: t1", t1, t0, end, " s")
        if not t1 - t0 >= _SHORTEST:
            raise InvalidInput(f"minimum-jerk move: t1 − t0 must be at least {MIN_MOVE:g} s, got t0 = {t0!r} s, "
                               f"t1 = {t1!r} s")
        if 0 < t0 - times[-1] < _SHORTEST:
            raise InvalidInput(f"minimum-jerk move: t0 = {t0!r} s must be the previous move's end ({times[-1]!r} s) or at "
                               f"least {MIN_MOVE:g} s after it")
        target = check_finite("minimum-jerk move: target", target, start.shape)
        for tau in np.linspace(0.0, 1.0, samples):
            s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
            ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / (t1 - t0)
            t = t1 if tau == 1.0 else t0 + tau * (t1 - t0)  # (the move ends at t1 exactly)
            if t > times[-1]:
                times.append(t)
                values.append(current + s * (target - current))
                rates.append(ds * (target - current))
        current = target
    if 0 < end - times[-1] < _SHORTEST:
        raise InvalidInput(f"minimum-jerk moves: end = {end!r} s must be the last move's end ({times[-1]!r} s) or at least "
                           f"{MIN_MOVE:g} s after it")
    if end > times[-1]:  # (held until ``end``; a last move that ends there needs no held piece)
        times.append(end)
        values.append(current)
        rates.append(np.zeros_like(start))
    return PiecewisePolynomial.CubicHermite(times, np.column_stack(values), np.column_stack(rates))


def _moves(moves) -> list[tuple]:
    """``moves`` as a list of triples ``(t0, t1, target)``, else :class:`InvalidInput`."""
    if isinstance(moves, (str, bytes)) or not isinstance(moves, Iterable):
        raise InvalidInput(f"minimum-jerk moves: moves must be a list of (t0, t1, target), got {moves!r:.100}")
    moves = list(moves)
    for move in moves:
        if isinstance(move, (str, bytes)) or not isinstance(move, Sequence) or len(move) != 3:
            raise InvalidInput(f"minimum-jerk moves: each move is (t0, t1, target), got {move!r:.100}")
    return moves


def hold_move_hold(t0: float, t1: float, a: np.ndarray, b: np.ndarray) -> PiecewisePolynomial:
    """``a`` until ``t0``, a minimum-jerk move to ``b`` at ``t1``, then ``b`` (s: ``0 ≤ t0``,
    ``t0 + MIN_MOVE ≤ t1 ≤ 1000``, :data:`MIN_MOVE` = 1e-6 s); ``a`` and ``b``: finite vectors of one
    size, at least one number (:func:`minimum_jerk_moves`'s checks)."""
    return minimum_jerk_moves(a, [(t0, t1, b)])


def trajectory_ports(robot: RobotDyn, trajectory: PiecewisePolynomial, name: str) -> tuple[OutputPort, OutputPort, OutputPort]:
    """Value, velocity and acceleration output ports of ``trajectory`` (Drake's
    ``TrajectorySource`` named ``name``, split by a ``Demultiplexer``, added to ``robot``, a
    :class:`RobotDyn`). ``name``: a non-empty string, new with ``name + "_split"``; anything else is an
    :class:`InvalidInput` naming the argument, before anything is added."""
    check_type("trajectory_ports: robot", robot, RobotDyn, "a RobotDyn")
    check_name("trajectory_ports: name", name)
    if not isinstance(trajectory, PiecewisePolynomial):
        raise InvalidInput(f"trajectory_ports({name!r:.60}): trajectory must be a PiecewisePolynomial, got "
                           f"{type(trajectory).__name__}")
    robot.check_new_names([name, name + "_split"])  # (both refused before either is added)
    n = trajectory.rows()
    source = robot.add(TrajectorySource(trajectory, output_derivative_order=2), name)
    split = robot.add(Demultiplexer([n, n, n]), name + "_split")
    robot.builder.Connect(source.get_output_port(), split.get_input_port())
    return split.get_output_port(0), split.get_output_port(1), split.get_output_port(2)
