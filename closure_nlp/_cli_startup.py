"""Imported first by :mod:`closure_nlp.cli`: a Ctrl-C while its heavy modules load is one line
(:mod:`closure_nlp._quiet_interrupt`; ``cli`` restores the hook after its imports)."""

from ._quiet_interrupt import install

install()
