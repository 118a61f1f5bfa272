"""The ``closure-nlp`` command line: a thin layer over the API (docs/formats.md).

Each command is a ``cmd_<name>(args)`` function in a module of its own (``<name>_command``),
which prints one JSON-able dict per input and a human-readable line for it. Exit status
(README, "Exit status"): 2 for bad input, which the commands check before any work and raise
as :class:`InputError` naming the file and the field; 1 when the method cannot answer
(:class:`MethodError`, out of memory, a non-finite result) or the system refuses
(:class:`OutputFault`, any ``OSError``: a full disk, stdout full or closed); 3 for an internal
error (a bug: any other exception once the work has started, printed as ``internal error:``,
never as bad input); 130 for Ctrl-C. No traceback reaches the user (``CLOSURE_NLP_TRACEBACK=1``
prints it, for bug reports).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys

from closure_nlp.base import quiet_interrupt as _quiet_interrupt
from closure_nlp.base.errors import MethodError
from closure_nlp.base.files import escape
from closure_nlp.base.interrupts import interruptible
from closure_nlp.cli.arguments import bounded_float, float_value, int_value
from closure_nlp.cli.characterize_command import add_characterize
from closure_nlp.cli.eligibility_command import add_eligibility, cmd_eligibility
from closure_nlp.cli.output import InputError, OutputFault, flush_stdout
from closure_nlp.cli.place_command import add_place, cmd_place
from closure_nlp.cli.plan_command import add_plan, cmd_plan
from closure_nlp.cli.rho_command import add_rho, cmd_rho
from closure_nlp.cli.select_command import add_select, cmd_select
from closure_nlp.cli.show_command import add_show
from closure_nlp.cli.study_command import add_study, cmd_study
from closure_nlp.contact.contact_set import ContactType

_quiet_interrupt.restore()


int_value.__name__ = "integer"  # argparse says "invalid integer value: ..."
float_value.__name__ = "number"


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad flags the docs/formats.md way: one ``error:`` line, exit 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="closure-nlp", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    common = _Parser(add_help=False)
    common.add_argument("--json", action="store_true", help="print only JSON on stdout")
    common.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    common.add_argument(
        "--position-tolerance",
        type=bounded_float(0.0, float("inf"), "the position tolerance"),
        metavar="LENGTH",
        help="how far the real part's contact points may lie from the file's (model units; "
        "default: the file's tolerance, else 0)",
    )
    common.add_argument(
        "--normal-tolerance",
        type=bounded_float(0.0, 90.0, "the normal tolerance"),
        metavar="DEGREES",
        help="how far the real part's normals may lie from the file's (default: the file's "
        "tolerance, else 0); results say whether they are robust within both",
    )
    for add in COMMANDS:
        add(sub, common)
    return parser


# Functions (subparsers, common_parent) -> None, each registering one command.
COMMANDS = (
    add_rho,
    add_eligibility,
    add_select,
    add_place,
    add_plan,
    add_characterize,
    add_show,
    add_study,
)


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the exit status (module docstring) and never raises."""
    try:
        if sys.stdout is None:  # started with stdout closed: an answer would be lost
            raise OutputFault("stdout", "closed: nothing could be printed")
        args = build_parser().parse_args(argv)
        with _one_line_warnings(), interruptible():
            _compile_kernels(args)
            args.run(args)
        flush_stdout()  # a full device fails here: the answer is not out, exit 1
    except SystemExit as exc:  # argparse: --help (0) or a bad flag (2, its line already printed)
        return exc.code if isinstance(exc.code, int) else 2
    except KeyboardInterrupt:
        sys.stderr.write("interrupted: stopped by Ctrl-C; finished output is kept\n")
        return 130
    except InputError as exc:
        _error(exc)
        return 2
    except (MethodError, OutputFault) as exc:
        _error(exc)
        if isinstance(exc, OutputFault) and str(exc).startswith("stdout"):
            _drop_stdout()
        return 1
    except MemoryError:
        sys.stderr.write("error: out of memory: the input is too large for this machine\n")
        return 1
    except BrokenPipeError:  # stdout closed early (``| head``): nothing more to say
        _drop_stdout()
        return 1
    except OSError as exc:  # the system said no: a full disk, a lost scheduler
        text = exc.strerror or str(exc)
        _error(f"{exc.filename}: {text}" if exc.filename is not None else text)
        return 1
    except Exception as exc:  # a bug: said as one, never dressed as bad input
        if os.environ.get("CLOSURE_NLP_TRACEBACK"):
            import traceback

            traceback.print_exc()
        text = escape(" ".join(str(exc).split())[:300])
        sys.stderr.write(
            f"internal error: {type(exc).__name__}: {text} (a bug in closure_nlp, not in the "
            "input; CLOSURE_NLP_TRACEBACK=1 shows where)\n"
        )
        return 3
    return 0


def _error(exc) -> None:
    """The one ``error:`` line, control characters of names escaped."""
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(f"error: {escape(str(exc))}\n")


def _drop_stdout() -> None:
    """Point stdout at the null device: the interpreter's last flush must not fail again
    (it would print "Exception ignored" and change the exit status)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        fd = sys.stdout.fileno()
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, fd)
        os.close(null)


def _compile_kernels(args) -> None:
    """Before a command that computes rho: the compiled kernels, loaded from the disk cache, or
    compiled once, said on stderr (how long) like the progress lines: on a terminal, unless
    ``--quiet``."""
    if args.run not in (cmd_rho, cmd_eligibility, cmd_select, cmd_place, cmd_plan, cmd_study):
        return
    from closure_nlp.criterion.warm_up import warm_up

    shown = not args.quiet and sys.stderr.isatty()
    notify = (lambda text: sys.stderr.write(f"{text}\n")) if shown else None
    args.compile_seconds = warm_up(
        notify, rho_only=args.run is cmd_rho, capacity=_frictionless_placements(args)
    )


def _frictionless_placements(args) -> bool:
    """Whether the command may place contacts that are all frictionless (the zonotope's
    capacity then runs): a study's tasks may; plan and place unless their options give a
    contact friction (FPC, or a zero or unreadable ``--mu``, counts as maybe); the others
    place nothing."""
    if args.run is cmd_study:
        return True
    if args.run not in (cmd_plan, cmd_place):
        return False
    try:
        types = [ContactType.parse(p.strip(" \t")) for p in str(args.type).split(",")]
        mus = [float_value(p.strip(" \t")) for p in str(args.mu).split(",")]
    except ValueError:
        return True  # the command refuses the option later: nothing to save here
    return ContactType.FPC in types or not all(mu > 0 for mu in mus)


@contextlib.contextmanager
def _one_line_warnings():
    """Each warning is one ``warning:`` line on stderr (Python's format adds a source line)."""
    import warnings

    saved = warnings.showwarning
    seen = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = " ".join(str(message).split())
        if text not in seen:  # the same warning from two places is still one line
            seen.add(text)
            sys.stderr.write(f"warning: {escape(text)}\n")

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = saved


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
