"""Where contacts may go: regions of elements (ids, facing an axis, inside a box), and no step
of selection or placement using an excluded element."""

import json

import numpy as np
import pytest

import closure_nlp.cli.main as cli
from closure_nlp import Eligibility, PlacementOptions, contact_specs, plan, save_model
from closure_nlp.model.regions import excluded_elements, region, with_exclusions
from tests.shapes import box_model

# box_model's facets, by index: outward -x, +x, -y, +y, -z, +z
TOP = 5


@pytest.fixture(scope="module")
def box():
    return box_model(10.0)


@pytest.mark.parametrize(
    "spec,ids",
    [
        ("ids:0,2-4", {0, 2, 3, 4}),
        ("ids: 5", {5}),
        ("facing:+z", {5}),
        ("facing:-x", {0}),
        ("facing:z", {5}),
        ("facing:0,0,2:10", {5}),
        ("facing:1,1,0:46", {1, 3}),  # 45 degrees from +x and from +y
        ("facing:1,1,0:44", set()),
        ("box:-11,-11,9,11,11,11", {5}),
        ("box:11,11,11,-11,-11,-11", {0, 1, 2, 3, 4, 5}),  # corners in any order
        ([1, 2], {1, 2}),
    ],
)
def test_regions(box, spec, ids):
    assert region(box, spec) == ids


@pytest.mark.parametrize(
    "spec,needle",
    [
        ("nope:1", "nope:1"),
        ("ids:5-2", "5-2"),
        ("ids:99", "99"),
        ("ids:a", "'a'"),
        ("facing:+w", "+w"),
        ("facing:0,0,0", "0,0,0"),
        ("facing:+z:200", "200"),
        ("box:1,2,3", "1,2,3"),
        ("box:0,0,0,1,1,nan", "nan"),
        ("facing", "facing"),
    ],
)
def test_a_bad_region_names_itself(box, spec, needle):
    with pytest.raises(ValueError, match="exclude") as caught:
        excluded_elements(box, exclude=[spec])
    assert needle in str(caught.value)


def test_only_regions_are_united_then_exclusions_removed(box):
    only = ["facing:+z", "facing:-z", "ids:0"]
    assert excluded_elements(box, only=only, exclude="ids:4") == (1, 2, 3, 4)
    assert excluded_elements(box) == ()
    kept = with_exclusions(box, exclude="facing:+z")
    assert kept.unusable == (TOP,) and len(kept) == len(box)  # ids kept: the same part
    assert TOP not in kept.neighbours(0)


def test_the_whole_parts_scale_is_kept(box):
    specs = contact_specs(4, type="sfce", mu=0.4, model=box)
    whole = Eligibility(box, specs)
    part = Eligibility(box, specs, exclude=["facing:+z", "facing:+x"])
    assert part.torque_scale == whole.torque_scale and part.excluded == (1, TOP)
    with pytest.raises(ValueError, match="excluded"):
        part([TOP, 0, 2, 3])


def test_no_step_of_a_plan_uses_an_excluded_element(box):
    """Heuristic, iterative neighbours, placement neighbour moves, alternatives and the
    ceiling's domain, on a box whose top may hold no contact."""
    specs = contact_specs(4, type="pcwf", mu=0.4)
    hand = Eligibility(box, specs, torque_scale=0.1, exclude="facing:+z")
    options = PlacementOptions(starts=1, extra_starts=0, bound=True, bound_cells=20)
    for seed in (1, 2, 3):
        run = plan(hand, seeds=1, seed=seed, placement=options, alternatives=2)
        used = {*run.heuristic.elements, *run.iterative.elements, *run.placement.elements}
        used |= {e for a in run.attempts for e in a.elements}
        used |= {m.target for m in run.placement.moves}
        assert TOP not in used
        assert run.placement.force_closure  # four faces with friction still hold the box


def _run(capsys, *argv):
    code = cli.main([*map(str, argv), "--json", "--quiet"])
    out, err = capsys.readouterr()
    return code, out, err


def test_the_command_line_lists_and_checks_exclusions(tmp_path, capsys, box):
    path = tmp_path / "box.model.json"
    save_model(box, path)
    code, out, _ = _run(capsys, "select", path, "--contacts", 4, "--mu", 0.4, "--exclude", "ids:5")
    assert code == 0 and json.loads(out)["excluded"] == [TOP]
    assert TOP not in json.loads(out)["elements"]
    code, _, err = _run(capsys, "select", path, "--contacts", 4, "--exclude", "sideways:5")
    assert code == 2 and "sideways:5" in err
    code, _, err = _run(capsys, "place", path, "--elements", "5,0,2,4", "--exclude", "ids:5")
    assert code == 2 and "5" in err and "excluded" in err
    code, _, err = _run(capsys, "select", path, "--contacts", 4, "--only", "ids:0")
    assert code == 2 and "--only" in err


def test_unit_axis_and_box_follow_the_models_frame():
    model = box_model(np.array([30.0, 20.0, 10.0]))
    assert region(model, "box:-31,-21,-11,31,21,-9") == {4}
    assert region(model, "facing:-z") == {4}
