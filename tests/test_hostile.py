"""The hostile-input corpus (tests/hostile.py): every input ends in a clear error or a finite
answer; none in a traceback, a NaN or a hang."""

import pytest

from .hostile import as_expected, corpus, run_case

CASES = corpus()


def _marked(case):
    """A case waiting on a change outside the library fails until it is made, then must pass."""
    if case.pending is None:
        return case
    return pytest.param(case, marks=pytest.mark.xfail(reason=case.pending, strict=True))


@pytest.mark.parametrize("case", [_marked(c) for c in CASES], ids=[c.id for c in CASES])
def test_hostile_input(case, tmp_path):
    outcome = run_case(case, tmp_path / "case")
    assert as_expected(case, outcome), (case.expect, case.code, case.message, outcome.detail)
