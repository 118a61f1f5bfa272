"""Terminal and JSON output of the commands, and the errors they raise."""

from __future__ import annotations

import contextlib
import json
import sys
import time

from closure_nlp.base.errors import MethodError
from closure_nlp.base.files import (
    escape,
    non_finite_key,
)
from closure_nlp.base.formatting import bracket
from closure_nlp.base.progress import progress_line


class InputError(ValueError):
    """Bad input tied to a file: the message names the file, then the field."""

    def __init__(self, source: str, message: str):
        super().__init__(f"{source}: {message}")


class OutputFault(RuntimeError):
    """The system refused the output (a full disk, a closed or full stdout, an encoding that
    cannot show a name): exit 1, like any fault of the environment, never a bug."""

    def __init__(self, source: str, message: str):
        super().__init__(f"{source}: {message}")


def print_line(line: str) -> None:
    """``line`` on stdout; a failure of stdout is an :class:`OutputFault` (exit 1)."""
    try:
        sys.stdout.write(line + "\n")
    except UnicodeEncodeError as exc:
        shown = exc.object[max(exc.start - 20, 0) : exc.end + 20]
        raise OutputFault(
            "stdout",
            f"cannot print {shown!r} in the output's encoding {exc.encoding}: set "
            "PYTHONIOENCODING=utf-8 (or use --json)",
        ) from None
    except BrokenPipeError:
        raise
    except OSError as exc:  # a full device (/dev/full), an I/O error
        raise OutputFault("stdout", f"cannot write: {exc.strerror or exc}") from None


def flush_stdout() -> None:
    """Push out what is buffered: a full device fails here, after the last line."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise OutputFault("stdout", f"cannot write: {exc.strerror or exc}") from None


def shown(name) -> str:
    """A name (a path) as messages show it: control characters escaped, one line."""
    return escape(str(name))


@contextlib.contextmanager
def reading(source: str):
    """Checks of a command's inputs, before any work: ``ValueError``/``TypeError`` raised in
    them is bad input of ``source`` (exit 2); the same raised later is an internal error."""
    try:
        yield
    except InputError:
        raise
    except (ValueError, TypeError) as exc:
        raise InputError(source, str(exc)) from None


def check_finite(payload: dict, source: str) -> None:
    """Every number printed or written is finite: a NaN is the method's failure, not an answer."""
    key = non_finite_key(payload)
    if key is not None:
        raise MethodError(f"{source}: the method produced a non-finite {key}; nothing reported")


def emit(args, payload: dict, text: str) -> None:
    scale = getattr(args, "scale", None)
    if scale is not None:  # a model command: the torque scale, mu_s and point it used
        payload = {**payload, **scale.to_dict()}
        text = f"{shown(args.model)}: {scale.text(getattr(args, 'soft_fingers', True))}\n{text}"
    check_finite(payload, str(payload.get("file", getattr(args, "model", ""))))
    print_line(json.dumps(payload, allow_nan=False) if args.json else text)


def load_each(paths, loader):
    """Load and validate every input before any work, so bad input prints no partial output."""
    loaded = []
    for path in paths:
        try:
            loaded.append((path, loader(path)))
        except (ValueError, TypeError) as exc:
            raise InputError(path, str(exc)) from None
    return loaded


def whole_cost(result, t0: float) -> dict:
    """``seconds``: the whole cost of an answer since ``t0`` (search and certificate), with its
    parts under ``timing``: the search as the result timed it, the rest (certificate, robustness)
    under ``certificate``."""
    whole = time.perf_counter() - t0
    search = result.timing[0] if result.timing is not None else result.stats.seconds
    return {"seconds": whole, "timing": {"search": search, "certificate": max(whole - search, 0.0)}}


def verdict_text(result, positive: bool, yes="force closure", no="not force closure") -> str:
    """The certified verdict in words; a bracket that reaches zero is marginal, never closure."""
    if getattr(result, "marginal", False):
        return "marginal: within numerical accuracy of no interior"
    robust = getattr(result, "robust", None)
    if positive and robust is not None:
        shift = f"the support function may move {result.shift:.3g}"
        if robust:
            return f"{yes}, robust within the model's tolerance ({shift})"
        return f"{yes} by the file, NOT robust within the model's tolerance ({shift})"
    return yes if positive else no


def bounds_text(result, name: str) -> str:
    """``; certified lo <= name <= hi`` (one digit more than the value, numbers.bracket), and
    the width when the bracket did not converge."""
    if getattr(result, "bounds", None) is None:
        return ""
    lo, hi = result.bounds
    text = "; certified {} <= {name} <= {}".format(*bracket(result.bounds), name=name)
    if not result.converged:
        text += f" (not converged: width {hi - lo:.2g})"
    return text


def joined_ids(ids) -> str:
    return ",".join(str(i) for i in ids)


def progress_bar(args, starts: int | None = None):
    """``(callback, close)``: a progress line on stderr, only on a terminal and without
    ``--quiet``; ``starts`` (placement starts) gives an ETA over the starts."""
    return progress_line(args.quiet, {"placement start": starts} if starts else None)
