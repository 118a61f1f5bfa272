"""Exit status of the command line: 2 bad input, 1 method failure, 3 internal error, 130 Ctrl-C;
one line on stderr, never a traceback, never a non-finite number printed."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import closure_nlp.cli.main as cli
from closure_nlp.cli import rho_command
from closure_nlp.criterion.support_minimum import rho as real_rho

ROOT = Path(__file__).resolve().parents[1]
BOX = str(ROOT / "examples" / "box_7fpc.contacts.json")
LAMP = str(ROOT / "models" / "lamp.model.json")


def run(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def test_internal_error_is_not_bad_input(monkeypatch, capsys):
    def broken(*args, **kwargs):
        return None - 1.0  # the kind of bug the issue saw printed as "error: ..." with exit 2

    monkeypatch.setattr(rho_command, "rho", broken)
    code, out, err = run(capsys, "rho", BOX)
    assert code == 3 and out == ""
    line = one_line(err)
    assert line.startswith("internal error: TypeError: unsupported operand") and "bug" in line


def test_non_finite_result_is_a_method_failure_and_never_printed(monkeypatch, capsys):
    def nan_rho(*args, **kwargs):
        result = real_rho(*args, **kwargs)
        object.__setattr__(result, "rho", float("nan"))
        return result

    monkeypatch.setattr(rho_command, "rho", nan_rho)
    for extra in ([], ["--json"]):
        code, out, err = run(capsys, "rho", BOX, *extra)
        assert code == 1 and out == ""
        line = one_line(err)
        assert line.startswith(f"error: {BOX}: the method produced a non-finite rho")


def test_ctrl_c_in_process_is_one_line_130(monkeypatch, capsys):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(rho_command, "rho", interrupted)
    code, out, err = run(capsys, "rho", BOX)
    assert code == 130 and one_line(err).startswith("interrupted:")


def test_memory_error_is_a_method_failure(monkeypatch, capsys):
    def huge(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(rho_command, "rho", huge)
    code, _, err = run(capsys, "rho", BOX)
    assert code == 1 and "out of memory" in one_line(err)


def test_bad_flag_names_the_file_and_the_flag(capsys):
    code, out, err = run(capsys, "eligibility", LAMP, "--elements", "0,1,2,3", "--mu", "1e300")
    assert code == 2 and out == ""
    line = one_line(err)
    assert line.startswith(f"error: {LAMP}: contact options: contacts[0].mu: ")
    assert "accepted range" in line


def test_finished_work_is_printed_before_a_failure(tmp_path, capsys):
    # Several files: each answer is printed as it is found.
    code, out, _ = run(capsys, "rho", BOX, BOX, "--json")
    assert code == 0 and [json.loads(x)["file"] for x in out.splitlines()] == [BOX, BOX]


def _env():
    return {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}


def test_sigint_during_ipopt_exits_130_with_one_line(tmp_path):
    """CasADi swallows a KeyboardInterrupt raised inside IPOPT and returns its last iterate as
    an answer; the CLI must stop instead, with one line and no partial report."""
    out = tmp_path / "plan"
    t0 = time.perf_counter()  # how long the imports take on this machine now
    subprocess.run([sys.executable, "-c", "import closure_nlp.cli.main"], env=_env(), check=True)
    startup = time.perf_counter() - t0
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "closure_nlp.cli",
            "plan",
            LAMP,
            "--contacts",
            "4",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
    )
    time.sleep(startup + 2.0)  # imports done, solving
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert stdout == ""
    assert one_line(stderr).startswith("interrupted:")
    assert not out.exists()


SWALLOWER = """
import os, signal, time


def run():
    # as trimesh round its optional imports: every exception caught, an interrupt included
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.2)
    except BaseException:
        pass
    return "went on"
"""


def test_an_interrupt_inside_a_package_that_swallows_it_is_not_lost(tmp_path, monkeypatch):
    """Ctrl-C while a package that catches every exception is on the stack (CasADi in a solve,
    trimesh while imported) raises once that package returns."""
    from closure_nlp.base import interrupts

    (tmp_path / "swallower").mkdir()
    (tmp_path / "swallower" / "__init__.py").write_text(SWALLOWER)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(interrupts, "SWALLOWING_PACKAGES", ("casadi", "trimesh", "swallower"))
    import swallower

    went_on = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts.interruptible():
            went_on.append(swallower.run())  # the package returns, as it would
            time.sleep(1.0)  # the interrupt is raised here, not when the block ends
            went_on.append("after the package")
    assert went_on == ["went on"]


@pytest.mark.parametrize(
    "argv",
    [
        ["rho", "missing.contacts.json"],
        ["eligibility", LAMP, "--elements", "0,x"],
        ["select", LAMP, "--contacts", "1000"],
        ["rho"],
    ],
)
def test_subprocess_bad_input_exit_2_without_traceback(argv):
    proc = subprocess.run(
        [sys.executable, "-m", "closure_nlp.cli", *argv],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=120,
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert one_line(proc.stderr).startswith("error:")


def test_broken_pipe_is_quiet(tmp_path):
    proc = subprocess.Popen(
        [sys.executable, "-m", "closure_nlp.cli", "rho", BOX, BOX, BOX],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=_env(),
    )
    proc.stdout.close()  # the reader went away
    stderr = proc.stderr.read().decode()
    proc.wait(timeout=120)
    assert "Traceback" not in stderr
    assert np.isin(proc.returncode, [0, 1])


def test_ctrl_c_while_starting_is_one_line():
    """A KeyboardInterrupt while the CLI's modules are still importing (simulated right after
    the startup hook is in place) prints one line; importing the package and the CLI leaves
    sys.excepthook as it was."""
    code = "import closure_nlp.cli.startup\nraise KeyboardInterrupt\n"
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=60
    )
    assert proc.stderr == "interrupted: stopped by Ctrl-C while starting\n"
    check = (
        "import sys\nhook = sys.excepthook\nimport closure_nlp, closure_nlp.cli.main\n"
        "assert sys.excepthook is hook\n"
    )
    subprocess.run([sys.executable, "-c", check], env=_env(), timeout=60, check=True)


API_LOOP = """
import os, signal, sys, threading, time
import numpy as np
from benchmarks.bench import random_contact_set
from closure_nlp.criterion.support_minimum import SupportMinimizer
from closure_nlp.contact.wrenches import WrenchSlots

slots = WrenchSlots.from_contacts(random_contact_set(np.random.default_rng(0), ["pcwf"] * 120))
problem = SupportMinimizer().problem(slots)
rng = np.random.default_rng(1)
problem.solve(slots, np.eye(6)[0])  # built and warm: the loop below is nearly all IPOPT
threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT)).start()
start = time.perf_counter()
try:
    while time.perf_counter() - start < 60:
        problem.solve(slots, rng.normal(size=6))
except KeyboardInterrupt:
    sys.exit(7)
sys.exit(0)
"""


def test_sigint_during_ipopt_reaches_an_api_caller():
    """A library caller's Ctrl-C, which lands inside IPOPT nearly always here, is raised as
    KeyboardInterrupt after the solve instead of being swallowed by CasADi."""
    proc = subprocess.run(
        [sys.executable, "-c", API_LOOP], env=_env(), capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 7, proc.stderr
