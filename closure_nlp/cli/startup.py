"""Imported first by :mod:`closure_nlp.cli.main`: a Ctrl-C while its heavy modules load is one line
(:mod:`closure_nlp.base.quiet_interrupt`; ``cli`` restores the hook after its imports)."""

from closure_nlp.base.quiet_interrupt import install

install()
