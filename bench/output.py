"""Where the bench scripts write: ``--out`` (default ``bench/results/<name>``, ignored by git) and,
with ``--save``, the committed copy in ``bench/reference/<name>`` that the docs' benchmark tables
are generated from (``docs/_ext/sotdrake_docs.py``). Nothing else under ``bench/`` is written."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"  # ignored by git
REFERENCE = HERE / "reference"  # committed: changes only with --save


def add_output_arguments(parser: argparse.ArgumentParser, name: str, *aliases: str, flag: str = "--out") -> None:
    """``flag`` (and ``aliases``: the JSON file written, ``args.<flag>``; default
    ``bench/results/<name>``) and ``--save``."""
    parser.add_argument(flag, *aliases, type=Path, default=RESULTS / name,
                        help=f"the JSON file written (default: bench/results/{name}, ignored by git)")
    parser.add_argument("--save", action="store_const", const=REFERENCE / name, default=None,
                        help=f"also write bench/reference/{name}, the committed run the docs' tables show")


def write_json(data: object, out: Path, save: bool | Path | None = False, indent: int = 2) -> list[Path]:
    """Write ``data`` as JSON to ``out`` and, with ``save``, to the reference file: ``save`` itself
    (what ``--save`` holds: the bench's own reference, whatever ``out`` is), or with ``True``
    ``bench/reference/<out's name>``."""
    text = json.dumps(data, indent=indent, default=repr) + "\n"
    reference = save if isinstance(save, Path) else REFERENCE / Path(out).name
    paths = [Path(out)] + ([reference] if save else [])
    for path in paths:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return paths
