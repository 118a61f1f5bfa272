"""The certified ceiling on placements: never below a placement's certified capacity."""

from __future__ import annotations

import numpy as np
import pytest

from closure_nlp.contact.contact_set import ContactSet
from closure_nlp.criterion.rho_hat import Eligibility
from closure_nlp.criterion.support_minimum import rho
from closure_nlp.model.scale import contact_specs
from closure_nlp.placement import ceiling as placement_bound
from closure_nlp.placement import max_min_lp as lp_solvers
from closure_nlp.placement.ceiling import (
    BoundOptions,
    CellLP,
    capacity_bound,
    element_pieces,
    relative_gap,
)
from closure_nlp.placement.options import PlacementOptions
from closure_nlp.placement.place import Placer
from tests.shapes import box_model


def _random_cell(rng, eligibility, elements, depth=(0, 10)):
    """Each contact on a random sub-piece of its element (halved ``depth`` times, at random in
    that range: deep cells make the bound tight), sometimes with a second piece from another
    element."""
    cell = []
    for e in elements:
        piece = element_pieces(eligibility, e)[0]
        for _ in range(int(rng.integers(*depth))):
            piece = piece.halves()[int(rng.integers(0, 2))]
        pieces = [piece]
        if rng.random() < 0.25:
            other = int(rng.integers(0, len(eligibility.model.elements)))
            pieces.append(element_pieces(eligibility, other)[0])
        cell.append(pieces)
    return tuple(cell)


def _sample(rng, eligibility, cell) -> ContactSet:
    contacts = []
    for spec, pieces in zip(eligibility.specs, cell):
        piece = pieces[int(rng.integers(0, len(pieces)))]
        w = rng.dirichlet(np.full(len(piece.vertices), 0.5))
        contacts.append(spec.at(w @ piece.vertices, piece.inward_normal))
    return ContactSet(tuple(contacts), eligibility.torque_scale, eligibility.model.reference_point)


def _held_below(rng, eligibility, cells, ceiling) -> int:
    """How many placements, one sampled in each of ``cells``, hold (certified capacity > 0);
    none may hold more than ``ceiling``."""
    held = 0
    for cell in cells:
        capacity = -rho(_sample(rng, eligibility, cell)).bounds[1]
        assert capacity <= ceiling
        held += capacity > 0
    return held


def _violations(eligibility, elements, cells=6, samples=5, seed=0, depth=(0, 10), rows=0):
    """(samples whose certified capacity -hi exceeds their cell's bound, force-closure samples);
    ``rows`` > 0: each cell's LP by row generation from that many rows."""
    rng = np.random.default_rng(seed)
    lp = CellLP(eligibility)
    bad = closure = 0
    for _ in range(cells):
        cell = _random_cell(rng, eligibility, elements, depth)
        bound = lp.bound(cell, rounds=2, tolerance=1e-3, rows=rows).value
        for _ in range(samples):
            result = rho(_sample(rng, eligibility, cell))
            capacity = -result.bounds[1]  # certified: the true -rho is at least this
            closure += capacity > 0
            bad += capacity > bound
    return bad, closure


CASES = [
    ("pcwf", 0.5, (0, 1, 2, 3)),
    ("sfce", 0.3, (0, 1, 4, 5)),
    (["fpc", "pcwf", "sfcl", "sfce", "pcwf"], 0.4, (0, 1, 2, 3, 4)),
]


@pytest.mark.parametrize("kind, mu, elements", CASES)
@pytest.mark.parametrize("rows", [0, 8])
def test_cell_bound_is_above_every_sampled_placement(kind, mu, elements, rows):
    model = box_model(2.0)
    specs = contact_specs(len(elements), type=kind, mu=mu, mu_s=0.2)
    eligibility = Eligibility(model, specs, 0.5)
    bad, closure = _violations(eligibility, elements, rows=rows)
    assert bad == 0
    assert closure >= 8  # the samples are held: the comparison is not against zero


def test_the_check_fails_when_a_term_is_dropped(monkeypatch):
    """With the last contact's term left out of the LP, sampled placements beat the 'bound'."""
    solve = placement_bound._GrowingLP.solve

    def dropped(lp, A, pool, rows):
        A = A.copy()
        A[:, lp.owner == lp.owner.max()] = 0.0
        return solve(lp, A, pool, rows)

    monkeypatch.setattr(placement_bound._GrowingLP, "solve", dropped)
    model = box_model(2.0)
    specs = contact_specs(4, type="pcwf", mu=0.5)
    eligibility = Eligibility(model, specs, 0.5)
    bad, _ = _violations(eligibility, (0, 1, 2, 3), 4, 4, seed=1, depth=(10, 11))
    assert bad > 0


def test_dual_bound_holds_for_any_weights():
    """D(y) is above min_k (A lam)_k for every feasible lam (weak duality), and equals the LP's
    value at its dual."""
    rng = np.random.default_rng(1)
    A = rng.random((30, 7))
    owner = np.array([0, 0, 0, 1, 1, 2, 2])
    result = placement_bound._solve_lp(A, owner, np.zeros((30, 6)))
    assert result.value == pytest.approx(result.lp_value, rel=1e-6)
    for _ in range(200):
        lam = np.concatenate(
            [rng.dirichlet(np.ones(3)), rng.dirichlet(np.ones(2)), rng.dirichlet(np.ones(2))]
        )
        assert (A @ lam).min() <= result.value
        y = rng.dirichlet(np.ones(30))
        assert (A @ lam).min() <= lp_solvers.dual_bound(A, owner, y)


def test_row_generation_reaches_the_full_lp():
    """The LP started on a few rows, with rows added where its weights fall short, ends at the
    value of the LP over every row (a loop that stopped after its first solve would not)."""
    rng = np.random.default_rng(4)
    owner = np.array([0, 0, 0, 1, 1, 1, 2, 2])
    for _ in range(5):
        A = rng.random((400, 8)) ** 3
        pool = np.zeros((400, 6))
        full = placement_bound._solve_lp(A, owner, pool)
        first = CellLP._first_rows(A, owner, 0, 6)
        assert len(first) == 6
        generated = CellLP._solve_rows(A, owner, pool, first)
        assert len(generated.directions) < 400  # the point of it: a smaller LP
        assert generated.value == pytest.approx(full.value, rel=1e-5)
        assert (A @ generated.lam).min() >= generated.lp_value * (1 - 1e-5)


def test_an_lp_grown_row_by_row_ends_at_the_fresh_lp():
    """The cutting planes' LP keeps its solver (and basis) while rows join: after each batch
    its value, and the certified bound of its duals, are those of the LP over the same rows
    solved from scratch, and its duals' bound holds for every weight vector."""
    rng = np.random.default_rng(7)
    owner = np.array([0, 0, 0, 1, 1, 2, 2, 2])
    for _ in range(4):
        A = rng.random((300, 8)) ** 2
        pool = rng.standard_normal((300, 6))
        lp = placement_bound._GrowingLP(owner)
        rows = np.arange(10)
        for _ in range(5):
            grown = lp.solve(A, pool, rows)
            fresh = placement_bound._solve_lp(A[rows], owner, pool[rows])
            assert grown.lp_value == pytest.approx(fresh.lp_value, rel=1e-7)
            assert grown.value == pytest.approx(fresh.value, rel=1e-7)
            assert len(grown.directions) == len(rows)
            for _ in range(20):
                lam = np.concatenate([rng.dirichlet(np.ones(k)) for k in (3, 2, 3)])
                assert (A[rows] @ lam).min() <= grown.value
            rest = np.setdiff1d(np.arange(300), rows)
            rows = np.concatenate([rows, rng.choice(rest, 15, replace=False)])


def test_capacity_bound_on_the_box():
    """The ceiling is above the exchange method's placement and above random placements on the
    elements; the gap is what it says."""
    model = box_model(1.0)
    specs = contact_specs(4, type="pcwf", mu=0.5)
    eligibility = Eligibility(model, specs, 1.0)
    placer = Placer(
        eligibility, PlacementOptions(neighbour_moves=0, starts=1, extra_starts=0, bound=False)
    )
    elements = (0, 1, 2, 3)
    placed = placer(elements)
    options = BoundOptions(time_budget=1.0, root_cuts=8, polish_every=0)
    result = capacity_bound(placer, elements, placed, options)
    assert result.domain == tuple((e,) for e in elements)
    assert result.value >= -placed.bounds[1]
    assert result.capacity >= -placed.bounds[1]
    assert result.gap == pytest.approx(relative_gap(result.value, result.capacity))
    assert 0 <= result.gap < 1 and result.value <= result.root_value
    rng = np.random.default_rng(2)
    cell = tuple(element_pieces(eligibility, e) for e in elements)
    _held_below(rng, eligibility, [cell] * 10, result.value)


def test_a_searched_ceiling_over_neighbours_is_above_every_sampled_placement():
    """After cells past the root (neighbours in the domain, exchange runs finding incumbents),
    no placement sampled anywhere in the domain holds more than the ceiling; some do hold."""
    model = box_model(1.0)
    specs = contact_specs(4, type="sfce", mu=0.4, mu_s=0.2)
    eligibility = Eligibility(model, specs, 0.7)
    placer = Placer(eligibility, PlacementOptions(starts=1, extra_starts=0, bound=False))
    elements = (0, 1, 2, 3)
    placed = placer(elements)
    options = BoundOptions(gap=0.0, time_budget=np.inf, max_nodes=40, polish_every=10)
    result = capacity_bound(placer, elements, placed, options)
    assert result.nodes > 1 and any(len(ids) > 1 for ids in result.domain)
    assert result.value >= result.capacity >= -placed.bounds[1]
    rng = np.random.default_rng(5)
    cell = tuple([element_pieces(eligibility, e)[0] for e in ids] for ids in result.domain)
    assert _held_below(rng, eligibility, [cell] * 40, result.value) >= 5


def test_the_part_ceiling_is_above_placements_on_any_elements(tmp_path, capsys):
    """The ceiling over the whole part bounds placements sampled on random element sets
    (contacts sharing an element too), and ``plan --part-ceiling`` reports it above its plan."""
    import json

    from closure_nlp.cli import main as cli
    from closure_nlp.model.elements import save_model
    from closure_nlp.placement.ceiling import part_ceiling

    model = box_model(1.0)
    specs = contact_specs(4, type="pcwf", mu=0.5)
    eligibility = Eligibility(model, specs, 1.0)
    placer = Placer(eligibility, PlacementOptions(starts=1, extra_starts=0, bound=False))
    found = part_ceiling(placer, None, BoundOptions(time_budget=np.inf, max_nodes=12))
    assert found.domain == (tuple(range(6)),) * 4 and found.gap is None
    rng = np.random.default_rng(4)
    # each cell drawn just before its sample, from the same generator
    cells = (
        tuple(element_pieces(eligibility, int(e)) for e in rng.integers(0, 6, 4)) for _ in range(30)
    )
    assert _held_below(rng, eligibility, cells, found.value) >= 5
    path = tmp_path / "box.model.json"
    save_model(model, path)
    argv = ["plan", str(path), "--contacts", "4", "--seeds", "1", "--starts", "1"]
    flags = ["--torque-scale", "1", "--mu", "0.5", "--bound-cells", "4", "--part-ceiling"]
    assert cli.main([*argv, *flags, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    part, placed = data["part_ceiling"], data["placement"]
    assert part["capacity_bound"] >= -placed["bounds"][1]
    assert part["gap"] == pytest.approx(relative_gap(part["capacity_bound"], -placed["bounds"][1]))


def test_no_force_closure_gives_a_zero_ceiling():
    """All four contacts on one face push one way: the ceiling is 0 (a proof that no placement
    there is force closure) and the gap is undefined."""
    model = box_model(1.0)
    specs = contact_specs(4, type="pcwf", mu=0.5)
    eligibility = Eligibility(model, specs, 1.0)
    placer = Placer(
        eligibility, PlacementOptions(neighbour_moves=0, starts=1, extra_starts=0, bound=False)
    )
    placed = placer((0, 0, 0, 0))
    options = BoundOptions(time_budget=1.0, polish_every=0)
    result = capacity_bound(placer, (0, 0, 0, 0), placed, options)
    assert 0.0 <= result.value <= 1e-6  # round-off margin only (f_max 1)
    assert result.gap is None and result.reached


def test_options_are_checked():
    with pytest.raises(ValueError, match="gap"):
        BoundOptions(gap=-1.0)
    with pytest.raises(ValueError, match="time_budget"):
        BoundOptions(time_budget=float("nan"))
    with pytest.raises(ValueError, match="root_cuts"):
        BoundOptions(root_cuts=1.5)
    with pytest.raises(ValueError, match="polish_runs"):
        BoundOptions(polish_runs=-1)
    with pytest.raises(ValueError, match="probe_every"):
        BoundOptions(probe_every=-2)


def test_gap_text_says_what_was_proved():
    from types import SimpleNamespace

    from closure_nlp.placement.ceiling import gap_text

    base = dict(
        capacity_bound=0.7928, bound_nodes=12, bound_elements=((1,), (2,)), bounds=(-0.5162, -0.516)
    )
    held = SimpleNamespace(**base, gap=0.021, gap_reached=True)
    assert gap_text(held) == (
        "certified: no placement on these elements holds more than 0.7928; "
        "this one holds 0.5160, within 2.1% (12 cells)"
    )
    # a budget ended first: how fast the gap was still falling, never "a budget ended"
    late = SimpleNamespace(
        **base, gap=0.1, gap_reached=False, bound_seconds=4.0, root_gap=0.3, gap_per_cell=0.005
    )
    text = gap_text(late)
    assert "within 10%" in text and "from 30%" in text and "0.5 points a cell" in text
    assert "12 cells in 4 s" in text
    assert "budget" not in text
    root = SimpleNamespace(**{**base, "bound_nodes": 1}, gap=0.35, gap_reached=False)
    assert "the root cell" in gap_text(root) and "--bound-cells" in gap_text(root)
    nowhere = SimpleNamespace(**{**base, "capacity_bound": 1e-12}, gap=None, gap_reached=True)
    assert gap_text(nowhere).startswith("certified: no placement on these elements is force")
    short = SimpleNamespace(**base, gap=None, gap_reached=False)
    assert gap_text(short).endswith("this one is not force closure (12 cells)")
    near = SimpleNamespace(**{**base, "bound_elements": ((1, 3), (2,))}, gap=0.2, gap_reached=True)
    assert "and their neighbours" in gap_text(near)
    assert gap_text(SimpleNamespace(capacity_bound=None)) == ""


def test_the_trend_is_the_gap_falling_over_the_search():
    """``trend()`` reads the search's history: the root's gap, and the fall per second and
    per cell over the last quarter of each."""
    from closure_nlp.placement.ceiling import CapacityBound

    history = (
        (0.0, 1.0, 0.5, 1),
        (2.0, 0.8, 0.5, 30),
        (8.0, 0.625, 0.5, 32),
        (10.0, 0.5556, 0.5, 40),
    )
    found = CapacityBound(0.5556, 0.5, 0.1, None, 40, 3, False, ((1,),), 10.0, history=history)
    root, per_second, per_cell = found.trend()
    assert root == pytest.approx(0.5)
    last = (0.5556 - 0.5) / 0.5556
    assert per_second == pytest.approx((0.2 - last) / 2.0)
    assert per_cell == pytest.approx((0.375 - last) / 10.0)  # cells 30 to 40
    alone = CapacityBound(1.0, 0.5, 0.5, None, 1, 1, False, ((1,),), 1.0, history=history[:1])
    assert alone.trend() == (pytest.approx(0.5), None, None)


def test_the_two_lp_solvers_agree():
    """HiGHS called directly and through scipy's linprog give the same LP value and a dual
    whose recomputed bound is that value."""
    if lp_solvers.Highs is None:
        pytest.skip("highspy is not installed")
    rng = np.random.default_rng(5)
    owner = np.array([0, 0, 1, 1, 1, 2, 2, 2, 2])
    for _ in range(5):
        A = rng.random((60, 9)) ** 2
        x1, d1, v1 = lp_solvers.highs_solve(A, owner, 3)
        x2, d2, v2 = lp_solvers.linprog_solve(A, owner, 3)
        assert v1 == pytest.approx(v2, rel=1e-8)
        for d in (d1, d2):
            y = np.maximum(-d, 0.0)
            assert lp_solvers.dual_bound(A, owner, y / y.sum()) == pytest.approx(v1, rel=1e-7)


def test_a_failed_highs_solve_falls_back(monkeypatch):
    """A HiGHS solve that does not end optimal (numerical trouble) is redone, then handed to
    scipy's linprog: the same LP value, never an exception or a wrong bound."""
    if lp_solvers.Highs is None:
        pytest.skip("highspy is not installed")
    rng = np.random.default_rng(6)
    owner = np.array([0, 0, 1, 1, 2, 2])
    A = rng.random((40, 6))
    expected = lp_solvers.linprog_solve(A, owner, 3)[2]
    monkeypatch.setattr(lp_solvers, "OPTIMAL", object())  # no status is "optimal"
    calls = []
    linprog = lp_solvers.linprog_solve
    monkeypatch.setattr(lp_solvers, "linprog_solve", lambda *a: calls.append(1) or linprog(*a))
    result = placement_bound._solve_lp(A, owner, np.zeros((40, 6)))
    assert calls and result.lp_value == pytest.approx(expected, rel=1e-9)
    assert result.value == pytest.approx(expected, rel=1e-6)


def test_every_solver_failing_still_gives_a_certified_bound(monkeypatch):
    """When HiGHS and linprog both fail on an LP, the cell's bound is the weak dual of uniform
    duals: looser, still above every sampled placement, and no exception."""

    def failed(*args):
        raise RuntimeError("capacity bound: the LP solver failed (test)")

    monkeypatch.setattr(lp_solvers, "highs_solve", failed)
    monkeypatch.setattr(lp_solvers, "linprog_solve", failed)
    model = box_model(2.0)
    specs = contact_specs(4, type="pcwf", mu=0.5)
    bad, closure = _violations(Eligibility(model, specs, 0.5), (0, 1, 2, 3), 3, 4, depth=(4, 8))
    assert bad == 0 and closure >= 6


def test_lp_values_scale_with_the_wrench_scale():
    """The LP is solved on its matrix over the largest entry: scaling the matrix by 1e-9 or
    1e9 scales the value and keeps the weights (HiGHS's absolute tolerances do not decide)."""
    rng = np.random.default_rng(8)
    owner = np.array([0, 0, 0, 1, 1, 2, 2])
    A = rng.random((50, 7))
    base = placement_bound._solve_lp(A, owner, np.zeros((50, 6)))
    for factor in (1e-9, 1e9):
        scaled = placement_bound._solve_lp(A * factor, owner, np.zeros((50, 6)))
        assert scaled.value == pytest.approx(base.value * factor, rel=1e-9)
        np.testing.assert_allclose(scaled.lam, base.lam, atol=1e-9)


def test_exchange_runs_keep_to_their_share_of_the_time(monkeypatch):
    """Under a time budget, polish_share caps the time the exchange runs from the best cells
    take: with a share of zero only the first runs (it starts before any time is spent); with
    all of it, one per cell as polish_every asks. Without a time budget the cells alone decide
    (the same runs on any machine), whatever the share. (The exchange run is replaced by a
    stand-in that takes 20 ms.)"""
    import time
    from types import SimpleNamespace

    def exchange_run(self, elements, weights=None, progress=None):
        time.sleep(0.02)
        return SimpleNamespace(bounds=(-0.01, -0.01), rho=-0.01)

    monkeypatch.setattr(Placer, "__call__", exchange_run)
    model = box_model(1.0)
    specs = contact_specs(4, type="pcwf", mu=0.5)
    placer = Placer(Eligibility(model, specs, 1.0), PlacementOptions(neighbour_moves=0))
    runs = {}
    for budget in (60.0, np.inf):
        for share in (0.0, 1.0):
            options = BoundOptions(
                gap=0.0,
                time_budget=budget,
                max_nodes=9,
                root_cuts=2,
                polish_every=1,
                polish_share=share,
            )
            runs[budget, share] = capacity_bound(placer, (0, 1, 2, 3), None, options).polishes
    assert runs[60.0, 0.0] == 1
    assert runs[60.0, 1.0] >= 3
    assert runs[np.inf, 0.0] == runs[np.inf, 1.0] == runs[60.0, 1.0]


def test_the_split_halves_the_piece_of_largest_moment():
    """Several elements' pieces are separated first; then the piece whose size times its
    contact's f_max is largest is halved (whatever its element's size); a cell of points is not
    split."""
    model = box_model(2.0)
    eligibility = Eligibility(model, contact_specs(3, type="pcwf", mu=0.5), 0.5)
    lp = CellLP(eligibility)
    whole = [element_pieces(eligibility, e)[0] for e in (0, 1, 2)]
    quarter = whole[0].halves()[0].halves()[0]
    half = whole[1].halves()[0]
    tiny = element_pieces(eligibility, 3)[0].halves()[0].halves()[0].halves()[0]
    cell = ((quarter,), (half,), (tiny,))
    bound = lp.bound(cell, rounds=0, tolerance=1e-3)
    split = placement_bound._split(lp, placement_bound._Cell(cell, bound, 0))
    assert [c[1][0].size for c in split] == [p.size for p in half.halves()]
    assert all(c[0] == (quarter,) and c[2] == (tiny,) for c in split)
    # a contact pushing eight times harder: its smaller piece moves the bound more
    strong = Eligibility(model, contact_specs(3, type="pcwf", mu=0.5, f_max=(8.0, 1.0, 1.0)), 0.5)
    strong_lp = CellLP(strong)
    bound = strong_lp.bound(cell, rounds=0, tolerance=1e-3)
    split = placement_bound._split(strong_lp, placement_bound._Cell(cell, bound, 0))
    assert [c[0][0].size for c in split] == [p.size for p in quarter.halves()]
    assert all(c[1] == (half,) and c[2] == (tiny,) for c in split)
    mixed = ((quarter,), (half,), (tiny, whole[2]))
    bound = lp.bound(mixed, rounds=0, tolerance=1e-3)
    split = placement_bound._split(lp, placement_bound._Cell(mixed, bound, 0))
    assert sorted(len(c[2]) for c in split) == [1, 1] and split[0][1] == (half,)
    points = tuple(
        (placement_bound.Piece(e, whole[k].vertices[:1], whole[k].inward_normal),)
        for k, e in enumerate((0, 1, 2))
    )
    bound = lp.bound(points, rounds=0, tolerance=1e-3)
    assert placement_bound._split(lp, placement_bound._Cell(points, bound, 0)) is None


def test_frictionless_cells_take_the_facet_bound():
    """7 frictionless contacts on small pieces of the box: a cell's bound is at most the
    zonotope's facet bound (where that one holds) and above every sampled placement's certified
    capacity; a facet bound at most ``floor`` closes the cell without its LP."""
    model = box_model(2.0)
    eligibility = Eligibility(model, contact_specs(7, type="fpc"), 0.5)
    lp = CellLP(eligibility)
    rng = np.random.default_rng(0)
    with_facets = 0
    for _ in range(8):
        pieces = _random_cell(rng, eligibility, (0, 1, 2, 3, 4, 5, 0), (10, 14))
        cell = tuple([p[0]] for p in pieces)
        facet = lp.facet_bound(cell)
        bound = lp.bound(cell, rounds=2, tolerance=1e-3)
        assert bound.value <= facet
        for _ in range(3):
            assert -rho(_sample(rng, eligibility, cell)).bounds[1] <= bound.value
        if np.isfinite(facet):
            with_facets += 1
            closed = lp.bound(cell, rounds=2, tolerance=1e-3, floor=facet)
            assert closed.value == facet and len(closed.y) == 0
    assert with_facets >= 3


def _area(v: np.ndarray) -> float:
    """Area of a planar polygon in 3-D (vertices in order)."""
    return 0.5 * float(np.linalg.norm(np.cross(v - v[0], np.roll(v, -1, axis=0) - v[0]).sum(0)))


def test_a_polygon_is_cut_across_its_longest_extent():
    """A round facet's halves cover it (areas add up, every vertex inside) and keep shrinking:
    a cut along a diagonal would keep the diameter; four cuts halve it here."""
    t = np.linspace(0.0, 2.0 * np.pi, 25)[:-1]
    vertices = np.c_[16.0 * np.cos(t), 16.0 * np.sin(t), np.full(24, 3.0)]
    piece = placement_bound.Piece(0, vertices, np.array([0.0, 0.0, -1.0]))
    halves = piece.halves()
    assert sum(_area(h.vertices) for h in halves) == pytest.approx(_area(vertices), rel=1e-12)
    for h in halves:
        assert np.all(np.linalg.norm(h.vertices[:, :2], axis=1) <= 16.0 + 1e-9)
        assert np.allclose(h.vertices[:, 2], 3.0)
    for _ in range(4):
        piece = max(piece.halves(), key=lambda p: p.size)
    assert piece.size <= 0.5 * 32.0


def test_probes_give_cuts_and_incumbents_and_keep_the_ceiling_sound():
    """Probes (the split cells' LP placements searched) on 3 contacts of the box: no sampled
    placement beats the ceiling, and a probed incumbent is a certified placement with no
    exchange round, never below the given one."""
    model = box_model(1.0)
    specs = contact_specs(3, type="sfce", mu=0.5, mu_s=0.2)
    eligibility = Eligibility(model, specs, 0.7)
    placer = Placer(
        eligibility, PlacementOptions(neighbour_moves=0, starts=1, extra_starts=0, bound=False)
    )
    elements = (0, 1, 2)
    placed = placer(elements)
    common = dict(gap=0.0, time_budget=np.inf, max_nodes=120, polish_every=0)
    probed = capacity_bound(placer, elements, placed, BoundOptions(**common))
    plain = capacity_bound(placer, elements, placed, BoundOptions(**common, probe_every=0))
    assert probed.value >= probed.capacity >= plain.capacity == -placed.bounds[1]
    if probed.placement is not None:  # a probe's placement: certified, no exchange round
        assert probed.placement.rounds == 0
        assert -probed.placement.bounds[1] == probed.capacity
        again = rho(probed.placement.contact_set)
        assert -again.bounds[1] == pytest.approx(probed.capacity, rel=1e-6)
    rng = np.random.default_rng(7)
    cell = tuple(element_pieces(eligibility, e) for e in elements)
    assert _held_below(rng, eligibility, [cell] * 30, probed.value) >= 5
    # without probe incumbents (the part's ceiling) the given placement stays the incumbent
    kept = capacity_bound(placer, elements, placed, BoundOptions(**common, probe_incumbents=False))
    assert kept.placement is None and kept.capacity == -placed.bounds[1]
