"""Inputs and outputs against the file system: special files refused before they are opened,
reading bounded, folders replaced so that a kill at any step leaves the old set or the new one,
outputs that never replace a device, a FIFO or a socket."""

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import closure_nlp.base.files as files
import closure_nlp.cli.main as cli
from closure_nlp.base.files import (
    MAX_INPUT_BYTES,
    check_input,
    load_json,
    read_input,
    recover_folder,
    staged_folder,
    write_atomic,
)

ROOT = Path(__file__).resolve().parents[1]
BOX = ROOT / "examples" / "box_7fpc.contacts.json"
LAMP = ROOT / "models" / "lamp.model.json"


def run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _fifo(folder: Path) -> Path:
    path = folder / "in.fifo"
    os.mkfifo(path)
    return path


def _sparse(folder: Path, size: int = 2 * 2**30) -> Path:
    path = folder / "sparse.contacts.json"
    with path.open("wb") as handle:
        handle.truncate(size)
    return path


SPECIAL_INPUTS = {
    "fifo": (_fifo, "is a FIFO (named pipe), not a regular file"),
    "dev_zero": (lambda d: Path("/dev/zero"), "is a character device, not a regular file"),
    "dev_urandom": (lambda d: Path("/dev/urandom"), "is a character device, not a regular file"),
    "sparse_2GiB": (_sparse, "file of 2 GiB is over the 256 MiB limit for input files"),
    "folder": (lambda d: d, "is a folder, not a regular file"),
}


@pytest.mark.parametrize("name", SPECIAL_INPUTS)
def test_special_inputs_are_refused_at_once_by_the_helper(tmp_path, name):
    make, needle = SPECIAL_INPUTS[name]
    path = make(tmp_path)
    t0 = time.monotonic()
    for call in (check_input, read_input, load_json):
        with pytest.raises(ValueError, match="^" + re.escape(needle)):
            call(path)
    assert time.monotonic() - t0 < 5.0  # refused before any reading (a FIFO would block)


def _command(kind: str, path: Path, folder: Path) -> list:
    return {
        "rho": ["rho", path],
        "eligibility": ["eligibility", path, "--elements", "0,1,2,3"],
        "plan": ["plan", path, "--contacts", "4"],
        "characterize": ["characterize", path, "--out", folder / "o.model.json"],
        "study": ["study", path, "--out", folder / "out", "--limit", "0"],
        "show --contacts": ["show", LAMP, "--contacts", path, "--out", folder / "x.png"],
    }[kind]


@pytest.mark.parametrize(
    "command", ["rho", "eligibility", "plan", "characterize", "study", "show --contacts"]
)
@pytest.mark.parametrize("name", ["fifo", "dev_zero", "sparse_2GiB"])
def test_every_command_refuses_special_inputs_at_once(tmp_path, command, name):
    """In a child process with a time limit: before the check, a FIFO blocked forever and
    /dev/zero filled the memory."""
    make, needle = SPECIAL_INPUTS[name]
    path = make(tmp_path)
    if command == "characterize" and name == "sparse_2GiB":
        path = path.rename(tmp_path / "sparse.stl")
        needle = needle.replace("256 MiB", "1 GiB")
    argv = [sys.executable, "-m", "closure_nlp.cli", *map(str, _command(command, path, tmp_path))]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines() == [f"error: {path}: {needle}"]
    assert proc.stdout == ""


def test_input_limit_is_what_the_docs_say():
    assert MAX_INPUT_BYTES == 256 * 2**20 and files.MAX_MESH_BYTES == 2**30


def test_a_symlink_to_a_regular_file_is_read(tmp_path):
    link = tmp_path / "box.contacts.json"
    link.symlink_to(BOX)
    assert load_json(link) == load_json(BOX)


def test_a_file_swapped_for_a_fifo_after_the_check_is_refused_on_the_open_file(
    tmp_path, monkeypatch
):
    fifo = _fifo(tmp_path)
    monkeypatch.setattr(files, "check_input", lambda path, limit=0: Path(path))
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="FIFO"):
        read_input(fifo)
    assert time.monotonic() - t0 < 5.0


def test_a_file_that_grows_past_the_limit_while_read_is_refused(tmp_path):
    path = tmp_path / "x.json"
    path.write_text("[1, 2, 3]")
    with pytest.raises(ValueError, match="over the 4 bytes limit"):
        read_input(path, limit=4)


def test_a_duplicate_key_is_refused_naming_it(tmp_path, capsys):
    path = tmp_path / "dup.contacts.json"
    text = BOX.read_text()
    path.write_text('{"contacts": [], ' + text.lstrip()[1:])
    code, out, err = run(capsys, "rho", path)
    assert code == 2 and out == ""
    assert err == f"error: {path}: duplicate key 'contacts' in one object\n"


# --- folder outputs: the old set survives a fault at every step -----------------------------

STEPS_EXCHANGE = ["staged", "written", "exchanged"]
STEPS_RENAMES = ["staged", "written", "moved-old", "moved-new"]


def _old_set(out: Path) -> None:
    out.mkdir()
    (out / "report.json").write_text("old")


def _kill_at(out: Path, step: str, exchange: bool) -> int:
    """Write a new set into ``out`` in a child process that kills itself (SIGKILL: no cleanup)
    when ``staged_folder`` reaches ``step``."""
    code = (
        "import os, signal, sys\n"
        "import closure_nlp.base.files as files\n"
        "step = sys.argv[2]\n"
        "if sys.argv[3] == 'renames':\n"
        "    files._RENAMEAT2 = None\n"
        "def hook(name):\n"
        "    if name == step:\n"
        "        os.kill(os.getpid(), signal.SIGKILL)\n"
        "files._step_hook = hook\n"
        "with files.staged_folder(sys.argv[1]) as staged:\n"
        "    (staged / 'report.json').write_text('new')\n"
        "    (staged / 'summary.md').write_text('new')\n"
        "sys.exit(5)\n"
    )
    mode = "exchange" if exchange else "renames"
    proc = subprocess.run(
        [sys.executable, "-c", code, str(out), step, mode],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        timeout=60,
    )
    return proc.returncode


def _state(out: Path) -> str:
    if not out.exists():
        return "missing"
    names = sorted(p.name for p in out.iterdir())
    if names == ["report.json"] and (out / "report.json").read_text() == "old":
        return "old"
    if names == ["report.json", "summary.md"]:
        return "new"
    return f"mixed: {names}"


@pytest.mark.skipif(files._RENAMEAT2 is None, reason="no renameat2 on this system")
@pytest.mark.parametrize("step", STEPS_EXCHANGE)
def test_a_kill_at_each_step_of_an_exchange_leaves_the_old_or_the_new_set(tmp_path, step):
    out = tmp_path / "run"
    _old_set(out)
    assert _kill_at(out, step, exchange=True) == -signal.SIGKILL
    assert _state(out) == ("new" if step == "exchanged" else "old")  # at once, no recovery
    with staged_folder(out) as staged:  # the next run cleans up what the killed one left
        (staged / "report.json").write_text("old")
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


@pytest.mark.parametrize("step", STEPS_RENAMES)
def test_a_kill_at_each_step_of_two_renames_is_recovered_to_the_old_or_the_new_set(tmp_path, step):
    out = tmp_path / "run"
    _old_set(out)
    assert _kill_at(out, step, exchange=False) == -signal.SIGKILL
    expected = "new" if step == "moved-new" else "old"
    if step == "moved-old":
        assert _state(out) == "missing"  # between the renames: the old set is beside it
    recover_folder(out)
    assert _state(out) == expected
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


@pytest.mark.parametrize("exchange", [True, False])
@pytest.mark.parametrize("step", sorted(set(STEPS_EXCHANGE + STEPS_RENAMES)))
def test_an_exception_at_each_step_leaves_one_whole_set(tmp_path, monkeypatch, step, exchange):
    out = tmp_path / "run"
    _old_set(out)
    if not exchange:
        monkeypatch.setattr(files, "_RENAMEAT2", None)

    def hook(name):
        if name == step:
            raise RuntimeError(f"fault at {name}")

    monkeypatch.setattr(files, "_step_hook", hook)
    reached = True
    try:
        with staged_folder(out) as staged:
            (staged / "report.json").write_text("new")
            (staged / "summary.md").write_text("new")
    except RuntimeError:
        pass
    else:
        reached = False  # this path has no such step
    after = {"exchanged", "moved-new"}
    assert _state(out) == ("new" if step in after or not reached else "old")
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_a_new_folder_killed_before_its_rename_leaves_nothing_behind(tmp_path):
    out = tmp_path / "fresh"
    assert _kill_at(out, "written", exchange=True) == -signal.SIGKILL
    recover_folder(out)
    assert list(tmp_path.iterdir()) == []


# --- outputs never replace special files -----------------------------------------------------


def _special_outputs(folder: Path) -> dict:
    fifo = folder / "out.fifo"
    os.mkfifo(fifo)
    sock_path = folder / "out.sock"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    made = {"fifo": (fifo, "a FIFO (named pipe)"), "socket": (sock_path, "a socket")}
    null = folder / "null"
    try:
        os.mknod(null, 0o666 | 0o020000, os.makedev(1, 3))  # a copy of /dev/null
        made["device"] = (null, "a character device")
    except PermissionError:  # not root: the system's own device stands in
        made["device"] = (Path("/dev/null"), "a character device")
    return made


@pytest.mark.parametrize("kind", ["fifo", "socket", "device"])
def test_place_and_show_and_characterize_refuse_a_special_out(tmp_path, capsys, kind):
    path, words = _special_outputs(tmp_path)[kind]
    before = os.stat(path)
    for argv in (
        ["place", LAMP, "--elements", "0,1,2,3", "--out", path],
        ["show", LAMP, "--out", path],
        ["characterize", ROOT / "models" / "cup.stl", "--out", path],
    ):
        code, out, err = run(capsys, *argv)
        assert code == 2 and out == "", err
        assert err == f"error: {path}: --out: exists and is {words}, not a regular file\n"
    after = os.stat(path)
    assert (after.st_mode, after.st_ino, after.st_rdev) == (
        before.st_mode,
        before.st_ino,
        before.st_rdev,
    )


@pytest.mark.parametrize("kind", ["fifo", "socket", "device"])
def test_write_atomic_never_replaces_a_special_file(tmp_path, kind):
    path, words = _special_outputs(tmp_path)[kind]
    with pytest.raises(ValueError, match=re.escape(f"exists and is {words}")):
        write_atomic(path, "{}")
    assert not Path(path).is_file()


def test_write_atomic_replaces_a_regular_file_through_a_symlink_as_a_regular_file(tmp_path):
    target = tmp_path / "x.json"
    target.write_text("old")
    write_atomic(target, "new")
    assert target.read_text() == "new" and target.is_file()
