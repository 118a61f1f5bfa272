"""Progress of long runs: the events the API reports and the bar the CLI draws from them.

Every long step calls ``progress(stage, step, value)`` when it finishes: ``stage`` is one of
:data:`STAGES`, ``step`` counts within the stage, ``value`` is the stage's current best rho_hat or
rho. The callback must not raise. The CLI draws these events as one line on stderr, only when
stderr is a terminal and ``--quiet`` is not given, with an ETA where the number of steps is
known (the placement's first starts).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

# progress(stage, step, value)
Progress = Callable[[str, int, float], None]

STAGES = (
    "heuristic",  # an element added (value: rho_hat of the partial set)
    "iterative",  # a position tried (value: the best rho_hat)
    "placement round",  # an exchange round (value: the best rho of this start)
    "placement start",  # a start finished (value: the best rho over the starts)
    "neighbour move",  # a contact moved into a neighbouring element (value: rho after)
    "capacity bound",  # a cell of the ceiling's branch and bound (value: the ceiling on -rho)
    "certification",  # 0: the final rho's wide search and bounds begin; 1: done (value: rho)
    "alternative",  # a further element set placed after a failed placement (value: its rho)
    "seed",  # a seed of a plan of several finished (value: the best rho over the seeds so far)
)


class ProgressLine:
    """A tqdm line on stderr fed by progress events; ``totals`` gives known step counts."""

    def __init__(self, totals: dict[str, int] | None = None, file=None):
        from tqdm import tqdm

        self.totals = dict(totals or {})
        self.bar = tqdm(total=None, unit="step", file=file or sys.stderr, leave=False)
        self.started: dict[str, float] = {}

    def __call__(self, stage: str, step: int, value: float) -> None:
        now = time.perf_counter()
        self.started.setdefault(stage, now)
        text = f"{stage} {step}"
        total = self.totals.get(stage)
        if total and 0 < step < total:
            eta = (now - self.started[stage]) / step * (total - step)
            text = f"{stage} {step}/{total} (ETA {eta:.0f} s)"
        name = "rho_hat" if stage in ("heuristic", "iterative") else "rho"
        self.bar.set_description(f"{text} {name}={value:.5g}", refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        self.bar.close()


def progress_line(quiet: bool, totals: dict[str, int] | None = None):
    """``(callback, close)``: a :class:`ProgressLine` on a terminal, else nothing."""
    if quiet or not sys.stderr.isatty():
        return None, lambda: None
    line = ProgressLine(totals)
    return line, line.close


__all__ = ["Progress", "ProgressLine", "STAGES", "progress_line"]
