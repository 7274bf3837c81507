"""Running a SoT diagram the way every script in ``diagrams/`` does: simulate with a progress bar
(and a Meshcat recording), then write the run's files."""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import logging
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import NoReturn

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram

from .exceptions import InvalidInput, SotError, check_number, check_type, os_reason
from .interactive import MAX_DURATION
from .introspection import all_systems

#: The kinematic solvers a script offers with ``--solver`` (see :func:`sotdrake.robot.add_sot`).
SOLVER_HELP = {"cascade": "the basic SOT (pseudo-inverse cascade)", "hqp": "SolverKine (hierarchical QP, joint limits hard)"}


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """argparse's help with each option's default, except where the default says nothing: None
    (the help tells what happens without the option) and a flag's ``True``/``False``."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None or isinstance(action.default, bool) or action.nargs == 0:
            return action.help
        return super()._get_help_string(action)


class ScriptParser(argparse.ArgumentParser):
    """The parser of a script: once the arguments are parsed, the folders of ``--out`` that do not
    exist yet are noted, so that :func:`run_script` removes those the script made (whichever way:
    :func:`start`, a live run's files) and left empty when an option is refused."""

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                         namespace: argparse.Namespace | None = None) -> tuple[argparse.Namespace, list[str]]:
        parsed, extras = super().parse_known_args(args, namespace)
        out = getattr(parsed, "out", None)
        if isinstance(out, (str, Path)):
            _note_missing(Path(out))
        return parsed, extras


def script_arguments(doc: str, out: str, duration: float | None = 8.0, solver: str | None = None,
                     bag: bool = True, meshcat: bool = True) -> argparse.ArgumentParser:
    """The arguments every script in ``diagrams/`` takes: ``--duration``, ``--out`` and ``--quiet``;
    with ``meshcat`` (a script that records its run) ``--no-meshcat``, with ``bag`` ``--bag`` (the
    run's trace also as a rosbag2, written by :func:`write_run`), and with ``solver`` (its default:
    ``'cascade'`` or ``'hqp'``) ``--solver`` for :func:`sotdrake.robot.add_sot`; add the script's
    own, then call ``parse_args``. The description is the first paragraph of ``doc``."""
    parser = ScriptParser(description=doc.split("\n\n")[0], formatter_class=HelpFormatter)
    parser.add_argument("--duration", type=float, default=duration,
                        help="simulated time (s)" if duration is not None else "simulated time (s); None: each run's own")
    parser.add_argument("--out", type=Path, default=Path(out), help="output directory")
    if meshcat:
        parser.add_argument("--no-meshcat", action="store_true", help="no recording (faster)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    if bag:
        parser.add_argument("--bag", action="store_true",
                            help='also write the trace as a rosbag2, run/run.mcap (pip install ".[ros2]")')
    if solver is not None:
        if solver not in SOLVER_HELP:
            raise InvalidInput(f"script_arguments: solver must be one of {sorted(SOLVER_HELP)}, got {solver!r}")
        parser.add_argument("--solver", choices=sorted(SOLVER_HELP), default=solver,
                            help="; ".join(f"{name}: {text}" for name, text in SOLVER_HELP.items()))
    return parser


def options_given(parser: argparse.ArgumentParser, args: argparse.Namespace, names: Sequence[str],
                  values: bool = False) -> list[str]:
    """The options among ``names`` (argparse destinations, e.g. ``'com_gain'``) given a value other
    than their default, as ``--com-gain`` (with ``values``: ``--com-gain 4.0``): for a script that
    refuses the options of another mode rather than ignore them."""
    return [f"--{name.replace('_', '-')}" + (f" {getattr(args, name)}" if values else "") for name in names
            if getattr(args, name) != parser.get_default(name)]


def start(args: argparse.Namespace, live: bool = False) -> Meshcat | None:
    """Check ``--duration`` (in ``(0, MAX_DURATION]``: a day, as ``Runner.go``) and ``--out`` (a
    directory that can be created and written: checked before the run, not after it), set up
    logging, and start Meshcat unless ``--no-meshcat`` (or the script has no such option): for the
    recording (no URL printed: it would stop working when the script exits) or, with ``live``, to
    watch (the URL printed). See :func:`sotdrake.visualization.start_meshcat`. A refused option is a
    ``SystemExit`` whose message names it: :func:`run_script` ends the script with it
    (``<script>: error: <message>``, exit status 2)."""
    if args.duration is not None and not 0 < args.duration <= MAX_DURATION:
        raise SystemExit(f"--duration must be a number in (0, {MAX_DURATION:g}] s, got {args.duration}")
    out = getattr(args, "out", None)
    if out is not None:
        check_output_directory(Path(out))
    if getattr(args, "bag", False):
        import importlib.util

        if importlib.util.find_spec("rosbags") is None:
            raise SystemExit('--bag needs the ros2 extra: pip install ".[ros2]"')
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    if getattr(args, "no_meshcat", True):
        return None
    from .visualization import start_meshcat

    return start_meshcat(live)


def json_safe(value: object) -> object:
    """``value`` with every non-finite float (``inf``: e.g. no pair came in range; NaN) as ``None``,
    in the dictionaries and lists it holds: JSON has no such numbers (``Infinity`` is not JSON);
    numpy numbers and arrays as Python numbers and lists, a path as its string. A value nested too
    deeply for JSON (or holding itself) is an :class:`InvalidInput`."""
    try:
        return _json_safe(value)
    except RecursionError:
        raise InvalidInput(f"a value nested too deeply for JSON (or holding itself): {type(value).__name__}") from None


def _json_safe(value: object) -> object:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(item) for item in value]
    if isinstance(value, Path):
        return str(value)
    return value


def save_npz(path: Path | str, arrays: Mapping[str, object], allow_pickle: bool = False) -> Path:
    """``arrays`` (name → array) in a compressed ``.npz`` (``.npz`` appended to ``path`` if it has
    not that suffix, as numpy does), read back with ``np.load``. Unlike ``np.savez_compressed``, any
    name is stored, ``file`` and ``allow_pickle`` included (numpy takes them as its own arguments)."""
    import zipfile

    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as archive:
        for name, value in arrays.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as file:
                np.lib.format.write_array(file, np.asanyarray(value), allow_pickle=allow_pickle)
    return path


def run_script(main: Callable[[], object], leave_out: tuple[str, ...] = ("outputs",), print_summary: bool = True) -> object:
    """What a script of ``diagrams/`` runs under ``__main__``: ``main()``, its summary printed
    (:func:`report`, ``leave_out``) when it returns a ``dict`` and ``print_summary``.

    Every refusal of a script ends here, as argparse's own errors: a :class:`SotError` (an option
    argparse let through that the build or the run refuses) or a ``SystemExit`` with a message (the
    checks of :func:`start`, :func:`check_output_directory` and the scripts' own) ends the script
    with ``<script>: error: <the message>`` on one line of stderr and exit status 2; a
    ``SystemExit`` with a non-zero status (``parser.error``, which has printed its line) keeps its
    status. Either way the ``--out`` folders :func:`start` created during ``main()`` and still
    empty are removed. A ``SystemExit`` of status 0 or None (``--help``) passes unchanged."""
    if not callable(main):
        raise InvalidInput(f"run_script: main must be the script's function (run_script(main)), got {type(main).__name__}")
    made = len(_CREATED_OUTPUTS)
    try:
        result = main()
    except SotError as error:
        _remove_created_outputs(made)
        _refuse(str(error))
    except SystemExit as stop:
        if stop.code is None or stop.code == 0:
            raise
        _remove_created_outputs(made)
        if not isinstance(stop.code, int):
            _refuse(str(stop.code))
        raise
    if isinstance(result, dict) and print_summary:
        report(result, leave_out)
    return result


def _refuse(message: str) -> NoReturn:
    """``<script>: error: <message>`` (on one line) on stderr, then exit status 2."""
    line = " ".join(part.strip() for part in message.splitlines() if part.strip())
    print(f"{Path(sys.argv[0]).name}: error: {line}", file=sys.stderr, flush=True)
    raise SystemExit(2) from None


def _remove_created_outputs(made: int) -> None:
    """Remove the folders noted in :data:`_CREATED_OUTPUTS` after the first ``made`` ones, the
    deepest first, if they are still empty (one that exists since before is never noted)."""
    while len(_CREATED_OUTPUTS) > made:
        with contextlib.suppress(OSError):
            _CREATED_OUTPUTS.pop().rmdir()  # (only an empty one)


#: The ``--out`` folders (and parents) that did not exist when a script's arguments were parsed or
#: that :func:`check_output_directory` created, in this process, the deepest last.
_CREATED_OUTPUTS: list[Path] = []


def _note_missing(out: Path) -> list[Path]:
    """Note the folders of ``out`` (itself and its parents) that do not exist; returns them, the
    deepest first."""
    try:
        missing = [folder for folder in (out, *out.parents) if not folder.exists()]
    except (OSError, ValueError):  # (a NUL byte, a name too long: --out is refused later)
        return []
    _CREATED_OUTPUTS.extend(reversed(missing))
    return missing


def check_output_directory(out: Path) -> None:
    """Create ``out`` (and its parents) if needed and check that files can be written there; a
    ``SystemExit`` naming ``--out`` and the reason otherwise (no traceback; :func:`run_script`
    ends the script with it). The folders created are removed by :func:`run_script` if the script
    is refused before it writes in them."""
    import os

    missing = _note_missing(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except (OSError, ValueError) as error:
        for folder in missing:  # (the parents made before the failure, deepest first)
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise SystemExit(f"--out {out}: cannot create the output directory ({os_reason(error)})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise SystemExit(f"--out {out}: the output directory is not writable")


def simulate(diagram: Diagram, duration: float, visualizer: MeshcatVisualizer | None = None, progress: bool = True,
             label: str = "") -> tuple[Simulator, float]:
    """Run ``duration`` seconds of simulated time (recording ``visualizer`` if given: the
    ``MeshcatVisualizer`` that :func:`sotdrake.visualization.add_robot_visualizer` returns, not the
    ``Meshcat``; anything else is refused before the simulator is built); returns the simulator and
    the wall time of the loop (s). The stacks are checked first
    (:func:`sotdrake.stack_checks.check_stack`: a task without gain or feature is named).

    The streaming tracers of ``diagram`` (:class:`sotdrake.tracing.Tracer`) move their samples to
    their files as the run goes (see :func:`sotdrake.tracing.flush_tracers`) and at its end, whether
    it returns or stops on an error or Ctrl-C: a tracer's file then holds the whole run. The garbage collector
    is frozen for the loop (:func:`frozen_gc`): what the build made is collected once, then left
    out of the collections, so that no full collection pauses a tick."""
    from tqdm import tqdm

    from .stack_checks import check_stack
    from .tracing import tracers_of

    check_type("simulate: diagram", diagram, Diagram, "a built Diagram (builder.Build())")
    if check_number("duration", duration, 0.0, MAX_DURATION, " s") == 0:
        raise InvalidInput("duration must be > 0 s, got 0")
    if visualizer is not None and not isinstance(visualizer, MeshcatVisualizer):
        hint = ": give add_robot_visualizer(robot, meshcat)'s result" if isinstance(visualizer, Meshcat) else ""
        raise InvalidInput("simulate: visualizer must be None or the MeshcatVisualizer that add_robot_visualizer returns, "
                           f"got {type(visualizer).__name__}{hint}")
    check_stack(diagram)
    simulator = Simulator(diagram)
    simulator.Initialize()
    if visualizer is not None:
        visualizer.StartRecording(False)
    chunk = 0.05
    tracers = tracers_of(diagram)
    start = time.perf_counter()
    with frozen_gc(), tqdm(total=round(duration, 6), disable=not progress, file=sys.stderr, desc=label, leave=bool(not label),
              bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} s [{elapsed}<{remaining}]") as bar:
        try:
            for k in range(1, int(np.ceil(duration / chunk - 1e-9)) + 1):
                t = min(k * chunk, duration)
                simulator.AdvanceTo(t)
                for tracer in tracers:
                    tracer.flush(simulator.get_context())
                bar.update(t - bar.n)
            for tracer in tracers:  # (the run's end too: when simulate returns, the files hold the whole run)
                tracer.flush(simulator.get_context(), force=True)
        except BaseException:  # (an error, Ctrl-C: the samples recorded so far reach the files)
            for tracer in tracers:
                with contextlib.suppress(Exception):
                    tracer.flush(simulator.get_context(), force=True)
            raise
    return simulator, time.perf_counter() - start


@contextlib.contextmanager
def frozen_gc() -> Iterator[None]:
    """Collect, then ``gc.freeze()`` for the block and ``gc.unfreeze()`` after it: the objects the
    build made (the diagram's systems, their numpy buffers, the model) move to the permanent
    generation, so a collection during the block only scans what the block itself allocated and
    the full (generation 2) collections that would scan everything have nothing to wait for. The
    behaviour is otherwise unchanged: objects freed by reference counting are freed as before; a
    cycle made during the block is collected as usual."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def gen2_collections() -> int:
    """The number of full (generation 2) garbage collections since the interpreter started."""
    return int(gc.get_stats()[2]["collections"])


def save_figure(fig, path: Path, dpi: int = 100, tight: bool = True) -> Path:
    """Write the matplotlib figure ``fig`` to ``path`` (laid out first with ``tight``) and close it."""
    import matplotlib.pyplot as plt

    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return Path(path)


def write_run(out: Path, diagram: Diagram, summary: dict, trace: dict | None = None,
              meshcat: Meshcat | None = None, visualizer=None, graph: bool = True, bag: bool = False) -> dict:
    """Write ``trace.npz``, ``control_graph.svg`` (and ``.dot``), ``recording.html`` and
    ``summary.json`` (with the paths written, ``stalled_tasks``: the tasks whose error stopped
    decreasing, with the error they were left at, see :mod:`sotdrake.progress`, and
    ``refused_commands``: the timed commands refused during the run, by entity) in ``out``; with
    ``bag``, the trace as a rosbag2 too (``run/run.mcap``: :func:`sotdrake.ros.write_trace_bag`, the
    joints named by the diagram's ``dynamic`` entity; needs the ros2 extra); returns the paths."""
    from .progress import stalled_tasks
    from .visualization import save_recording, write_control_graph

    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        outputs = {}
        if trace is not None:
            outputs["trace"] = save_npz(out / "trace.npz", trace, allow_pickle=True)
        if graph:
            outputs["control_graph"] = write_control_graph(diagram, out / "control_graph.svg")
        if meshcat is not None and visualizer is not None:
            outputs["recording"] = save_recording(visualizer, meshcat, out / "recording.html")
        summary.setdefault("stalled_tasks", stalled_tasks(diagram))
        summary.setdefault("refused_commands", {system.get_name(): [{"t": t, "message": m} for t, m in system.refused_commands]
                                                for system in all_systems(diagram) if getattr(system, "refused_commands", None)})
        try:
            if bag and trace is not None:
                outputs["bag"] = _write_bag(out / "run", diagram, trace)
        finally:  # (the summary even when the bag is refused: the run's other outputs are written)
            summary["outputs"] = {k: str(v) for k, v in outputs.items()}
            (out / "summary.json").write_text(json.dumps(json_safe(summary), indent=2) + "\n")
    except SotError:
        raise
    except (OSError, ValueError) as error:  # (a NUL byte in the path: ValueError)
        raise InvalidInput(f"write_run: cannot write the run in {str(out)!r}: {os_reason(error)}") from None
    names = ", ".join(Path(p).name for p in outputs.values())
    note = "; open recording.html in a browser: it plays by itself" if "recording" in outputs else ""
    print(f"wrote {names}{', ' if names else ''}summary.json in {out}{note}", file=sys.stderr)
    return outputs


def _write_bag(directory: Path, diagram: Diagram, trace: dict) -> Path:
    """The trace as a rosbag2 in ``directory``. Its configuration is ``q`` (or ``q_device``), or the
    positions of a state ``x`` (or ``x_plant``), named by the plant of a system of the diagram that
    has one of that size (the ``dynamic`` entity, a physics plant), else ``q0``, ``q1``, …"""
    import sotdrake.ros

    systems = list(all_systems(diagram))
    plants = [s.plant for s in systems if getattr(getattr(s, "plant", None), "num_positions", None)]
    plants += [s for s in systems if hasattr(s, "num_positions") and hasattr(s, "num_velocities")]
    key = next((k for k in ("q", "q_device", "x", "x_plant") if k in trace), None)
    if key is None:
        raise InvalidInput(f"--bag: the trace has no configuration (q, q_device, x or x_plant); it has {sorted(trace)}")
    width = int(np.shape(trace[key])[1])
    if key.startswith("x"):
        plant = next((p for p in plants if p.num_positions() + p.num_velocities() == width), None)
        nq = plant.num_positions() if plant is not None else width
    else:
        plant = next((p for p in plants if p.num_positions() == width), None)
        nq = width
    joints = sotdrake.ros.joint_coordinates(plant) if plant is not None else ([f"q{i}" for i in range(nq)], np.arange(nq))
    return sotdrake.ros.write_trace_bag(directory, {**trace, "q": np.asarray(trace[key])[:, :nq]}, joints)


def report(summary: dict, leave_out: tuple[str, ...] = ("outputs",)) -> dict:
    """Print a scenario's ``summary`` as every script of ``diagrams/`` does: indented JSON, flushed,
    without the keys of ``leave_out``, at the top level and in the dictionaries it holds (by
    default the paths :func:`write_run` wrote, ``outputs``); returns ``summary`` unchanged."""

    def kept(mapping: dict) -> dict:
        return {key: value for key, value in mapping.items() if key not in leave_out}

    shown = {key: kept(value) if isinstance(value, dict) else value for key, value in kept(summary).items()}
    print(json.dumps(json_safe(shown), indent=2), flush=True)
    return summary
