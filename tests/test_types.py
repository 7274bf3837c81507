"""The package passes ``mypy`` (the configuration in pyproject.toml: pydrake treated as untyped).

mypy is a dependency of the ``test`` extra, so this test never skips: mypy missing or crashing is a
failure too.
"""

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_mypy_passes():
    """One mypy run on the package (packages from pyproject.toml). The cache is mypy's usual
    ``.mypy_cache`` (git ignores it), shared with ``python -m mypy``: a second run checks only what
    changed."""
    result = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True)
    summary = result.stdout.strip().splitlines()[-1:] or [""]
    assert re.match(r"(Success: no issues found|Found \d+ errors?) in ", summary[0]), (
        f"mypy did not check the package (exit {result.returncode}):\n{result.stdout}{result.stderr}")
    errors = [line for line in result.stdout.splitlines() if ": error: " in line]
    assert not errors and result.returncode == 0, "mypy errors:\n" + "\n".join(errors)
