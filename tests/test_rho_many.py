"""rho_many: many contact sets at once, certified like rho, whatever the number of workers."""

import numpy as np
import pytest

from closure_nlp import ContactSet, Eligibility, contact_specs, force_closure_cvxpy, load_model, rho
from closure_nlp.contact.random_sets import random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import tolerance_unit
from closure_nlp.criterion.crosscheck import distance_cvxpy
from closure_nlp.criterion.many import rho_hat_many, rho_many
from closure_nlp.criterion.support_minimum import SupportMinimizer


def _arrays(n: int, m: int = 4, seed: int = 0):
    rng = np.random.default_rng(seed)
    sets = [random_contact_set(rng, ["pcwf"] * m, mu=0.5) for _ in range(n)]
    P = np.array([[c.position for c in s.contacts] for s in sets])
    U = np.array([[c.inward_normal for c in s.contacts] for s in sets])
    return sets, P, U


@pytest.fixture(scope="module")
def forty():
    return _arrays(40)


def test_columns_are_each_sets_certified_rho(forty):
    sets, P, U = forty
    columns = rho_many(P, U, mu=0.5, workers=1)
    assert len(columns) == 40 and columns.bounds.shape == (40, 2)
    for k, s in enumerate(sets):
        # the same contacts, their normals normalised once more (a last-bit difference at most)
        again = ContactSet(
            tuple(type(c)(P[k, i], U[k, i], mu=0.5) for i, c in enumerate(s.contacts))
        )
        one = rho(again)
        assert columns.rho[k] == one.rho and tuple(columns.bounds[k]) == one.bounds
        assert columns.rho[k] == pytest.approx(rho(s).rho, rel=1e-9, abs=1e-12)
        assert columns.force_closure[k] == one.force_closure
        assert np.array_equal(columns.direction[k], one.direction)
    lo, hi = columns.bounds.T
    assert np.all(lo <= columns.rho) and np.all(columns.rho <= hi)
    assert 0 < columns.force_closure.sum() < 40  # both verdicts are exercised


def test_verdicts_agree_with_the_cvxpy_check(forty):
    """An independent check of force closure (cvxpy's LP/SOCP on the exact cones)."""
    sets, P, U = forty
    columns = rho_many(P, U, mu=0.5, workers=2)
    for k in range(0, 40, 4):
        if not columns.marginal[k]:
            assert bool(columns.force_closure[k]) == force_closure_cvxpy(sets[k])


@pytest.mark.parametrize("workers,pool", [(2, "threads"), (3, "threads"), (2, "processes")])
def test_the_answers_do_not_depend_on_the_workers(workers, pool):
    _, P, U = _arrays(70, seed=3)  # three chunks of sets
    serial = rho_many(P, U, mu=0.5, workers=1)
    parallel = rho_many(P, U, mu=0.5, workers=workers, pool=pool)
    for name in ("rho", "bounds", "force_closure", "marginal", "converged", "direction"):
        assert np.array_equal(getattr(serial, name), getattr(parallel, name)), name


def test_parameters_per_set_and_per_contact():
    sets, P, U = _arrays(3, m=3, seed=5)
    types = [["sfce", "pcwf", "fpc"]] * 3
    mus = np.array([0.3, 0.5, 0.7])  # one per set
    columns = rho_many(P, U, type=types, mu=mus, mu_s=0.1, f_max=[[1, 2, 3]] * 3, workers=1)
    for k in range(3):
        expected = rho(
            ContactSet(
                tuple(
                    type(c)(c.position, c.inward_normal, t, mus[k], 0.1, f)
                    for c, t, f in zip(sets[k].contacts, types[k], (1, 2, 3))
                )
            )
        )
        assert columns.rho[k] == expected.rho


def test_a_list_of_contact_sets_and_read_only_columns(forty):
    sets, _, _ = forty
    columns = rho_many(sets[:5], workers=1)
    assert list(columns.rho) == [rho(s).rho for s in sets[:5]]
    with pytest.raises(ValueError):
        columns.rho[0] = 1.0


@pytest.mark.parametrize(
    "kwargs,error,field",
    [
        ({"inward_normals": np.zeros((2, 4, 3))}, ValueError, "inward_normal"),
        ({"inward_normals": np.ones((2, 3, 3))}, ValueError, "inward_normals"),
        ({"mu": [0.5, 0.5, 0.5]}, ValueError, "mu"),
        ({"mu": -1.0}, ValueError, "mu"),
        ({"type": "velcro"}, ValueError, "velcro"),
        ({"workers": 0}, ValueError, "workers"),
        ({"pool": "gpu"}, ValueError, "pool"),
        ({"torque_scale": [1.0, 2.0, 3.0]}, ValueError, "torque_scale"),
        ({"inward_normals": np.ones((2, 4, 3), dtype=bool)}, TypeError, "inward_normals"),
        ({"tol": 0.0}, ValueError, "tol"),
        ({"tol": 0.5}, ValueError, "tol"),
        ({"tol": float("nan")}, ValueError, "tol"),
        ({"tol": True}, TypeError, "tol"),
        ({"tol": "1e-3"}, TypeError, "tol"),
    ],
)
def test_bad_arguments_name_the_field(kwargs, error, field):
    _, P, U = _arrays(2)
    args = {"inward_normals": U, **kwargs}
    with pytest.raises(error, match=field):
        rho_many(P[:2], **args)


@pytest.mark.parametrize("tol", [1e-3, 1e-2])
def test_a_wider_bracket_holds_the_default_answer(forty, tol):
    """``tol`` widens each certified bracket to at most ``tol`` of the set's scale; the default
    1e-6 answer lies inside it, and its verdicts never claim more than the default's."""
    sets, P, U = forty
    fine = rho_many(P, U, mu=0.5, workers=1)
    wide = rho_many(P, U, mu=0.5, workers=2, tol=tol)
    assert wide.converged.all()
    for k, s in enumerate(sets):
        unit = tolerance_unit(WrenchSlots.from_contacts(s))
        lo, hi = wide.bounds[k]
        assert hi - lo <= tol * max(abs(lo), abs(hi), unit) * (1 + 1e-9)
        assert lo <= wide.rho[k] <= hi
        # both brackets hold rho: they overlap (to their round-off), and the narrow one's
        # answer lies within its own width of the wide one
        fine_lo, fine_hi = fine.bounds[k]
        slack = 1e-12 * unit + (fine_hi - fine_lo)
        assert max(lo, fine_lo) <= min(hi, fine_hi) + 1e-12 * unit
        assert lo - slack <= fine.rho[k] <= hi + slack
        if wide.force_closure[k]:
            assert fine.force_closure[k] and hi < -tol * unit
        if fine.force_closure[k] and not wide.force_closure[k]:
            assert wide.marginal[k] and hi >= -tol * unit  # within the asked accuracy of zero
    # what buys the time: on force-closure sets the brackets are wider
    closure = fine.force_closure
    assert np.median(np.diff(wide.bounds)[closure]) > np.median(np.diff(fine.bounds)[closure])


def test_a_wider_bracket_holds_the_cvxpy_distance():
    """Outside the wrench set, rho is the distance to it: cvxpy's SOCP, an independent
    solver, lands inside every wide bracket (to its own accuracy)."""
    sets, P, U = _arrays(30, m=3, seed=9)
    wide = rho_many(P, U, mu=0.5, workers=1, tol=1e-2)
    outside = [k for k in range(30) if not wide.force_closure[k] and not wide.marginal[k]]
    assert len(outside) >= 10
    for k in outside:
        distance = distance_cvxpy(sets[k])
        lo, hi = wide.bounds[k]
        assert lo - 1e-7 <= distance <= hi + 1e-7


def test_the_wide_answers_do_not_depend_on_the_workers():
    _, P, U = _arrays(70, seed=4)
    serial = rho_many(P, U, mu=0.5, workers=1, tol=1e-3)
    forked = rho_many(P, U, mu=0.5, workers=2, pool="processes", tol=1e-3)
    for name in ("rho", "bounds", "force_closure", "marginal", "converged", "direction"):
        assert np.array_equal(getattr(serial, name), getattr(forked, name)), name


def test_rho_takes_the_same_tol(forty):
    sets, P, U = forty
    wide = rho_many(P[:6], U[:6], mu=0.5, workers=1, tol=1e-3)
    for k in range(6):
        again = ContactSet(
            tuple(type(c)(P[k, i], U[k, i], mu=0.5) for i, c in enumerate(sets[k].contacts))
        )
        one = rho(again, tol=1e-3)
        assert tuple(wide.bounds[k]) == one.bounds and wide.rho[k] == one.rho
    with pytest.raises(ValueError, match="tol"):
        rho(sets[0], tol=1e-3, minimizer=SupportMinimizer())
    with pytest.raises(ValueError, match="tol"):
        rho(sets[0], tol=2.0)


def test_masked_positions_are_refused():
    _, P, U = _arrays(2)
    with pytest.raises(TypeError, match="masked"):
        rho_many(np.ma.masked_array(P, mask=np.zeros_like(P, dtype=bool)), U)


def test_rho_hat_many_is_each_sets_rho_hat_whatever_the_workers():
    from pathlib import Path

    lamp = load_model(Path(__file__).resolve().parents[1] / "models" / "lamp.model.json")
    hand = Eligibility(lamp, contact_specs(4, type="pcwf", mu=0.2, model=lamp))
    rng = np.random.default_rng(2)
    sets = [rng.integers(0, len(lamp), 4).tolist() for _ in range(12)]
    one = rho_hat_many(hand, sets, workers=1)
    two = rho_hat_many(hand, sets, workers=2)
    assert np.array_equal(one.bounds, two.bounds) and np.array_equal(one.eligible, two.eligible)
    for k, ids in enumerate(sets):
        assert one.rho_hat[k] == hand(ids).rho_hat
    with pytest.raises(ValueError, match="element_sets"):
        rho_hat_many(hand, [[0, 1]])


def test_one_contact_set_from_arrays():
    sets, P, U = _arrays(1, m=3, seed=7)
    made = ContactSet.from_arrays(P[0], U[0], type=["pcwf", "sfce", "fpc"], mu=0.5, mu_s=0.1)
    assert [c.type.value for c in made.contacts] == ["pcwf", "sfce", "fpc"]
    assert np.allclose([c.position for c in made.contacts], P[0]) and made.torque_scale == 1.0
    with pytest.raises(ValueError, match="mu"):
        ContactSet.from_arrays(P[0], U[0], mu=[0.5, 0.5])
    with pytest.raises(ValueError, match="shape"):
        ContactSet.from_arrays(P[0], U[0][:2])
    with pytest.raises(ValueError, match="inward_normal"):
        ContactSet.from_arrays(P[0], np.zeros((3, 3)))


def test_the_one_pass_slots_are_the_per_set_slots_to_the_bit():
    """The batch's slots (one numpy pass) hold the numbers that ContactSet.from_arrays and
    WrenchSlots.from_contacts give each set, for every type, per-contact parameters, per-set
    torque scales and reference points, and normals of any length."""
    from closure_nlp.contact.slot_arrays import slots_of_arrays
    from closure_nlp.contact.wrenches import WrenchSlots

    rng = np.random.default_rng(7)
    _, P, U = _arrays(30, m=5, seed=7)
    U = U * rng.uniform(1e-3, 1e3, size=(30, 5, 1))
    kinds = rng.choice(["fpc", "pcwf", "sfcl", "sfce"], size=(30, 5)).astype(object)
    mu, mu_s = rng.uniform(0, 1, size=(30, 5)), rng.uniform(0, 0.1, size=(30, 5))
    f_max, scales = rng.uniform(0.5, 3, size=(30, 5)), rng.uniform(0.1, 2, size=30)
    points = rng.normal(size=(30, 3))
    batch = slots_of_arrays(P, U, kinds, mu, mu_s, f_max, scales, points)
    for k, slots in enumerate(batch):
        one = WrenchSlots.from_contacts(
            ContactSet.from_arrays(
                P[k], U[k], type=list(kinds[k]), mu=mu[k], mu_s=mu_s[k], f_max=f_max[k],
                torque_scale=scales[k], reference_point=points[k],
            )
        )  # fmt: skip
        for name in ("G", "starts", "f_max", "pieces"):
            assert np.array_equal(getattr(slots, name), getattr(one, name)), name
        assert slots.types == one.types and slots.n_pieces == one.n_pieces
    huge = U.copy()
    huge[0, 0] *= 1e200  # its squares overflow: the per-set path rescales it first
    assert slots_of_arrays(P, huge, kinds, mu, mu_s, f_max, scales, points) is None
    columns = rho_many(P[:2], huge[:2], mu=0.5, workers=1)
    assert columns.rho[0] == rho(ContactSet.from_arrays(P[0], huge[0], mu=0.5)).rho


def test_rho_hat_many_takes_a_wider_bracket():
    """``tol`` as rho_many's: each element set's bracket within ``tol`` of its scale, holding
    the default answer, its verdict never stronger; the same as one call with that tol."""
    from pathlib import Path

    lamp = load_model(Path(__file__).resolve().parents[1] / "models" / "lamp.model.json")
    hand = Eligibility(lamp, contact_specs(4, type="pcwf", mu=0.2, model=lamp))
    rng = np.random.default_rng(5)
    sets = [rng.integers(0, len(lamp), 4).tolist() for _ in range(16)]
    fine = rho_hat_many(hand, sets, workers=1)
    wide = rho_hat_many(hand, sets, workers=2, tol=1e-2)
    assert wide.converged.all() and fine.eligible.any()
    for k, ids in enumerate(sets):
        unit = tolerance_unit(hand.slots(hand.check_elements(ids)))
        lo, hi = wide.bounds[k]
        fine_lo, fine_hi = fine.bounds[k]
        assert hi - lo <= 1e-2 * max(abs(lo), abs(hi), unit) * (1 + 1e-9)
        assert max(lo, fine_lo) <= min(hi, fine_hi) + 1e-12 * unit
        if wide.eligible[k]:
            assert fine.eligible[k] and hi < -1e-2 * unit
        one = hand(ids, tol=1e-2)
        assert one.bounds == tuple(wide.bounds[k]) and one.rho_hat == wide.rho_hat[k]
    # the wider bracket is what was asked for: on eligible sets it stops sooner
    eligible = fine.eligible
    assert np.median(np.diff(wide.bounds)[eligible]) > np.median(np.diff(fine.bounds)[eligible])
    with pytest.raises(ValueError, match="tol"):
        rho_hat_many(hand, sets[:1], tol=0.5)
    with pytest.raises(TypeError, match="tol"):
        rho_hat_many(hand, sets[:1], tol="1e-3")
    with pytest.raises(ValueError, match="tol"):
        hand(sets[0], certify=False, tol=1e-3)


def test_a_lone_long_set_gets_both_threads_and_the_same_bits():
    """Fewer sets than one chunk run in the caller's thread, a long certificate's rounds in
    two threads: the answer of one thread, bit for bit."""
    a = np.pi / 2 * np.arange(4)
    P = np.column_stack([np.cos(a), np.sin(a), np.zeros(4)])[None]  # a ring of 4 soft fingers
    both = rho_many(P, -P, type="sfce", mu=0.5, mu_s=0.2, workers=2)
    one = rho_many(P, -P, type="sfce", mu=0.5, mu_s=0.2, workers=1)
    for name in ("rho", "bounds", "force_closure", "marginal", "converged", "direction"):
        assert np.array_equal(getattr(both, name), getattr(one, name)), name
    assert one.force_closure[0] and one.converged[0]
