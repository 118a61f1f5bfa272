"""Cross-solver agreement: IPOPT (quality) against cvxpy (crosscheck) and certified bounds."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from closure_nlp.base.tolerances import Tolerances
from closure_nlp.cli.main import main
from closure_nlp.contact.contact_set import Contact, ContactSet, ContactType, grasp_matrices
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import CertifiedBounds, CertifyOptions, certified_bounds
from closure_nlp.criterion.crosscheck import (
    ball_minimum,
    distance_cvxpy,
    force_closure_check,
    force_closure_cvxpy,
)
from closure_nlp.criterion.hull_distance import min_norm_point
from closure_nlp.criterion.sphere_branch_bound import BranchBoundOptions
from closure_nlp.criterion.support_minimum import SearchOptions, SupportMinimizer, rho, search_rho

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "box_7fpc.contacts.json"
TYPES = ["fpc", "pcwf", "sfcl", "sfce"]
KINDS = [*TYPES, "mixed"]
CERTIFY_TOL = 1e-6


def make(kind, m, seed):
    rng = np.random.default_rng(1000 * m + seed + 17 * len(kind))
    types = list(rng.choice(TYPES, m)) if kind == "mixed" else [kind] * m
    return random_contact_set(rng, types, mu=0.5, mu_s=0.3, tilt=0.25)


def one(kind, position=(0, 0, 0), normal=(0, 0, 1), **kw):
    return Contact(list(position), list(normal), kind, **kw)


def ring(kind, count, **kw):
    """``count`` contacts on the unit circle in the plane z = 0, pushing towards the centre."""
    angles = np.linspace(0, 2 * np.pi, count + 1)[:-1]
    return ContactSet(
        tuple(
            one(kind, (np.cos(a), np.sin(a), 0), (-np.cos(a), -np.sin(a), 0), **kw) for a in angles
        )
    )


# --- IPOPT against cvxpy on random sets ------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_verdict_and_distance_agree_with_ipopt(kind):
    verdicts = []
    for m in range(2, 8):
        for seed in (0, 1, 2):
            cs = make(kind, m, seed)
            ours = rho(cs)
            scale = max(1.0, abs(ours.rho))
            if abs(ours.rho) > 1e-6:  # both solvers are exact to ~1e-8 only at the boundary
                assert force_closure_cvxpy(cs) == ours.force_closure, (m, seed, ours.rho)
            verdicts.append(ours.force_closure)
            distance = distance_cvxpy(cs)
            if ours.force_closure:
                assert distance == 0.0
            else:
                assert distance == pytest.approx(ours.rho, abs=1e-6 * scale), (m, seed)
    if kind != "fpc":  # random FPC sets need 7 contacts and a lucky draw to hold
        assert any(verdicts) and not all(verdicts)


@pytest.mark.parametrize("kind", KINDS)
def test_ipopt_rho_within_certified_bounds(kind):
    closure = 0
    for m in (3, 5, 7):
        cs = make(kind, m, 0)
        ours = rho(cs)
        bounds = certified_bounds(cs, ours.direction)
        scale = max(1.0, abs(ours.rho))
        assert bounds.lo <= bounds.hi
        assert bounds.lo - CERTIFY_TOL * scale <= ours.rho <= bounds.hi + CERTIFY_TOL * scale
        assert bounds.converged, (m, bounds)
        assert bounds.gap <= CERTIFY_TOL * scale
        assert bounds.force_closure is ours.force_closure
        # lo is the support function at a unit direction, so it is never below IPOPT's answer
        assert bounds.lo >= ours.rho - 1e-12
        assert -slots_support(cs, bounds.direction) == pytest.approx(bounds.lo, abs=1e-12)
        closure += ours.force_closure
    if kind != "fpc":
        assert closure >= 1


def slots_support(cs, u):
    return float(WrenchSlots.from_contacts(cs).support(u)[0])


def test_bounds_without_hint_still_bracket_rho():
    cs = make("pcwf", 4, 0)
    ours = rho(cs)
    bounds = certified_bounds(cs)
    assert bounds.lo - 1e-9 <= ours.rho <= bounds.hi + 1e-9
    assert bounds.hi < 0 and bounds.force_closure is True


def test_bounds_stay_valid_when_the_budget_stops_them():
    # Two opposite soft fingers: the weakest directions form a circle (symmetry about the axis),
    # which the refinement cannot resolve in one step: wider, still valid, bounds.
    cs = ContactSet((one("sfce", (0, 0, 1), (0, 0, -1)), one("sfce", (0, 0, -1), (0, 0, 1))))
    ours = rho(cs)
    stopped = CertifyOptions(branch_bound=BranchBoundOptions(max_rounds=3))
    bounds = certified_bounds(cs, ours.direction, options=stopped)
    assert not bounds.converged and bounds.iterations == 3
    assert bounds.lo <= ours.rho + 1e-9 and ours.rho <= bounds.hi
    assert bounds.hi < 0 and bounds.force_closure is True


def test_non_closure_bounds_are_tight_and_positive():
    cs = make("pcwf", 3, 0)
    ours = rho(cs)
    assert not ours.force_closure and ours.rho > 0.1
    lo, hi = certified_bounds(cs, ours.direction)
    assert 0 < lo <= hi <= lo + 1e-6
    assert lo - 1e-6 <= ours.rho <= hi + 1e-6


# --- degenerate and borderline sets ----------------------------------------------------------

DEGENERATE = {
    # name: (contact set, force closure, exact rho or None)
    "two opposite pcwf": (
        ContactSet((one("pcwf", (0, 0, 1), (0, 0, -1)), one("pcwf", (0, 0, -1), (0, 0, 1)))),
        False,
        0.0,
    ),
    "two opposite fpc": (
        ContactSet((one("fpc", (0, 0, 1), (0, 0, -1)), one("fpc", (0, 0, -1), (0, 0, 1)))),
        False,
        0.0,
    ),
    "single fpc": (ContactSet((one("fpc", f_max=2.5),)), False, 2.5),
    "four fpc on one face": (
        ContactSet(tuple(one("fpc", (x, y, 0)) for x, y in [(0, 0), (1, 0), (0, 1), (1, 1)])),
        False,
        1.0,
    ),
    "three fpc coplanar ring": (ring("fpc", 3), False, 0.0),
    "three pcwf coplanar ring": (ring("pcwf", 3, mu=0.5), True, None),
    "two opposite sfcl": (
        ContactSet((one("sfcl", (0, 0, 1), (0, 0, -1)), one("sfcl", (0, 0, -1), (0, 0, 1)))),
        True,
        None,
    ),
}


@pytest.mark.parametrize("name", list(DEGENERATE))
def test_degenerate_sets_get_the_right_verdict(name):
    cs, closure, exact = DEGENERATE[name]
    ours = rho(cs)
    assert ours.force_closure is closure
    assert force_closure_cvxpy(cs) is closure
    bounds = certified_bounds(cs, ours.direction)
    assert bounds.force_closure is closure
    tol = CERTIFY_TOL * max(1.0, abs(ours.rho))  # IPOPT is ~1e-6 off at some cone apexes
    assert bounds.lo - tol <= ours.rho <= bounds.hi + tol
    if exact is not None:
        assert ours.rho == pytest.approx(exact, abs=1e-8)
        assert bounds.lo == pytest.approx(exact, abs=1e-8)
        assert bounds.hi == pytest.approx(exact, abs=1e-8)
        assert distance_cvxpy(cs) == pytest.approx(exact, abs=1e-8)


def test_rank_deficient_grasp_is_never_closure_even_with_a_margin():
    # Two point contacts cannot resist the torque about the line through them: rank 5.
    # The cone program alone would find interior forces with zero resultant.
    cs = DEGENERATE["two opposite pcwf"][0]
    check = force_closure_check(cs)
    assert check.rank == 5 and not check.force_closure and not check


def test_zero_friction_acts_as_frictionless():
    pcwf = ring("pcwf", 3, mu=0.0)
    fpc = ring("fpc", 3)
    # radial pushes in one plane: forces in that plane, no torque
    assert force_closure_check(pcwf).rank == force_closure_check(fpc).rank == 2
    assert force_closure_check(ring("pcwf", 3, mu=0.5)).rank == 6
    assert not force_closure_cvxpy(pcwf)


# --- slots with several rows (element vertices) ----------------------------------------------


def element_slots(kind, seed):
    """Three 'facets' (four vertex rows each) around a box and one point contact."""
    rng = np.random.default_rng(seed)
    slots = []
    for normal, centre in [
        ((0, 0, 1), (0, 0, -1)),
        ((0, 0, -1), (0.2, 0, 1)),
        ((1, 0, 0), (-1, 0.1, 0)),
        ((-1, 0, 0), (1, 0, 0.1)),
    ]:
        n = np.array(normal, float)
        frame = np.linalg.svd(n[None, :])[2][1:]  # two unit tangents
        offsets = 0.3 * rng.uniform(-1, 1, (4, 2)) @ frame
        G = grasp_matrices(np.array(centre) + offsets, n)
        slots.append((G, ContactType.parse(kind), 0.4, 0.2, 1.0))
    return WrenchSlots.build(slots)


@pytest.mark.parametrize(
    "kind,seed",
    [(kind, seed) for kind in ("fpc", "pcwf", "sfcl", "sfce") for seed in (0, 1)],
)
def test_multi_row_slots_agree(kind, seed):
    slots = element_slots(kind, seed)
    found = SupportMinimizer()(slots)
    value = found.value  # min over the sphere of p: -rho
    if abs(value) > 1e-6:
        assert force_closure_cvxpy(slots) == (value > 0)
    if value < -1e-6:
        assert distance_cvxpy(slots) == pytest.approx(-value, abs=1e-6)
    lo, hi = certified_bounds(slots, found.direction)
    assert -value <= hi + 1e-9  # any unit direction's p bounds min p from above
    assert lo - 1e-6 * max(1.0, abs(value)) <= -value  # ... and IPOPT's must be the global one


def test_plain_descent_alone_misses_what_the_smoothed_one_finds():
    # The element slots where the descent on p alone, with 3 IPOPT starts 0.2 apart (the search
    # before the smoothed descent), ranked the global basin's start too low: the minimum was
    # 7.5e-3 too high (rho_hat too negative).
    slots = element_slots("pcwf", 1)
    plain = SupportMinimizer(
        Tolerances(distinct_start=0.2), SearchOptions(smoothing=(), element_ipopt_starts=3)
    )(slots)
    ours = SupportMinimizer()(slots)
    lo, _ = certified_bounds(slots, ours.direction)
    assert plain.value > -lo + 1e-3  # the trap is real: certified lower p exists
    assert ours.value <= -lo + 1e-6 * max(1.0, abs(lo))


def test_every_vertex_row_is_a_contact_of_the_cone():
    # Four FPC 'facets' of four vertices: sixteen normal wrenches span rank 5 (no force along
    # y), the four first vertices alone only rank 4. Neither holds.
    slots = element_slots("fpc", 0)
    first = WrenchSlots.build(
        [(slots.G[s : s + 1], ContactType.FPC, 0.4, 0.2, 1.0) for s in slots.starts]
    )
    assert force_closure_check(slots).rank == 5
    assert force_closure_check(first).rank == 4
    assert not force_closure_cvxpy(slots) and not force_closure_cvxpy(first)


# --- results, validation ---------------------------------------------------------------------


def test_ball_minimum_reports_the_support_function():
    cs = make("sfce", 3, 0)
    found = ball_minimum(cs)
    assert found.distance > 0
    assert np.linalg.norm(found.direction) == pytest.approx(1.0)
    assert found.value == pytest.approx(slots_support(cs, found.direction), abs=1e-15)
    assert found.distance == -found.value


def test_min_norm_point_is_in_the_hull():
    P = np.array([[1.0, 1, 0, 0, 0, 0], [1.0, -1, 0, 0, 0, 0], [3.0, 0, 0, 0, 0, 0]])
    x, weights = min_norm_point(P)
    np.testing.assert_allclose(x, [1, 0, 0, 0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(weights, [0.5, 0.5, 0.0], atol=1e-15)


@pytest.mark.parametrize("seed", range(6))
def test_min_norm_point_is_optimal_on_nearly_degenerate_clouds(seed):
    """Wolfe's point x is optimal when every point has P_j . x >= |x|^2 (the hyperplane through
    x normal to it separates the hull from the origin): checked on clouds whose points nearly
    repeat, where roundoff in the minor cycle once made it drop the improving point for good."""
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(8, 6)) + [3.0, 0, 0, 0, 0, 0]
    P = np.vstack([base, base + 1e-9 * rng.normal(size=base.shape), rng.normal(size=(40, 6)) + 4])
    x, weights = min_norm_point(P)
    assert np.all(weights >= 0) and weights.sum() == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(weights @ P, x, atol=1e-14)
    assert (P @ x).min() >= (x @ x) * (1 - 1e-12)


def test_nearest_point_bracket_of_a_lamp_element_set_closes():
    """Four lamp facets whose rho_hat > 0: the bracket stalled 2.1e-6 wide before the line-search
    fallback of Wolfe's minor cycle."""
    from benchmarks.bench import paper_eligibility

    slots = paper_eligibility("lamp").slots([28, 34, 55, 41])
    bounds = certified_bounds(slots, SupportMinimizer()(slots).direction)
    assert bounds.lo > 0 and bounds.converged, bounds


def test_certified_bounds_unpack_and_validate():
    cs = make("fpc", 3, 0)
    bounds = certified_bounds(cs)
    assert isinstance(bounds, CertifiedBounds)
    lo, hi = bounds
    assert (lo, hi) == (bounds.lo, bounds.hi)
    with pytest.raises(ValueError, match="tol"):
        certified_bounds(cs, tol=0)
    with pytest.raises(ValueError, match="direction"):
        certified_bounds(cs, [1.0, 0, 0])
    with pytest.raises(TypeError, match="slots"):
        certified_bounds([1, 2, 3])
    with pytest.raises(TypeError, match="slots"):
        force_closure_cvxpy("box")
    with pytest.raises(ValueError, match="max_iter"):
        CertifyOptions(max_iter=0)
    with pytest.raises(ValueError, match="fw_steps"):
        BranchBoundOptions(fw_steps=0)
    with pytest.raises(TypeError, match="branch_bound"):
        CertifyOptions(branch_bound=3)


def test_rho_always_carries_bounds_and_certify_changes_nothing():
    cs = make("pcwf", 4, 0)
    certified = rho(cs)
    lo, hi = certified.bounds
    assert lo <= certified.rho <= hi
    out = certified.to_dict()
    assert out["bounds"] == [lo, hi] and out["marginal"] is False and out["converged"] is True
    assert rho(cs, certify=True).to_dict()["bounds"] == out["bounds"]
    searched = search_rho(cs)
    assert searched.bounds is None and "bounds" not in searched.to_dict()
    # The bare search and the certified path run different local solvers (the search ends with
    # an IPOPT polish): any direction's value bounds rho from below, and both values agree to
    # the certificate's tolerance.
    assert searched.rho <= hi
    assert abs(certified.rho - searched.rho) <= 1e-6 * abs(searched.rho)
    with pytest.raises(TypeError, match="certify"):
        rho(cs, certify="yes")


# --- command line ----------------------------------------------------------------------------


def test_cli_rho_certify_json(tmp_path, capsys):
    other = tmp_path / "three.contacts.json"
    other.write_text(json.dumps(make("sfcl", 3, 0).to_dict()))
    code = main(["rho", str(EXAMPLE), str(other), "--certify", "--json"])
    out, err = capsys.readouterr()
    assert code == 0 and err == ""
    results = [json.loads(line) for line in out.splitlines()]
    assert [r["force_closure"] for r in results] == [True, False]
    for r in results:
        lo, hi = r["bounds"]
        assert lo <= r["rho"] <= hi
        assert hi - lo <= CERTIFY_TOL * max(1.0, abs(r["rho"]))
    code = main(["rho", str(EXAMPLE)])
    plain, _ = capsys.readouterr()
    code = main(["rho", str(EXAMPLE), "--certify"])
    out, _ = capsys.readouterr()
    assert code == 0 and out == plain  # --certify is accepted and changes nothing
    assert "certified -0.0883" in out and "<= rho <=" in out


# --- the comparison script -------------------------------------------------------------------


@pytest.mark.slow
def test_compare_solvers_small(tmp_path):  # about 30 s
    proc = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "compare_solvers.py"), "--small"]
        + ["--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    for name in ("compare_solvers.csv", "compare_solvers.md", "compare_solvers.png"):
        assert (tmp_path / name).stat().st_size > 0
    table = (tmp_path / "compare_solvers.md").read_text()
    assert table in proc.stdout
    table_rows = [line for line in table.splitlines() if line.startswith("| ")]
    assert sum("GraspIt" in line for line in table_rows) == 1  # contact sets only
    for label in ("IPOPT", "SLSQP", "cvxpy SOCP", "cvxpy force-closure", "certified"):
        assert sum(label in line for line in table_rows) == 2  # contact and element sets
    rows = (tmp_path / "compare_solvers.csv").read_text().splitlines()
    assert len(rows) == 1 + 15 * 6 + 8 * 5  # header, 15 contact sets x 6, 8 element sets x 5
    for line in table_rows:
        if line.startswith("| IPOPT"):
            worst = [float(x) for x in line.split("|")[5:7] if x.strip() != "-"]
            assert max(worst) <= 2e-6  # IPOPT within the certified bounds (its kink precision)
