"""The host's share of this machine's cores during a run: a virtual machine's *steal* time.

On a shared host the hypervisor may run other machines on our cores; the guest's clocks, CPU time
included, keep counting meanwhile, so every timing of a run with steal is inflated. ``/proc/stat``
(Linux) counts it per core in jiffies; :class:`Steal` reads it before and after a run.
"""

from __future__ import annotations

from pathlib import Path

_STAT = Path("/proc/stat")


def _cpu_line() -> list[int] | None:
    """The aggregate ``cpu`` line's counters (user, nice, system, idle, iowait, irq, softirq, steal,
    …), or None where there is no ``/proc/stat``."""
    try:
        fields = _STAT.read_text().split("\n", 1)[0].split()
    except OSError:
        return None
    return [int(x) for x in fields[1:]] if fields and fields[0] == "cpu" else None


class Steal:
    """``Steal()`` at the start of a run, ``.fraction()`` at its end: the steal time over the run as a
    fraction of all the cores' time (None where it cannot be read)."""

    def __init__(self) -> None:
        self.start = _cpu_line()

    def fraction(self) -> float | None:
        end = _cpu_line()
        if self.start is None or end is None or len(end) < 8:
            return None
        total = sum(end) - sum(self.start)
        return (end[7] - self.start[7]) / total if total > 0 else None

    @staticmethod
    def describe(fraction: float | None) -> str:
        return "host steal unknown" if fraction is None else f"host steal {100 * fraction:.1f} % of the cores' time"
