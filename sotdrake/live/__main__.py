"""``python -m sotdrake.live diagrams/<script>.py [options]``: any script exposing
``build_diagram`` run live (see :mod:`sotdrake.live`).

``build_diagram`` is called with ``meshcat=`` when it takes it; the script's ``summarize(handles,
simulator, duration, wall)`` (or that of the module its ``build_diagram`` comes from, a scenario of
:mod:`sotdrake.scenarios`) is used for the summary when it has one.
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import logging
import sys
from pathlib import Path

from .runner import live_meshcat, run_live


def load_script(path: Path):
    """Import a diagram script as a module (registered in ``sys.modules`` for its dataclasses)."""
    path = Path(path)
    if not path.is_file():
        raise SystemExit(f"no such script: {path}")
    spec = importlib.util.spec_from_file_location(path.stem, path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"not a Python script: {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    if not callable(getattr(module, "build_diagram", None)):
        raise SystemExit(f"{path} has no build_diagram(...)")
    return module


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m sotdrake.live", description=__doc__.split("\n\n")[0])
    parser.add_argument("script", type=Path, help="a diagram script with build_diagram(...)")
    parser.add_argument("--out", type=Path, default=None, help="output directory (default: out/<script>_live)")
    parser.add_argument("--duration", type=float, default=None, help="stop after this simulated time (s)")
    parser.add_argument("--no-meshcat", action="store_true", help="no Meshcat")
    parser.add_argument("--port", type=int, default=0, help="command port on 127.0.0.1 (0: any free port)")
    parser.add_argument("--meshcat-port", type=int, default=None, help="Meshcat port (default: from 7000)")
    parser.add_argument("--rate", type=float, default=1.0, help="target real-time rate")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    module = load_script(args.script)
    meshcat = None if args.no_meshcat else live_meshcat(args.meshcat_port)
    build = module.build_diagram
    handles = build(meshcat=meshcat) if "meshcat" in inspect.signature(build).parameters else build()
    # A thin script imports its scenario's build_diagram: its summarize is the scenario module's.
    scenario = sys.modules.get(getattr(build, "__module__", None) or "", module)
    summarize = getattr(module, "summarize", None) or getattr(scenario, "summarize", None)
    if summarize is not None and len(inspect.signature(summarize).parameters) != 4:
        summarize = None
    out = args.out or Path("out") / f"{args.script.stem}_live"
    return run_live(handles, out, meshcat, args.duration, args.port, args.rate, summarize)


if __name__ == "__main__":
    main()
