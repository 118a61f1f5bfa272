"""Study limits are checked before the grid is built; Ctrl-C on a study is one line, exit 130."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import closure_nlp.cli.main as cli
from closure_nlp.base.validation import MAX_STUDY_TASKS

ROOT = Path(__file__).resolve().parents[1]
LAMP = ROOT / "models" / "lamp.model.json"


def study(tmp_path, body: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(f'models = ["{LAMP.as_posix()}"]\ncontacts = 4\n{body}\n')
    return path


@pytest.mark.parametrize(
    "body,needle",
    [
        ("seeds = 1_000_000_000_000", "over the limit of 100,000"),
        ("seeds = 10_000_000", "over the limit of 100,000"),
        (f"seeds = {MAX_STUDY_TASKS // 3 + 1}\nmu = [0.1, 0.2, 0.3]\n", "over the limit"),
        ("seeds = [0, 9223372036854775808]", "seeds[1]: a seed must be <= 2**63 - 1"),
        ("seeds = true", "seeds: expected a count"),
        ("mu = 1e300", "mu: must be <= 1e+06 (accepted range"),
        ("f_max = 1e-20", "f_max: must be >= 1e-12"),
        ("torque_scale = [1.0, 1e16]", "torque_scale[1]: must be <= 1e+15"),
        ("contacts = 1000", "limit 1..32"),
    ],
)
def test_study_limits_refused_at_once(tmp_path, capsys, body, needle):
    path = study(tmp_path, body)
    if body.startswith("contacts"):  # replaces the count of 4
        path.write_text(f'models = ["{LAMP.as_posix()}"]\n{body}\n')
    t0 = time.perf_counter()
    code = cli.main(["study", str(path), "--out", str(tmp_path / "out"), "--limit", "0"])
    _, err = capsys.readouterr()
    assert code == 2 and err.startswith(f"error: {path}: ") and needle in err, err
    assert time.perf_counter() - t0 < 10.0  # no grid of millions was built first
    assert not (tmp_path / "out").exists()


def test_study_out_under_a_file_refused(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    code = cli.main(["study", str(study(tmp_path, "seeds = 1")), "--out", str(tmp_path / "f")])
    _, err = capsys.readouterr()
    assert code == 2 and "--out: exists and is not a folder" in err


@pytest.mark.slow
def test_ctrl_c_on_a_study_keeps_finished_tasks(tmp_path):
    path = study(tmp_path, "seeds = 6\n[placement]\nstarts = 1")
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "closure_nlp.cli",
            "study",
            str(path),
            "--out",
            str(out),
            "--workers",
            "1",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"},
        start_new_session=True,  # Ctrl-C reaches the whole process group, workers included
    )
    deadline = time.time() + 300
    while time.time() < deadline and not list((out / "results").glob("*.parquet")):
        time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130 and stdout == ""
    assert stderr.splitlines() == ["interrupted: stopped by Ctrl-C; finished output is kept"]
    assert list((out / "results").glob("*.parquet"))  # the finished task is kept
