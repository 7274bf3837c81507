"""How a live run bears a burst of commands: commands per second, ticks missed, real time kept.

:func:`measure_burst` reads the run's ``status()``, waits ``idle`` seconds (the reference: the same
run without commands), then sends ``count`` commands at once on one connection (a thread sends,
the caller's thread reads the answers), reads ``status()`` again, and waits ``idle`` seconds more
(a second reference: on a shared machine the load of other jobs changes). Figures:

* ``commands_per_s``, ``accepted_per_s``: answered (and answered ``ok``) per wall second;
* ``ticks_missed``: how many more ticks the run is behind the wall clock after the burst than
  before it (0 when it kept up);
* ``realtime_kept_burst`` / ``realtime_kept_idle`` (before, after): ticks done over ticks due at
  the target rate during the burst / the idle windows (1: on time; below 1: falling behind; above
  1: catching up).
"""

from __future__ import annotations

import json
import threading
import time

from .shell import Client


def _status(client: Client) -> dict:
    answer = client.command("status()")
    if not answer["ok"]:
        raise RuntimeError(answer["error"])
    return json.loads(answer["answer"])


def measure_burst(client: Client, commands: list[str], count: int, rate: float, dt: float,
                  idle: float = 3.0) -> tuple[dict, list[dict]]:
    """Send ``count`` commands (cycling through ``commands``); returns the figures and the answers
    in sending order."""
    idle_status = _status(client)
    time.sleep(idle)
    first = _status(client)
    ids: list[int] = []

    def send() -> None:
        for k in range(count):
            ids.append(client.send_line(commands[k % len(commands)]))

    start = time.monotonic()
    sender = threading.Thread(target=send, name="burst-send")
    sender.start()
    answers: list[dict] = []
    while sender.is_alive() or len(answers) < count:
        if len(ids) > len(answers):
            answers.append(client.receive(ids[len(answers)]))
        else:
            time.sleep(0.001)
    sender.join()
    wall = time.monotonic() - start
    last = _status(client)
    time.sleep(idle)
    after = _status(client)

    def kept(a: dict, b: dict) -> float:
        return (b["ticks"] - a["ticks"]) / ((b["wall"] - a["wall"]) * rate / dt)

    accepted = sum(a["ok"] for a in answers)
    figures = {
        "commands": count,
        "accepted": accepted,
        "wall_s": round(wall, 3),
        "commands_per_s": round(count / wall),
        "accepted_per_s": round(accepted / wall),
        "ticks_due": round((last["wall"] - first["wall"]) * rate / dt),
        "ticks_missed": max(0, last["lag_ticks"] - first["lag_ticks"]),
        "realtime_kept_burst": round(kept(first, last), 4),
        "realtime_kept_idle": [round(kept(idle_status, first), 4), round(kept(last, after), 4)],
        "target_rate": rate,
    }
    return figures, answers
