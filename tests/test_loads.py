"""LOADS.json: the cases' wrenches and the error contract."""

import json

import numpy as np
import pytest

from closure_nlp.contact.loads import as_loads, load_loads

EXAMPLE = {
    "units": {"force": "N"},
    "loads": [
        {"name": "cut_x", "force": [200, 0, 0], "point": [0, 0, 10]},
        {
            "name": "with_gravity",
            "components": [
                {"force": [0, 150, 0], "point": [-10, 0, 10]},
                {"force": [0, 0, -1.2], "point": [-1.8, 0, 0], "torque": [0, 0, 3]},
            ],
        },
        {"name": "at_reference", "force": [0, 0, -5]},
    ],
}


def test_wrenches_about_the_reference_point(tmp_path):
    path = tmp_path / "loads.json"
    path.write_text(json.dumps(EXAMPLE))
    loads = load_loads(path)
    assert [c.name for c in loads.cases] == ["cut_x", "with_gravity", "at_reference"]
    assert loads.force_unit == "N"
    ref, ts = np.array([1.0, 2.0, 3.0]), 0.1
    W = loads.wrenches(ref, ts)
    # force at a point: F, then ts * ((p - ref) x F)
    np.testing.assert_allclose(W[0], [200, 0, 0, *(ts * np.cross([-1, -2, 7], [200, 0, 0]))])
    moment = (
        np.cross([-11, -2, 7], [0, 150, 0]) + np.cross([-2.8, -2, -3], [0, 0, -1.2]) + [0, 0, 3]
    )
    np.testing.assert_allclose(W[1], [0, 150, -1.2, *(ts * moment)])
    # no point: applied at the reference point, no moment
    np.testing.assert_allclose(W[2], [0, 0, -5, 0, 0, 0])
    assert as_loads(loads.to_dict()).wrenches(ref, ts).tolist() == W.tolist()
    for given in (path, str(path)):  # the API takes the file's path as the command line does
        assert as_loads(given).wrenches(ref, ts).tolist() == W.tolist()


@pytest.mark.parametrize(
    "data,needle",
    [
        ({"loads": [{"name": "a", "force": [0, 0, float("nan")]}]}, "loads[0].force"),
        ({"loads": [{"name": "a", "force": [0, 0, 0]}]}, "is zero"),
        (
            {
                "loads": [
                    {
                        "name": "a",
                        "components": [
                            {"force": [1, 0, 0], "point": [0, 0, 0]},
                            {"force": [-1, 0, 0], "point": [0, 0, 0]},
                        ],
                    }
                ]
            },
            "is zero",
        ),
        ({"loads": [{"name": "a", "force": [1, 0, 0], "where": 1}]}, "unknown key 'where'"),
        ({"loads": [{"force": [1, 0, 0]}]}, "missing key 'name'"),
        ({"loads": [{"name": "", "force": [1, 0, 0]}]}, "loads[0].name"),
        (
            {"loads": [{"name": "a", "force": [1, 0, 0]}, {"name": "a", "force": [0, 1, 0]}]},
            "duplicate name 'a'",
        ),
        ({"loads": [{"name": "a", "force": [1, 0]}]}, "expected 3 numbers"),
        ({"loads": [{"name": "a", "force": [1, 0, 0], "point": [0, 0]}]}, "loads[0].point"),
        ({"loads": [{"name": "a", "force": [1, 0, 0], "torque": "x"}]}, "loads[0].torque"),
        ({"loads": [{"name": "a", "components": []}]}, "loads[0].components"),
        ({"loads": [{"name": "a", "components": [{"point": [0, 0, 0]}]}]}, "missing key 'force'"),
        ({"loads": []}, "loads"),
        ({"load": []}, "unknown key 'load'"),
        ({"units": {"length": "mm"}, "loads": [{"name": "a", "force": [1, 0, 0]}]}, "units"),
    ],
)
def test_bad_loads_name_the_field(data, needle):
    with pytest.raises((ValueError, TypeError)) as info:
        as_loads(data)
    assert needle in str(info.value)
