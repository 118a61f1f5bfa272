"""Faults of the environment end with exit 1 and one ``error:`` line (never exit 3, never a
lost answer with exit 0); a malformed scheduler address is bad input (exit 2); names in
messages are shown with their control characters escaped."""

import errno
import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import closure_nlp.cli.main as cli

ROOT = Path(__file__).resolve().parents[1]
BOX = ROOT / "examples" / "box_7fpc.contacts.json"
LAMP = ROOT / "models" / "lamp.model.json"
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}


def child(*argv, env=None, **options):
    """The command line in a child process (stdout set up by ``options``)."""
    return subprocess.run(
        [sys.executable, "-m", "closure_nlp.cli", *map(str, argv)],
        stderr=subprocess.PIPE,
        text=True,
        timeout=300,
        env={**ENV, **(env or {})},
        **options,
    )


def test_stdout_on_a_full_device_is_a_failure():
    with open("/dev/full", "w") as full:
        proc = child("rho", BOX, stdout=full)
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == ["error: stdout: cannot write: No space left on device"]


def test_a_closed_stdout_is_a_failure_not_a_lost_answer():
    proc = child("rho", BOX, stdout=subprocess.DEVNULL, preexec_fn=lambda: os.close(1))
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == ["error: stdout: closed: nothing could be printed"]


def test_a_name_the_output_encoding_cannot_show(tmp_path):
    path = tmp_path / "caf\u00e9.contacts.json"
    shutil.copy(BOX, path)
    proc = child("rho", path, env={"PYTHONIOENCODING": "ascii"}, stdout=subprocess.PIPE)
    assert proc.returncode == 1 and proc.stdout == ""
    [line] = proc.stderr.splitlines()
    assert line.startswith("error: stdout: cannot print ") and "PYTHONIOENCODING=utf-8" in line
    proc = child("rho", path, "--json", env={"PYTHONIOENCODING": "ascii"}, stdout=subprocess.PIPE)
    assert proc.returncode == 0 and 'caf\\u00e9.contacts.json"' in proc.stdout


def test_names_with_control_characters_stay_on_one_line(tmp_path, capsys):
    for name, shown in (
        ("a\nb.contacts.json", "a\\nb.contacts.json"),
        ("red\x1b[31m.contacts.json", "red\\x1b[31m.contacts.json"),
    ):
        missing = tmp_path / ("gone-" + name)
        code = cli.main(["rho", str(missing)])
        out, err = capsys.readouterr()
        assert code == 2 and out == ""
        assert err == f"error: {tmp_path}/gone-{shown}: file not found\n"
        path = tmp_path / name
        shutil.copy(BOX, path)
        code = cli.main(["rho", str(path)])
        out, err = capsys.readouterr()
        assert code == 0 and len(out.splitlines()) == 1 and "\x1b" not in out
        assert out.startswith(f"{tmp_path}/{shown}: rho = ")


@pytest.mark.parametrize(
    "address",
    ["garbage", "tcp://host", "tcp://host:0", "ftp://host:1", "host:\uff18\uff17", "tcp://a b:1"],
)
def test_a_malformed_scheduler_address_is_bad_input(tmp_path, capsys, address):
    study = tmp_path / "s.toml"
    study.write_text(f'models = ["{LAMP.as_posix()}"]\ncontacts = 4\n')
    code = cli.main(["study", str(study), "--out", str(tmp_path / "out"), "--scheduler", address])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.startswith("error: closure-nlp study: argument --scheduler: expected") or (
        "unknown protocol" in err
    )
    assert len(err.splitlines()) == 1 and not (tmp_path / "out").exists()


def test_an_unreachable_scheduler_is_a_failure_of_the_environment(tmp_path):
    """In a child process: joining a scheduler starts threads that outlive the attempt (and
    would change how later tests in this process start their worker processes)."""
    study = tmp_path / "s.toml"
    study.write_text(f'models = ["{LAMP.as_posix()}"]\ncontacts = 4\n')
    code = (
        "import sys\n"
        "import closure_nlp.study.running as running\n"
        "from closure_nlp.cli.main import main\n"
        "running.CONNECT_SECONDS = 1\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    argv = [
        "study",
        study,
        "--out",
        tmp_path / "out",
        "--limit",
        "1",
        "--scheduler",
        "tcp://127.0.0.1:1",
    ]
    proc = subprocess.run(
        [sys.executable, "-c", code, *map(str, argv)],
        capture_output=True,
        text=True,
        timeout=300,
        env=ENV,
    )
    assert proc.returncode == 1 and proc.stdout == ""
    [line] = proc.stderr.splitlines()
    assert line.startswith("error: scheduler tcp://127.0.0.1:1: cannot connect: ")


def _file_size_limit(size: int):
    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))

    return limit


def test_characterize_onto_a_full_disk(tmp_path):
    """A file-size limit stands in for a full disk: writes fail with EFBIG (Python ignores
    SIGXFSZ), which the command must report as a fault of the system, not a bug."""
    out = tmp_path / "cup.model.json"
    out.write_text("old")
    proc = child(
        "characterize",
        ROOT / "models" / "cup.stl",
        "--out",
        out,
        stdout=subprocess.PIPE,
        preexec_fn=_file_size_limit(2000),
    )
    assert proc.returncode == 1, proc.stderr
    [line] = proc.stderr.splitlines()
    assert line.startswith(f"error: {out}: cannot write: File too large")
    assert out.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == [out.name]


def test_plan_out_onto_a_full_disk_keeps_the_old_report(tmp_path, capsys, monkeypatch):
    """The disk fills while the report is written (after the work): exit 1, one line, the
    previous report untouched."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "report.json").write_text("old")

    class Done:  # what plan returns, as far as the command reads it before writing
        force_closure = True

        def to_dict(self):
            return {"rho": -0.1}

    def full(model, result, staged, options, **_):
        (Path(staged) / "report.json").write_text("half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(Path(staged) / "x.png"))

    from closure_nlp.cli import plan_command

    monkeypatch.setattr(plan_command, "plan", lambda *a, **k: Done())
    monkeypatch.setattr(plan_command, "write_report", full)
    code = cli.main(["plan", str(LAMP), "--contacts", "4", "--out", str(out)])
    out_text, err = capsys.readouterr()
    assert code == 1 and out_text == ""
    [line] = err.splitlines()
    assert line.startswith("error: ") and line.endswith("x.png: No space left on device")
    assert (out / "report.json").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
