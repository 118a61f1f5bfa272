"""The ``closure-nlp`` command line: a thin layer over the API (INTERFACE.md).

Each command is a ``_cmd_<name>(args)`` function that returns one JSON-able dict per input and a
human-readable line for it. Bad input raises ``ValueError``/``TypeError`` (exit 2); a failure of
the method itself raises :class:`MethodError` (exit 1). Both become one ``error:`` line on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys

from .errors import MethodError


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


COMMANDS: list = []  # functions (subparsers, common_parent) -> None, each registering one command


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
