"""The ``closure-nlp`` command line: :mod:`.main` parses and dispatches, one module per
command (``*_command``) builds its answer from the public API."""

from closure_nlp.cli import startup  # noqa: F401 - first: a Ctrl-C while the CLI loads is one line
