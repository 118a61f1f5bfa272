"""rho against the Ferrari-Canny epsilons of Dex-Net's and GraspIt!'s conventions
(``benchmarks/ferrari_canny.py``: qhull over edge wrenches built from points and normals, no
code shared with the package): the worked example of docs/interoperability.md prints what the
page shows, and the inequalities the page states hold on it and on seeded sets."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from benchmarks.ferrari_canny import edge_wrenches, epsilon_l1, epsilon_linf
from closure_nlp import ContactSet, rho
from closure_nlp.contact.random_sets import random_contact_set

PAGE = Path(__file__).resolve().parents[1] / "docs" / "interoperability.md"
QHULL = 1e-9  # qhull's facet offsets against the certified bracket, relative to the wrenches


def worked_example() -> tuple[str, str]:
    blocks = re.findall(r"^```(\w*)\n(.*?)^```\s*$", PAGE.read_text(), flags=re.S | re.M)
    for (lang, code), (next_lang, out) in zip(blocks, blocks[1:]):
        if lang == "python" and next_lang == "text":
            return code, out
    raise AssertionError("docs/interoperability.md: no python block followed by its output")


def test_worked_example_prints_what_the_page_shows():
    code, shown = worked_example()
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, str(PAGE), "exec"), {})
    assert printed.getvalue().split() == shown.split()


def _sets_arrays(cs: ContactSet):
    P = np.array([c.position for c in cs.contacts])
    N = np.array([c.inward_normal for c in cs.contacts])
    return P, N


def _inner_floor(P, N, mu, edges, **kw) -> float:
    """-hi of rho with the pyramid's inscribed cones, where those are force closure."""
    hi = rho(ContactSet.from_arrays(P, N, mu=mu * np.cos(np.pi / edges), **kw)).bounds[1]
    return -hi if hi < 0 else -np.inf


@pytest.mark.parametrize("name", ["Dex-Net", "GraspIt!"])
def test_worked_example_sandwich(name):
    """On the page's box: L-inf (4 edges) between -rho at mu cos(pi/4) and -rho at mu; L1 (8
    edges) between a quarter of -rho at mu cos(pi/8) and -rho."""
    points = np.array([[0.05, 0.01, 0.005], [-0.05, -0.01, 0.005],
                       [0.01, 0.03, -0.01], [-0.01, -0.03, -0.01]])  # fmt: skip
    inward = -np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0]])
    corner = np.array([0.05, 0.03, 0.02])
    s = 1 / np.median(corner) if name == "Dex-Net" else 1 / np.linalg.norm(corner)
    kw = {"torque_scale": s, "reference_point": np.zeros(3)}
    lo, hi = rho(ContactSet.from_arrays(points, inward, mu=0.5, **kw)).bounds
    assert hi < 0
    W8 = edge_wrenches(points, inward, 0.5, 8, s, kw["reference_point"])
    W4 = edge_wrenches(points, inward, 0.5, 4, s, kw["reference_point"])
    tol = QHULL * np.abs(W8).max()
    linf, l1 = epsilon_linf(W4), epsilon_l1(W8)
    assert _inner_floor(points, inward, 0.5, 4, **kw) - tol <= linf <= -lo + tol
    assert _inner_floor(points, inward, 0.5, 8, **kw) / 4 - tol <= l1 <= linf + tol
    assert l1 > 0


def test_frictionless_linf_epsilon_is_minus_rho():
    """A frictionless cone is one ray: the L-inf set is W_c^M itself, so on closure sets its
    epsilon lies in the certified [-hi, -lo]; on the others it is 0 (the origin, every force
    zero, lies on the boundary) and rho > 0."""
    closure = 0
    for seed in range(60):
        cs = random_contact_set(np.random.default_rng(seed), ["fpc"] * 7)
        P, N = _sets_arrays(cs)
        W = edge_wrenches(P, N, 0.0, 1, cs.torque_scale, cs.reference_point)
        eps = epsilon_linf(W)
        result = rho(cs)
        tol = QHULL * np.abs(W).max()
        if result.force_closure:
            closure += 1
            assert -result.bounds[1] - tol <= eps <= -result.bounds[0] + tol
        else:
            assert abs(eps) <= tol and result.bounds[1] >= 0
    assert closure >= 2


def test_l1_epsilon_sandwich_on_random_pcwf_sets():
    """Dex-Net's L1 of 8 edges on seeded 4-PCwF sets (mu 0.5, torques about the origin): on
    closure sets at most -rho and at least a quarter of -rho with the inscribed cones (where
    those are closure); never closure where rho says not."""
    closure = 0
    for seed in range(30):
        cs = random_contact_set(np.random.default_rng(seed), ["pcwf"] * 4, mu=0.5)
        P, N = _sets_arrays(cs)
        W = edge_wrenches(P, N, 0.5, 8)
        l1 = epsilon_l1(W)
        result = rho(cs)
        tol = QHULL * np.abs(W).max()
        if not result.force_closure:
            assert l1 <= tol, seed
            continue
        closure += 1
        assert _inner_floor(P, N, 0.5, 8) / 4 - tol <= l1 <= -result.bounds[0] + tol, seed
    assert closure >= 3


def test_bench_dexnet_reports_every_check_as_json(capsys):
    from benchmarks import bench

    assert bench.main(["dexnet", "--cases", "12", "--sets", "12", "--linf-sets", "1"]) == 0
    report = json.loads(capsys.readouterr().out)
    fpc, pcwf = report["7 FPC"], report["4 PCwF"]
    assert fpc["sets"] == 12 and pcwf["sets"] == 12
    assert fpc["linf_outside_certified_max"] == 0.0
    assert pcwf["l1_outside_sandwich_max"] == 0.0 and pcwf["l1_closure_not_ours"] == 0
    assert pcwf["median_ms"]["rho"] > 0 and pcwf["median_ms"]["l1_qhull"] > 0
