"""Output paths are checked before any work; a plan's folder is written as one set."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import closure_nlp.cli.main as cli
from closure_nlp.base.files import staged_folder
from closure_nlp.cli import place_command, plan_command
from closure_nlp.model.elements import save_model
from closure_nlp.report import drawing

from .shapes import box_model

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def box_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("box") / "box.model.json"
    save_model(box_model(), path)
    return str(path)


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def no_work(monkeypatch):
    """Any planning or placement work fails the test: the checks must come first."""

    def forbidden(*args, **kwargs):
        raise AssertionError("work started before the output path was checked")

    monkeypatch.setattr(plan_command, "plan", forbidden)
    monkeypatch.setattr(place_command, "Placer", forbidden)
    monkeypatch.setattr(drawing, "save_view", forbidden)


@pytest.mark.parametrize(
    "make,needle",
    [
        (lambda d: (d / "f").write_text("x") and d / "f", "exists and is not a folder"),
        (lambda d: (d / "f").write_text("x") and d / "f" / "sub", "which is a file"),
        (lambda d: Path("/proc/closure_nlp/out"), "cannot write"),
        (
            lambda d: (d / "o").mkdir() or (d / "o" / "mine.txt").write_text("x") and d / "o",
            "holds other files",
        ),
    ],
)
def test_plan_out_refused_before_any_work(tmp_path, capsys, box_file, no_work, make, needle):
    out = make(tmp_path)
    code, stdout, err = run(capsys, "plan", box_file, "--contacts", "4", "--out", out)
    assert code == 2 and stdout == ""
    assert err.startswith(f"error: {out}: --out: ") and needle in err
    assert len(err.splitlines()) == 1


def test_place_and_show_out_refused_before_any_work(tmp_path, capsys, box_file, no_work):
    (tmp_path / "f").write_text("x")
    code, _, err = run(capsys, "place", box_file, "--elements", "0,1,2,3", "--out", tmp_path)
    assert code == 2 and "is a folder, not a file" in err
    code, _, err = run(capsys, "show", box_file, "--out", tmp_path / "f" / "x.png")
    assert code == 2 and "which is a file" in err


@pytest.mark.slow  # one real plan (~10-25 s)
def test_plan_rerun_replaces_the_whole_set(tmp_path, capsys, box_file):
    out = tmp_path / "run"
    out.mkdir()
    (out / "report.json").write_text('{"old": true}')
    (out / "stale.png").write_text("from an older version")
    code, stdout, err = run(
        capsys,
        "plan",
        box_file,
        "--contacts",
        "4",
        "--type",
        "pcwf",
        "--mu",
        "0.5",
        "--seeds",
        "1",
        "--starts",
        "1",
        "--alternatives",
        "0",
        "--out",
        out,
        "--json",
    )
    assert code == 0, err
    written = json.loads(stdout)["out"]
    assert sorted(p.name for p in out.iterdir()) == sorted(written)
    assert "old" not in json.loads((out / "report.json").read_text())
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no temporary folder left


def test_staged_folder_exception_leaves_the_old_set(tmp_path):
    out = tmp_path / "set"
    out.mkdir()
    (out / "report.json").write_text("old")
    with pytest.raises(RuntimeError), staged_folder(out) as staged:
        (staged / "report.json").write_text("new")
        raise RuntimeError("killed midway")
    assert (out / "report.json").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["set"]


def test_temporary_folder_of_a_killed_run_is_removed_by_the_next(tmp_path):
    out = tmp_path / "set"
    code = (
        "import os, signal, sys\n"
        "from closure_nlp.base.files import staged_folder\n"
        "with staged_folder(sys.argv[1]) as staged:\n"
        "    (staged / 'report.json').write_text('partial')\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, str(out)],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=60,
    )
    assert proc.returncode == -signal.SIGKILL
    left = [p.name for p in tmp_path.iterdir()]
    assert not out.exists() and len(left) == 1 and left[0].startswith(".set.partial-")
    with staged_folder(out) as staged:
        (staged / "report.json").write_text("complete")
    assert [p.name for p in tmp_path.iterdir()] == ["set"]
    assert (out / "report.json").read_text() == "complete"


def test_temporary_file_of_a_killed_write_is_removed_by_the_next(tmp_path):
    from closure_nlp.base.files import write_atomic

    stale = tmp_path / ".x.json.partial-999999999-abc.tmp"  # no such process
    stale.write_text("half")
    write_atomic(tmp_path / "x.json", "{}")
    assert [p.name for p in tmp_path.iterdir()] == ["x.json"]
