"""Live runs and a safe command channel: the seed's ``run_command``, without arbitrary code.

A diagram runs at real-time rate until stopped (``python diagrams/talos_appli.py --live`` or
``python -m sotdrake.live diagrams/<script>.py``) and a user steers it from another terminal with
``sotdrake-shell "sot.push('taskrh')"``. One concept a module:

* :mod:`.grammar`: a command line → :class:`~.grammar.Command` (``ast`` on a whitelist, no eval);
* :mod:`.vocabulary`: the allow-list of entities and methods over the public API;
* :mod:`.framing` and :mod:`.connection`: the wire format, the token and its 0600 file;
* :mod:`.server`: the command server (127.0.0.1, bounded queue) applying commands at tick boundaries;
* :mod:`.runner`: the live loop (real time, Ctrl-C, the run's files);
* :mod:`.shell`: the client, ``sotdrake-shell`` (a command it stops waiting for is withdrawn: never
  applied later).
"""

from .connection import Connection, default_path, read_connection
from .grammar import Command, EntityRef, parse_command
from .runner import LiveRun, add_live_arguments, live_meshcat, run_live
from .server import CommandServer
from .shell import NotApplied
from .vocabulary import Vocabulary

__all__ = [
    "Command",
    "CommandServer",
    "Connection",
    "EntityRef",
    "LiveRun",
    "NotApplied",
    "Vocabulary",
    "add_live_arguments",
    "default_path",
    "live_meshcat",
    "parse_command",
    "read_connection",
    "run_live",
]
