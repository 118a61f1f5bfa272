"""The hostile-input corpus (tests/hostile.py): every input ends in a clear error or a finite
answer; none in a traceback, a NaN or a hang."""

import pytest

from .hostile import as_expected, corpus, run_case

CASES = corpus()


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_input(case, tmp_path):
    outcome = run_case(case, tmp_path / "case")
    assert as_expected(case, outcome), (case.expect, case.code, case.message, outcome.detail)
