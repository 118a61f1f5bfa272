"""A Ctrl-C while the command line is still importing its heavy modules (NumPy, CasADi, SciPy)
is one line, not a traceback: the package's ``__init__`` and :mod:`closure_nlp.cli.main` call
:func:`install` before their imports and :func:`restore` after them, so once imported the
package leaves ``sys.excepthook`` as it found it."""

from __future__ import annotations

import sys

_previous = []


def _hook(kind, value, traceback) -> None:
    if issubclass(kind, KeyboardInterrupt):
        sys.stderr.write("interrupted: stopped by Ctrl-C while starting\n")
        return
    (_previous[-1] if _previous else sys.__excepthook__)(kind, value, traceback)


def install() -> None:
    if sys.excepthook is not _hook:
        _previous.append(sys.excepthook)
        sys.excepthook = _hook


def restore() -> None:
    if sys.excepthook is _hook and _previous:
        sys.excepthook = _previous.pop()


install()  # on first import: the package's __init__ imports this module before anything else
