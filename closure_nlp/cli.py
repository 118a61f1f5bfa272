"""The ``closure-nlp`` command line: a thin layer over the API (INTERFACE.md).

Each command is a ``_cmd_<name>(args)`` function that returns one JSON-able dict per input and a
human-readable line for it. Bad input raises ``ValueError``/``TypeError`` (exit 2); a failure of
the method itself raises :class:`MethodError` (exit 1). Both become one ``error:`` line on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys

from .contacts import load_contact_set
from .errors import MethodError
from .quality import rho


class InputError(ValueError):
    """Bad input tied to a file: the message names the file, then the field."""

    def __init__(self, source: str, message: str):
        super().__init__(f"{source}: {message}")


def _emit(args, payload: dict, text: str) -> None:
    if args.json:
        print(json.dumps(payload, allow_nan=False))
    else:
        print(text)


# --- commands -------------------------------------------------------------------------------


def _load_each(paths, loader):
    """Load and validate every input before any work, so bad input prints no partial output."""
    loaded = []
    for path in paths:
        try:
            loaded.append((path, loader(path)))
        except (ValueError, TypeError) as exc:
            raise InputError(path, str(exc)) from None
    return loaded


def _add_rho(sub, common) -> None:
    p = sub.add_parser("rho", parents=[common], help="rho(0, W_c^M) of contact-set files")
    p.add_argument("files", nargs="+", metavar="FILE", help="*.contacts.json")
    p.set_defaults(run=_cmd_rho)


def _cmd_rho(args) -> None:
    for path, contact_set in _load_each(args.files, load_contact_set):
        result = rho(contact_set)
        payload = {"file": path, **result.to_dict()}
        verdict = "force closure" if result.force_closure else "not force closure"
        direction = " ".join(f"{x:+.4f}" for x in result.direction)
        _emit(
            args,
            payload,
            f"{path}: rho = {result.rho:.9g} ({verdict}); weakest direction u* = [{direction}]",
        )


# --- parser ---------------------------------------------------------------------------------


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad flags the INTERFACE.md way: one ``error:`` line, exit 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="closure-nlp", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    common = _Parser(add_help=False)
    common.add_argument("--json", action="store_true", help="print only JSON on stdout")
    common.add_argument("--quiet", action="store_true", help="no progress output on stderr")
    for add in COMMANDS:
        add(sub, common)
    return parser


# Functions (subparsers, common_parent) -> None, each registering one command.
COMMANDS: list = [_add_rho]


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        args.run(args)
    except (ValueError, TypeError) as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    except MethodError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
