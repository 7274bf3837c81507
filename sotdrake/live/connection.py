"""Where a live run listens, and the secret that lets a client in: the connection file.

The server picks a random 256-bit token and writes ``{"host", "port", "token", "pid", "meshcat"}``
as JSON to a file only its user can read (created with mode 0600, never widened):
``<out>/live.json`` and, for clients that are not told where to look, the per-user default
:func:`default_path` (``$XDG_RUNTIME_DIR/sotdrake/live.json``, else
``~/.cache/sotdrake/live.json``, in a directory of mode 0700). A client reads the file and sends
the token as its first line; another user cannot read it, so cannot drive the run.
"""

from __future__ import annotations

import json
import os
import secrets
import stat
from dataclasses import asdict, dataclass
from pathlib import Path

from ..exceptions import InvalidInput

HOST = "127.0.0.1"


@dataclass(frozen=True)
class Connection:
    host: str
    port: int
    token: str
    pid: int
    meshcat: str | None = None


def new_token() -> str:
    return secrets.token_hex(32)


def default_path() -> Path:
    """The per-user connection file of the latest live run."""
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    base = Path(runtime) if runtime and Path(runtime).is_dir() else Path.home() / ".cache"
    return base / "sotdrake" / "live.json"


def write_connection(path: Path, connection: Connection) -> Path:
    """Write ``connection`` to ``path``, readable by this user only (mode 0600)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    temporary = path.with_name(f".{path.name}.{os.getpid()}")
    if temporary.exists():
        temporary.unlink()
    fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as file:
        json.dump(asdict(connection), file)
    os.replace(temporary, path)  # atomic: a client never reads half a file
    return path


def read_connection(path: Path) -> Connection:
    """The connection in ``path``; refuses a file that others may read or write."""
    path = Path(path)
    if not path.is_file():
        raise InvalidInput(f"no live run: {path} does not exist (start one with --live, or give --connection)")
    mode = path.stat().st_mode
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise InvalidInput(f"{path}: mode {stat.filemode(mode)}, expected -rw------- (only the owner may read it)")
    try:
        data = json.loads(path.read_text())
        connection = Connection(str(data["host"]), int(data["port"]), str(data["token"]), int(data["pid"]), data.get("meshcat"))
    except (ValueError, KeyError, TypeError) as error:  # (not JSON, a field missing or of another kind)
        raise InvalidInput(f"{path}: not a live run's connection file ({type(error).__name__}: {error})") from None
    if not 0 < connection.port < 65536:
        raise InvalidInput(f"{path}: not a live run's connection file (port {connection.port})")
    return connection


def remove_connection(path: Path, connection: Connection) -> None:
    """Remove ``path`` if it still describes ``connection`` (a newer run may have replaced it)."""
    try:
        if read_connection(path).token == connection.token:
            Path(path).unlink()
    except (InvalidInput, OSError, ValueError, KeyError):
        pass
