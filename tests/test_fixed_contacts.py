"""Contacts already in place (``fixed``) and the minimum spacing between contacts, on the
machined block (examples/block): fixed contacts unchanged and counted in rho (against a support
function computed here from the positions alone), count checks counting them, the spacing kept,
and the refusals."""

import json
from pathlib import Path

import numpy as np
import pytest

import closure_nlp.cli.main as cli
from closure_nlp import (
    Eligibility,
    PlacementOptions,
    contact_specs,
    load_contact_set,
    load_model,
    place,
    plan,
    rho,
    select,
)
from closure_nlp.base.errors import MethodError

ROOT = Path(__file__).resolve().parents[1]
BLOCK = ROOT / "examples" / "block" / "block.model.json"
BASE = [[-20.0, -12.0, 0.0], [20.0, -12.0, 0.0], [0.0, 14.0, 0.0]]  # 3 locators under the block
SIDES = [33, 67, 66, 0]  # -x, +x, +y, -y faces


def base_file(tmp_path, positions=BASE, **extra) -> Path:
    contacts = [{"position": p, "inward_normal": [0, 0, 1]} for p in positions]
    path = tmp_path / "base.contacts.json"
    path.write_text(json.dumps({"defaults": {"type": "fpc"}, "contacts": contacts, **extra}))
    return path


@pytest.fixture(scope="module")
def block():
    return load_model(BLOCK)


@pytest.fixture(scope="module")
def planned(block, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fixed")
    fixed = base_file(tmp)
    eligibility = Eligibility(
        block, contact_specs(4, type="pcwf", mu=0.3), exclude="facing:+z", fixed=fixed
    )
    result = plan(eligibility, seeds=1, seed=0, placement=PlacementOptions(min_spacing=5.0))
    out = tmp / "contacts.json"
    out.write_text(json.dumps(result.placement.contact_file(block.name, block.units)))
    return eligibility, result, out


def support_min(contacts, torque_scale, reference, extra=None, samples=20000):
    """min over sampled unit directions (and ``extra`` ones) of the support function (eq 26),
    from the positions, normals and parameters alone: an upper bound of -rho."""
    u = np.random.default_rng(0).normal(size=(samples, 6))
    extra = np.zeros((0, 6)) if extra is None else extra
    u = np.vstack([extra, u / np.linalg.norm(u, axis=1, keepdims=True)])
    P = []
    for c in contacts:
        n = c.inward_normal / np.linalg.norm(c.inward_normal)
        t1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        r = c.position - reference
        w = [np.r_[d, torque_scale * np.cross(r, d)] for d in (n, t1, t2)]
        value = u @ w[0]
        if c.type.value == "pcwf":
            value = value + c.mu * np.hypot(u @ w[1], u @ w[2])
        P.append(c.f_max * value)
    P = np.array(P)
    positive = np.where(P > 0, P, 0.0).sum(axis=0)
    return float(np.where((P > 0).any(axis=0), positive, P.max(axis=0)).min())


def test_fixed_contacts_unchanged_and_first(planned):
    _, result, out = planned
    data = json.loads(out.read_text())
    fixed = [c for c in data["contacts"] if c.get("fixed")]
    assert [c["position"] for c in fixed] == BASE  # bitwise, in the given order
    assert all(c["inward_normal"] == [0.0, 0.0, 1.0] and c["type"] == "fpc" for c in fixed)
    assert [c.get("fixed", False) for c in data["contacts"]] == [True] * 3 + [False] * 4
    assert len(result.placement.contacts) == 4


def test_fixed_contacts_count_in_rho(planned, block):
    eligibility, result, out = planned
    placed = result.placement
    assert placed.force_closure
    again = rho(load_contact_set(out))
    lo, hi = placed.bounds
    assert again.bounds[0] <= hi + 1e-9 and lo - 1e-9 <= again.bounds[1]
    contacts = load_contact_set(out).contacts
    ts, ref = eligibility.torque_scale, block.reference_point
    sampled = support_min(contacts, ts, ref)
    assert -hi <= sampled + 1e-9  # -rho = min p <= any sampled p
    # at the engine's weakest direction, the support value computed here is -rho
    at_u = support_min(contacts, ts, ref, placed.direction[None], samples=0)
    assert abs(at_u + placed.rho) <= 1e-6 * max(1.0, abs(placed.rho))
    without = support_min(contacts[3:], ts, ref)  # the new contacts alone: far weaker
    assert without < 0.5 * sampled


def test_intent_kept(planned, block):
    eligibility, result, _ = planned
    top = set(eligibility.excluded)
    assert top and not set(result.placement.elements) & top
    for step in (result.heuristic, result.iterative):
        assert not set(step.elements) & top
    x = np.array([c.position for c in result.placement.contact_set.contacts])
    d = np.linalg.norm(x[:, None] - x[None], axis=2)[np.triu_indices(len(x), 1)]
    assert d.min() >= 5.0 * (1 - 1e-6)


def test_count_checks_count_fixed(block, tmp_path):
    four = contact_specs(4, type="fpc")
    with pytest.raises(ValueError, match="never give force closure"):
        select(Eligibility(block, four))
    eligibility = Eligibility(block, four, fixed=base_file(tmp_path))
    assert eligibility.all_specs[:3] == contact_specs(3, type="fpc")
    assert len(eligibility.slots([33, 67, 66, 0]).G) > 0  # the fixed rows are in every set


def test_spacing_kept_on_one_face(block, tmp_path):
    # two contacts on the same side face, kept 20 apart (the face is 60 x 20)
    eligibility = Eligibility(
        block, contact_specs(4, type="pcwf", mu=0.3), fixed=base_file(tmp_path)
    )
    options = PlacementOptions(min_spacing=20.0, starts=1, extra_starts=0, bound=False)
    result = place(eligibility, [0, 0, 66, 33], options=options)
    x = np.array([c.position for c in result.contact_set.contacts])
    d = np.linalg.norm(x[:, None] - x[None], axis=2)[np.triu_indices(len(x), 1)]
    assert d.min() >= 20.0 * (1 - 1e-6)
    free = Eligibility(block, contact_specs(7, type="fpc"))
    with pytest.raises(MethodError, match="min_spacing"):  # the face is 63.2 across at most
        place(free, [0, 0, 66, 33, 1, 34, 67], options=PlacementOptions(min_spacing=70.0))
    with pytest.raises(ValueError, match="fixed contacts 0 and 1"):  # 40 apart
        place(eligibility, [0, 1, 66, 33], options=PlacementOptions(min_spacing=50.0))


def run(args, capsys):
    code = cli.main(args)
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    "make,needle",
    [
        (lambda tmp: tmp.joinpath("bad.json").write_text("{") and tmp / "bad.json", "bad.json"),
        (lambda tmp: base_file(tmp, extra_key=1), "extra_key"),
        (lambda tmp: base_file(tmp, BASE[:2] + [[0.0, 14.0, -3.0]]), "fixed[2]: off the part"),
        (
            lambda tmp: base_file(tmp, [[-20.0, -12.0, 0.0], [20.0, -12.0, 0.0], [0.0, 0.0, 0.0]]),
            "fixed[2]: off the part's surface: 4.97",  # in the hole (a 32-gon): no surface
        ),
        (
            lambda tmp: (
                tmp.joinpath("up.json").write_text(
                    json.dumps({"contacts": [{"position": BASE[0], "inward_normal": [0, 0, -1]}]})
                )
                and tmp / "up.json"
            ),
            "fixed[0]: its inward normal is 180 degrees from that of element",
        ),
    ],
)
def test_bad_fixed_file(tmp_path, capsys, make, needle):
    path = make(tmp_path)
    code, err = run(
        ["select", str(BLOCK), "--contacts", "4", "--type", "fpc", "--fixed", str(path)], capsys
    )
    assert code == 2 and needle in err and err.startswith("error:")


def test_spacing_refusals(tmp_path, capsys):
    common = ["place", str(BLOCK), "--type", "pcwf", "--mu", "0.3"]
    code, err = run([*common, "--elements", "0,0,66,33", "--min-spacing", "70"], capsys)
    assert code == 1 and "min_spacing: cannot be kept" in err
    fixed = ["--fixed", str(base_file(tmp_path))]
    code, err = run([*common, *fixed, "--elements", "0,1,66,33", "--min-spacing", "50"], capsys)
    assert code == 2 and "fixed contacts 0 and 1" in err and "base.contacts.json" in err


def test_spacing_that_cannot_be_kept_together(block, tmp_path):
    # each contact on the -y face could keep 30 from each fixed contact alone, not from both
    eligibility = Eligibility(
        block, contact_specs(4, type="pcwf", mu=0.3), fixed=base_file(tmp_path)
    )
    options = PlacementOptions(min_spacing=30.0, starts=1, extra_starts=0, bound=False)
    with pytest.raises(MethodError, match="no placement found that keeps 30"):
        place(eligibility, [0, 0, 66, 33], options=options)


def test_study_intent(block, tmp_path):
    from closure_nlp import study_from_dict
    from closure_nlp.study.tasks import clear_cache, run_task

    base_file(tmp_path)
    data = {
        "models": [str(BLOCK)],
        "type": "pcwf",
        "mu": 0.3,
        "contacts": 4,
        "exclude": "facing:+z",
        "fixed": "base.contacts.json",
        "min_spacing": 5.0,
        "placement": {"starts": 1, "extra_starts": 0, "bound": False},
    }
    study = study_from_dict(data, tmp_path)
    (task,) = study.tasks
    assert dict(task.placement)["min_spacing"] == 5.0
    assert dict(task.intent)["exclude"] == ("facing:+z",)
    resolved = study.to_dict()
    assert resolved["exclude"] == ["facing:+z"] and resolved["fixed"] == "base.contacts.json"
    plain = study_from_dict({k: v for k, v in data.items() if k != "fixed"}, tmp_path)
    assert plain.tasks[0].task_id != task.task_id
    clear_cache()
    row = run_task(task)
    assert row["status"] == "ok", row["error"]
    placed = json.loads(row["placed_contacts"])
    top = {i for i, e in enumerate(block.elements) if e.inward_normal[2] < -0.98}
    assert len(placed) == 4 and not {c["element"] for c in placed} & top
    with pytest.raises(ValueError, match="fixed"):
        study_from_dict({**data, "fixed": "missing.json"}, tmp_path)
    with pytest.raises(ValueError, match="exclude"):
        study_from_dict({**data, "exclude": "facing:+w"}, tmp_path)
    with pytest.raises(ValueError, match="contacts"):  # 3 fixed FPC + 2 FPC: too few
        study_from_dict({**data, "type": "fpc", "contacts": 2}, tmp_path)


def test_plan_says_why_the_spacing_cannot_be_kept(block):
    eligibility = Eligibility(block, contact_specs(7, type="fpc"))
    options = PlacementOptions(min_spacing=200.0, bound=False)  # beyond the part's size
    with pytest.raises(MethodError, match="min_spacing: cannot be kept"):
        plan(eligibility, seeds=1, seed=0, placement=options, alternatives=2)


def test_plan_command_with_intent(tmp_path, capsys):
    import closure_nlp.cli.main as main_module

    out = tmp_path / "plan"
    args = ["plan", str(BLOCK), "--contacts", "4", "--type", "pcwf", "--mu", "0.3", "--seeds", "1"]
    args += ["--fixed", str(base_file(tmp_path)), "--exclude", "facing:+z", "--min-spacing", "5"]
    assert main_module.main([*args, "--json", "--out", str(out)]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["fixed"] == {"count": 3, "elements": payload["fixed"]["elements"]}
    assert payload["min_spacing"] == 5.0 and payload["excluded"]
    assert main_module.main(["rho", str(out / "contacts.json"), "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    lo, hi = payload["placement"]["bounds"]
    assert again["bounds"][0] <= hi and lo <= again["bounds"][1]
    written = json.loads((out / "contacts.json").read_text())["contacts"]
    assert [c["position"] for c in written[:3]] == BASE and all(c["fixed"] for c in written[:3])


def test_ceiling_holds_the_fixed_contacts_and_the_spacing(planned):
    from closure_nlp.placement.ceiling import Piece, _room

    placed = planned[1].placement
    assert placed.capacity_bound >= -placed.bounds[1] * (1 - 1e-9)  # a ceiling, fixed included
    point = Piece(0, np.zeros((1, 3)), np.array([0.0, 0.0, 1.0]))
    near = Piece(1, np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]), np.array([1.0, 0, 0]))
    far = Piece(2, np.array([[9.0, 0, 0], [0, 9.0, 0], [0, 0, 9.0]]), np.array([1.0, 0, 0]))
    assert not _room(([point], [near]), 2.0, 1)  # wholly within 2 of the fixed point
    assert _room(([point], [near, far]), 2.0, 1)  # a piece of it lies far enough
    assert _room(([point], [point]), 2.0, 2)  # two fixed contacts: nothing to decide


@pytest.mark.parametrize("base_f_max", [1.0, 1000.0])
def test_opposite_faces_half_circle_of_minima(block, tmp_path, base_f_max):
    """Two PCwF on each of two opposite faces above three locators: every force-only direction
    with ``u_y = -mu / sqrt(1 + mu^2)`` and ``u_z <= 0`` (a half circle) meets the -y face's cones
    on their edge, so ``min p = 4 mu / sqrt(1 + mu^2)`` (analytic, f_max 1) on a continuum of
    directions; the locators push no such direction, whatever their f_max. The certified bracket
    holds that value within its gap, relative to the larger of |rho| and the set's scale (the
    locators' f_max 1000 makes that scale 1000x the new contacts')."""
    from closure_nlp.base.tolerances import Tolerances
    from closure_nlp.criterion.certificate import tolerance_unit
    from closure_nlp.criterion.support_minimum import SupportMinimizer

    mu, certify = 0.3, 1e-4  # looser than the default 1e-6: the cells along the half circle
    exact = -4.0 * mu / np.sqrt(1.0 + mu**2)
    eligibility = Eligibility(
        block,
        contact_specs(4, type="pcwf", mu=mu),
        minimizer=SupportMinimizer(tolerances=Tolerances(certify=certify)),
        fixed=base_file(tmp_path, defaults={"type": "fpc", "f_max": base_f_max}),
    )
    elements = [0, 0, 66, 66]  # the -y and +y faces
    assert [block.elements[e].inward_normal[1] for e in elements] == [1.0, 1.0, -1.0, -1.0]
    result = eligibility(elements)
    lo, hi = result.bounds
    unit = tolerance_unit(eligibility.slots(elements))
    assert result.converged and result.eligible
    assert lo <= exact <= hi and hi - lo <= certify * max(abs(lo), unit)
    slots = eligibility.slots(elements)
    uy = -mu / np.sqrt(1.0 + mu**2)
    phi = np.linspace(np.pi, 2.0 * np.pi, 7)
    r = np.sqrt(1.0 - uy**2)
    arc = np.c_[r * np.cos(phi), np.full_like(phi, uy), r * np.sin(phi), np.zeros((7, 3))]
    assert np.allclose(slots.support(arc), -exact, rtol=1e-12)
