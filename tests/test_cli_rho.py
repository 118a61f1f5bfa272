"""`closure-nlp rho` end to end: output keys, several files, the error contract."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.bench import ring as ring_set
from closure_nlp import load_contact_set
from closure_nlp.cli.main import main
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import tolerance_unit

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "box_7fpc.contacts.json"


def run(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_json_keys_and_several_files(tmp_path, capsys):
    other = tmp_path / "two.contacts.json"
    other.write_text(
        json.dumps(
            {
                "contacts": [
                    {"position": [0, 0, 1], "inward_normal": [0, 0, -1]},
                    {"position": [0, 0, -1], "inward_normal": [0, 0, 1]},
                ]
            }
        )
    )
    code, out, err = run(["rho", str(EXAMPLE), str(other), "--json"], capsys)
    assert code == 0 and err == ""
    lines = [json.loads(line) for line in out.splitlines()]
    assert [d["file"] for d in lines] == [str(EXAMPLE), str(other)]
    box, pair = lines
    assert box["force_closure"] is True and box["rho"] < 0 and len(box["direction"]) == 6
    assert pair["force_closure"] is False and pair["rho"] == 0.0


def test_text_output(capsys):
    code, out, _ = run(["rho", str(EXAMPLE)], capsys)
    assert code == 0 and "force closure" in out and "rho = -" in out


@pytest.mark.parametrize(
    "content,needle",
    [
        ("{not json", "malformed JSON"),
        ('{"contacts": []}', "contacts"),
        ('{"contacts": [{"position": [0, 0, NaN], "inward_normal": [0, 0, 1]}]}', "position"),
        ('{"contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 0]}]}', "inward_normal"),
        ('{"contacts": [{"position": [0, 0], "inward_normal": [0, 0, 1]}]}', "position"),
        (
            '{"contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 1], "type": "glue"}]}',
            "type",
        ),
        ('{"contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 1], "mu": -1}]}', "mu"),
        ('{"contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 1], "mu_s": -1}]}', "mu_s"),
        (
            '{"contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 1], "f_max": -1}]}',
            "f_max",
        ),
        (
            '{"torque_scale": 0, "contacts": [{"position": [0, 0, 0], "inward_normal": [0, 0, 1]}]}',  # noqa: E501
            "torque_scale",
        ),
    ],
)
def test_bad_input_exits_2_with_one_error_line_and_no_output(tmp_path, capsys, content, needle):
    bad = tmp_path / "bad.contacts.json"
    bad.write_text(content)
    # The good file comes first: nothing may be printed for it either.
    code, out, err = run(["rho", str(EXAMPLE), str(bad), "--json"], capsys)
    assert code == 2
    assert out == ""
    assert err.startswith("error: ") and str(bad) in err and needle in err
    assert len(err.strip().splitlines()) == 1


def test_missing_file(capsys):
    code, out, err = run(["rho", "/nonexistent/x.json"], capsys)
    assert code == 2 and out == "" and "not found" in err


def test_bad_flag_exits_2_without_traceback():
    proc = subprocess.run(
        [sys.executable, "-m", "closure_nlp.cli", "rho", "--frobnicate", str(EXAMPLE)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error:") and "Traceback" not in proc.stderr


def test_seconds_is_the_whole_cost_with_its_parts(capsys):
    """``seconds`` covers the search and the certificate; ``timing`` names both parts."""
    code, out, _ = run(["rho", str(EXAMPLE), "--json"], capsys)
    answer = json.loads(out)
    parts = answer["timing"]
    assert code == 0 and set(parts) == {"search", "certificate"}
    assert parts["search"] > 0 and parts["certificate"] > 0
    assert answer["seconds"] == pytest.approx(parts["search"] + parts["certificate"], rel=1e-9)


def test_timing_search_is_the_search_alone(capsys, monkeypatch):
    """``timing.search`` is the result's own search time, not the search and certificate."""
    import dataclasses

    from closure_nlp.cli import rho_command

    real = rho_command.rho

    def timed(*args, **kwargs):
        result = real(*args, **kwargs)
        return dataclasses.replace(result, timing=(1e-6, 5.0))

    monkeypatch.setattr(rho_command, "rho", timed)
    code, out, _ = run(["rho", str(EXAMPLE), "--json"], capsys)
    parts = json.loads(out)["timing"]
    assert code == 0 and parts["search"] == 1e-6


def test_tol_widens_the_bracket_and_its_digits(capsys):
    code, out, _ = run(["rho", str(EXAMPLE), "--json"], capsys)
    fine = json.loads(out)
    code, out, _ = run(["rho", str(EXAMPLE), "--json", "--tol", "1e-2"], capsys)
    assert code == 0
    wide = json.loads(out)
    (lo, hi), (fine_lo, fine_hi) = wide["bounds"], fine["bounds"]
    assert hi - lo > 100 * (fine_hi - fine_lo)  # the search stopped sooner
    unit = tolerance_unit(WrenchSlots.from_contacts(load_contact_set(EXAMPLE)))
    assert hi - lo <= 1e-2 * max(abs(lo), abs(hi), unit) * (1 + 1e-9)
    assert max(lo, fine_lo) <= min(hi, fine_hi)  # both hold rho
    assert wide["force_closure"] is True
    # the default asked for explicitly is the default, to the bit
    code, out, _ = run(["rho", str(EXAMPLE), "--json", "--tol", "1e-6"], capsys)
    same = json.loads(out)
    assert same["bounds"] == fine["bounds"] and same["direction"] == fine["direction"]
    # the text prints only the digits the bracket pins down
    code, out, _ = run(["rho", str(EXAMPLE), "--tol", "1e-2"], capsys)
    assert "rho = -0.09 (force closure)" in out


@pytest.mark.parametrize("value", ["0", "0.5", "nan", "-1e-3", "1e-3x"])
def test_bad_tol_exits_2_naming_it(value, capsys):
    code, out, err = run(["rho", str(EXAMPLE), "--tol", value], capsys)
    assert code == 2 and out == "" and "--tol" in err and "Traceback" not in err


def _without_times(line: str) -> dict:
    answer = json.loads(line)
    for key in ("seconds", "timing"):
        answer.pop(key)
    return answer


def test_workers_change_no_answer_of_one_file_or_several(tmp_path, capsys):
    # Four soft fingers round a ring: a long certificate, whose rounds one file's run deals to
    # two threads with --workers 2.
    ring = tmp_path / "ring.contacts.json"
    ring.write_text(json.dumps(ring_set("sfce", 4).to_dict()))
    for files in ([ring], [ring, EXAMPLE]):
        answers = []
        for workers in ("1", "2"):
            code, out, err = run(["rho", *map(str, files), "--json", "--workers", workers], capsys)
            assert code == 0 and err == ""
            answers.append([_without_times(line) for line in out.splitlines()])
        assert answers[0] == answers[1] and len(answers[0]) == len(files)
    assert answers[0][0]["force_closure"] and answers[0][0]["converged"]
