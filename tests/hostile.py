"""The corpus of hostile and extreme inputs, generated, not stored.

Each :class:`Case` writes its files into a folder and runs one command through the in-process CLI
entry ``closure_nlp.cli.main.main`` (or one API call); :func:`outcome` sorts what happened into the
outcomes: a clear error, an answer, a traceback (an internal error or an exception escaping),
a NaN (a non-finite number printed), a hang. ``tests/test_hostile.py`` runs every case in
``make test``; ``python -m tests.hostile`` prints the table.

Expectations: ``"error"`` (exit 2 naming the file or flag, or ValueError/TypeError naming the
field) or ``"answer"`` (exit 0 or 1 with every number finite; the API: a finite result). A case
may also say its exit status (``code``) and a piece of its one ``error:`` line (``message``; for
the API, of the exception's text). Cases that need a process of their own (special files that
would block the test run, stdout on a full device or closed, an output encoding, a file-size
limit) return a :class:`Process` and run as a child of this one, with a time limit.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import resource
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
LAMP = ROOT / "models" / "lamp.model.json"
CUP_MESH = ROOT / "models" / "cup.stl"

ERROR, ANSWER = "error", "answer"
HANG_SECONDS = 60.0


@dataclass(frozen=True)
class Process:
    """A command line run in a child process: ``stdout`` is ``"pipe"``, ``"full"`` (/dev/full)
    or ``"closed"``; ``env`` is added to the environment; ``file_size`` limits the size of any
    file it writes (a full disk, without one)."""

    argv: list
    stdout: str = "pipe"
    env: dict | None = None
    file_size: int | None = None


@dataclass(frozen=True)
class Case:
    """One hostile input: ``make(folder)`` writes files and returns the CLI argv, a
    :class:`Process`, or (group ``api``) a callable whose return value is checked for finite
    numbers. ``code`` and ``message``, when given, are the exit status and a piece of the
    ``error:`` line (or of the exception) it must end with."""

    group: str
    name: str
    make: Callable[[Path], list | Callable | Process]
    expect: str
    code: int | None = None
    message: str | None = None
    pending: str | None = None  # why the case does not end as it must yet (tests: xfail)

    @property
    def id(self) -> str:
        return f"{self.group}:{self.name}"


# --- outcomes -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    kind: str  # "error", "answer", "traceback", "nan", "hang"
    detail: str
    seconds: float
    code: int | None = None  # the exit status (None for the API)


def as_expected(case: Case, outcome: Outcome) -> bool:
    """The kind, and the exit status and message when the case gives them."""
    if outcome.kind != case.expect:
        return False
    if case.code is not None and outcome.code != case.code:
        return False
    return case.message is None or case.message in outcome.detail


def _numbers(value):
    if isinstance(value, float):
        yield value
    elif isinstance(value, dict):
        for v in value.values():
            yield from _numbers(v)
    elif isinstance(value, (list, tuple)):
        for v in value:
            yield from _numbers(v)


_NAN_TEXT = re.compile(r"(?<![A-Za-z_])(nan|inf|-inf|NaN|Infinity)(?![A-Za-z_])")


def run_case(case: Case, folder: Path) -> Outcome:
    """Run one case in ``folder`` (created) and classify it."""
    import closure_nlp.cli.main as cli

    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    made = case.make(folder)
    if callable(made):  # an API call
        try:
            value = made()
        except (ValueError, TypeError, OSError) as exc:  # OSError: the file system said no
            return Outcome("error", f"{type(exc).__name__}: {exc}", time.perf_counter() - t0)
        except Exception as exc:  # noqa: BLE001 - the corpus counts these
            return Outcome("traceback", f"{type(exc).__name__}: {exc}", time.perf_counter() - t0)
        seconds = time.perf_counter() - t0
        values = [float(x) for x in np.ravel(np.asarray(value, dtype=float))]
        if not all(math.isfinite(x) for x in values):
            return Outcome("nan", repr(value), seconds)
        return Outcome("answer", repr(value)[:200], seconds)
    if isinstance(made, Process):
        return _run_process(made, folder, t0)
    argv = [str(a) for a in made]
    out, err = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli.main(argv)
            except SystemExit as exc:  # argparse: bad flag
                code = exc.code
            except BaseException as exc:  # noqa: BLE001 - main must never let one escape
                seconds = time.perf_counter() - t0
                return Outcome("traceback", f"{type(exc).__name__}: {exc}", seconds)
    finally:
        os.chdir(cwd)
    return _classify(argv, code, out.getvalue(), err.getvalue(), time.perf_counter() - t0)


def _run_process(made: Process, folder: Path, t0: float) -> Outcome:
    argv = [str(a) for a in made.argv]
    stdout = {"pipe": subprocess.PIPE, "full": None, "closed": subprocess.DEVNULL}[made.stdout]
    full = open("/dev/full", "w") if made.stdout == "full" else None  # noqa: SIM115

    def prepare():
        if made.stdout == "closed":
            os.close(1)
        if made.file_size is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (made.file_size, made.file_size))

    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg", **(made.env or {})}
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "closure_nlp.cli", *argv],
            stdout=full or stdout,
            stderr=subprocess.PIPE,
            cwd=folder,
            env=env,
            timeout=HANG_SECONDS,
            preexec_fn=prepare,
            text=True,
            errors="replace",
        )
    except subprocess.TimeoutExpired:
        return Outcome("hang", f"no end in {HANG_SECONDS:g} s", time.perf_counter() - t0)
    finally:
        if full is not None:
            full.close()
    code = proc.returncode if proc.returncode >= 0 else 128 - proc.returncode
    return _classify(argv, code, proc.stdout or "", proc.stderr, time.perf_counter() - t0)


def _classify(argv: list, code, stdout: str, stderr: str, seconds: float) -> Outcome:
    """What a command's exit status and output say: a clear error, an answer, a traceback..."""
    detail = f"exit {code}: {stderr.strip()[:300]}"
    outcome = _kind(argv, code, stdout, stderr, seconds, detail)
    return Outcome(outcome.kind, outcome.detail, seconds, code)


def _kind(argv, code, stdout, stderr, seconds, detail) -> Outcome:
    if seconds > HANG_SECONDS:
        return Outcome("hang", detail, seconds)
    if "Traceback" in stderr or code == 3 or code not in (0, 1, 2):
        return Outcome("traceback", detail, seconds)
    if "--json" in argv and stdout:
        for line in stdout.splitlines():
            if not all(math.isfinite(x) for x in _numbers(json.loads(line))):
                return Outcome("nan", line[:300], seconds)
    # An error message may quote the bad input ("got nan"); an answer may not print one.
    if code != 2 and (_NAN_TEXT.search(stdout) or _NAN_TEXT.search(stderr)):
        return Outcome("nan", stdout[:300] + stderr[:300], seconds)
    lines = [x for x in stderr.splitlines() if not x.startswith("warning: ")]
    if any(not x.isprintable() for x in lines):  # a raw control character reached the terminal
        return Outcome("traceback", detail, seconds)
    if code == 2:
        ok = len(lines) == 1 and lines[0].startswith("error: ") and stdout == ""
        return Outcome("error" if ok else "traceback", detail, seconds)
    if code == 1 and not (len(lines) == 1 and lines[0].startswith("error: ")):
        return Outcome("traceback", detail, seconds)
    return Outcome("answer", detail, seconds)


# --- building blocks ----------------------------------------------------------------------------


def _write(folder: Path, name: str, content) -> Path:
    path = folder / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif isinstance(content, str):
        path.write_text(content)
    else:
        path.write_text(json.dumps(content))
    return path


BOX = {  # 7 frictionless contacts on a unit box: force closure (examples/box_7fpc)
    "defaults": {"type": "fpc"},
    "contacts": json.loads((ROOT / "examples" / "box_7fpc.contacts.json").read_text())["contacts"],
}
PAIR = {  # two opposite soft fingers: a 2-contact answer that needs no long search
    "contacts": [
        {"position": [0, 0, 1], "inward_normal": [0, 0, -1], "type": "sfce"},
        {"position": [0, 0, -1], "inward_normal": [0, 0, 1], "type": "sfce"},
    ]
}


def _box_model() -> dict:
    """A unit cube as six facets (its inward normals), neighbours across edges."""
    elements = []
    for axis in range(3):
        others = [k for k in range(3) if k != axis]
        for sign in (-1.0, 1.0):
            corners = []
            for p, q in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
                v = [0.0, 0.0, 0.0]
                v[axis], v[others[0]], v[others[1]] = sign, float(p), float(q)
                corners.append(v)
            normal = [0.0, 0.0, 0.0]
            normal[axis] = -sign
            elements.append({"kind": "facet", "vertices": corners, "inward_normal": normal})
    adjacency = [[i, j] for i in range(6) for j in range(i + 1, 6) if i // 2 != j // 2]
    return {"name": "box", "units": "mm", "elements": elements, "adjacency": adjacency}


def _with(data: dict, path: tuple, value) -> dict:
    """A deep copy of ``data`` with the item at ``path`` (keys and indices) set to ``value``;
    ``...`` as value deletes it."""
    out = json.loads(json.dumps(data))
    target = out
    for key in path[:-1]:
        target = target[key]
    if value is ...:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return out


def _raw(text: str):
    """JSON text written as is (NaN literals, huge integers, broken syntax)."""
    return text


# Values a hostile user puts where a number or a vector belongs.
BAD_NUMBERS = [
    ("nan", _raw("NaN")),
    ("inf", _raw("Infinity")),
    ("minus_inf", _raw("-Infinity")),
    ("1e400", _raw("1e400")),
    ("int_400_digits", _raw("1" + "0" * 400)),
    ("string", "0.5"),
    ("true", True),
    ("null", None),
    ("list", [1]),
    ("object", {"x": 1}),
]


def _json_with_raw(data: dict, path: tuple, raw: str) -> str:
    """JSON of ``data`` with the value at ``path`` replaced by the raw text ``raw``."""
    marker = "__RAW_VALUE__"
    return json.dumps(_with(data, path, marker)).replace(f'"{marker}"', raw)


def _contact_cases() -> list[Case]:
    cases = []

    def rho_case(name, content, expect, extra=()):
        def make(folder, content=content):
            return ["rho", _write(folder, "c.contacts.json", content), "--json", *extra]

        cases.append(Case("contacts", name, make, expect))

    c0 = ("contacts", 0)
    for field in ("position", "inward_normal"):
        for k, (label, value) in enumerate(BAD_NUMBERS):
            content = (
                _json_with_raw(PAIR, (*c0, field, k % 3), value)
                if isinstance(value, str) and label not in ("string",)
                else _with(PAIR, (*c0, field, k % 3), value)
            )
            rho_case(f"{field}[{k % 3}]={label}", content, ERROR)
        for label, value in [
            ("short", [0, 0]),
            ("long", [0, 0, 1, 0]),
            ("empty", []),
            ("nested", [[0], [0], [1]]),
            ("strings", ["0", "0", "1"]),
            ("booleans", [True, False, False]),
            ("text", "0,0,1"),
            ("missing", ...),
        ]:
            rho_case(f"{field}={label}", _with(PAIR, (*c0, field), value), ERROR)
    for label, value, expect in [
        ("1e12", 1e12, ANSWER),
        ("1e13", 1e13, ERROR),
        ("1e200", 1e200, ERROR),
        ("1e300", 1e300, ERROR),
        ("-1e300", -1e300, ERROR),
        ("1e-300", 1e-300, ANSWER),
        ("5e-324", 5e-324, ANSWER),
    ]:
        rho_case(f"position_z={label}", _with(PAIR, (*c0, "position", 2), value), expect)
    for label, scale in [
        ("1e-300", 1e-300),
        ("1e-155", 1e-155),
        ("1e-12", 1e-12),
        ("1e155", 1e155),
        ("1e200", 1e200),
        ("1e300", 1e300),
        ("1.7e308", 1.7e308),
        ("5e-324", 5e-324),
    ]:
        normal = _with(PAIR, (*c0, "inward_normal"), [0, 0, -scale])
        rho_case(f"normal_length={label}", normal, ANSWER)
    rho_case("normal=zero", _with(PAIR, (*c0, "inward_normal"), [0, 0, 0]), ERROR)
    rho_case("normal=minus_zero", _with(PAIR, (*c0, "inward_normal"), [-0.0, 0.0, -0.0]), ERROR)
    ranges = {
        "mu": [(-1, ERROR), (0, ANSWER), (1e6, ANSWER), (1e7, ERROR), (1e300, ERROR)],
        "mu_s": [(-1, ERROR), (0, ANSWER), (1e12, ANSWER), (1e13, ERROR), (1e300, ERROR)],
        "f_max": [
            (0, ERROR),
            (-1, ERROR),
            (1e-13, ERROR),
            (1e-12, ANSWER),
            (1e12, ANSWER),
            (1e13, ERROR),
            (1e300, ERROR),
        ],
    }
    for field, values in ranges.items():
        for value, expect in values:
            rho_case(f"{field}={value:g}", _with(PAIR, (*c0, field), value), expect)
        for label, value in BAD_NUMBERS:
            content = (
                _json_with_raw(PAIR, (*c0, field), value)
                if isinstance(value, str) and label != "string"
                else _with(PAIR, (*c0, field), value)
            )
            rho_case(f"{field}={label}", content, ERROR)
    for value, expect in [
        (0, ERROR),
        (-1, ERROR),
        (1e-16, ERROR),
        (1e-15, ANSWER),
        (1e15, ANSWER),
        (1e16, ERROR),
        (1e300, ERROR),
        ("1", ERROR),
        (True, ERROR),
        (None, ERROR),
    ]:
        rho_case(f"torque_scale={value!r}", {**PAIR, "torque_scale": value}, expect)
    for label, value in [("glue", "glue"), ("number", 3), ("null", None), ("upper", "SFCE")]:
        expect = ANSWER if label == "upper" else ERROR
        rho_case(f"type={label}", _with(PAIR, (*c0, "type"), value), expect)
    rho_case("unknown_key", _with(PAIR, (*c0, "positon"), [0, 0, 1]), ERROR)
    for key, value, expect in [
        ("element", 3, ANSWER),
        ("element", -1, ERROR),
        ("element", "3", ERROR),
        ("element", True, ERROR),
        ("weights", [0.5, 0.5], ANSWER),
        ("weights", ["a"], ERROR),
        ("name", 7, ERROR),
    ]:
        rho_case(f"{key}={value!r}", _with(PAIR, (*c0, key), value), expect)
    rho_case("weights=[NaN]", _json_with_raw(PAIR, (*c0, "weights"), "[0.5, NaN]"), ERROR)
    for label, point, expect in [
        ("1e200", [0, 0, 1e200], ERROR),
        ("str", ["0", 0, 1], ERROR),
        ("bool", [True, 0, 0], ERROR),
        ("1e12", [0, 0, 1e12], ANSWER),
    ]:
        rho_case(f"reference_point={label}", {**PAIR, "reference_point": point}, expect)
    rho_case("contacts=empty", {"contacts": []}, ERROR)
    rho_case("contacts=object", {"contacts": {}}, ERROR)
    rho_case("contacts=text", {"contacts": "x"}, ERROR)
    rho_case("contacts=missing", {"torque_scale": 1}, ERROR)
    rho_case("contacts=2001", {"contacts": PAIR["contacts"] * 1001}, ERROR)
    rho_case("contact=list", {"contacts": [[0, 0, 1]]}, ERROR)
    rho_case("defaults=list", {**PAIR, "defaults": []}, ERROR)
    rho_case("defaults.mu=1e300", {**PAIR, "defaults": {"mu": 1e300}}, ERROR)
    rho_case("top=list", [PAIR], ERROR)
    rho_case("top=number", "3", ERROR)
    rho_case("nested_5000", "[" * 5000 + "]" * 5000, ERROR)
    rho_case("nested_100000", "[" * 100000 + "]" * 100000, ERROR)
    rho_case("malformed", '{"contacts": [', ERROR)
    rho_case("empty_file", "", ERROR)
    noise = bytes(np.random.default_rng(1).integers(0, 256, 4096, dtype=np.uint8))
    rho_case("random_bytes", noise, ERROR)
    rho_case("utf16", json.dumps(PAIR).encode("utf-16"), ERROR)
    rho_case("huge_digits", '{"contacts": ' + "1" * 5000 + "}", ERROR)
    rho_case("box_7fpc", BOX, ANSWER)
    rho_case("box_7fpc_certify", BOX, ANSWER, ("--certify",))
    rho_case("pair_text", PAIR, ANSWER)
    cases.append(Case("contacts", "missing_file", lambda f: ["rho", f / "none.json"], ERROR))
    cases.append(Case("contacts", "folder_as_file", lambda f: ["rho", f], ERROR))
    return cases


def _model_cases() -> list[Case]:
    cases = []
    base = _box_model()

    def elig_case(name, content, expect, ids="0,1,2,3", extra=()):
        def make(folder, content=content):
            path = _write(folder, "m.model.json", content)
            return ["eligibility", path, "--elements", ids, "--type", "pcwf", "--json", *extra]

        cases.append(Case("models", name, make, expect))

    e0 = ("elements", 0)
    for k, (label, value) in enumerate(BAD_NUMBERS):
        raw = isinstance(value, str) and label != "string"
        path = (*e0, "vertices", k % 4, k % 3)
        content = _json_with_raw(base, path, value) if raw else _with(base, path, value)
        elig_case(f"vertex={label}", content, ERROR)
        path = (*e0, "inward_normal", k % 3)
        content = _json_with_raw(base, path, value) if raw else _with(base, path, value)
        elig_case(f"normal={label}", content, ERROR)
    for label, scale, expect in [
        # A facet of size 2e12 next to unit ones: they are degenerate against the part (the
        # whole box at 1e11 is accepted: group mesh_scale).
        ("1e12", 1e12, ERROR),
        ("1e13", 1e13, ERROR),
        ("1e200", 1e200, ERROR),
        ("1e-200", 1e-200, ERROR),  # a facet of size 1e-200 next to unit ones: degenerate
    ]:
        content = _with(
            base,
            (*e0, "vertices"),
            [[-1, y * scale, z * scale] for y, z in [(-1, -1), (1, -1), (1, 1), (-1, 1)]],
        )
        elig_case(f"facet_size={label}", content, expect)
    for label, value in [
        ("kind=glue", ("kind", "glue")),
        ("kind=null", ("kind", None)),
        ("two_vertices", ("vertices", [[-1, 0, 0], [-1, 1, 0]])),
        ("collinear", ("vertices", [[-1, 0, 0], [-1, 1, 0], [-1, 2, 0]])),
        ("not_planar", ("vertices", [[-1, -1, -1], [-1, 1, -1], [-0.5, 1, 1], [-1, -1, 1]])),
        ("not_convex", ("vertices", [[-1, -1, -1], [-1, 1, 1], [-1, 1, -1], [-1, -1, 1]])),
        ("normal_in_plane", ("inward_normal", [0, 1, 0])),
        ("normal_zero", ("inward_normal", [0, 0, 0])),
        ("vertices_flat_list", ("vertices", [0, 0, 0])),
        ("vertices_empty", ("vertices", [])),
        ("unknown_key", ("colour", "red")),
    ]:
        key, v = value
        elig_case(label, _with(base, (*e0, key), v), ERROR)
    elig_case("normal_length_1e300", _with(base, (*e0, "inward_normal"), [1e300, 0, 0]), ANSWER)
    elig_case("normal_length_1e-300", _with(base, (*e0, "inward_normal"), [1e-300, 0, 0]), ANSWER)
    seg = {"kind": "segment", "vertices": [[0, 0, 1], [0, 0, 1]], "inward_normal": [1, 0, 0]}
    elig_case("segment_coincident", _with(base, ("elements", 5), seg), ERROR)
    seg = {"kind": "segment", "vertices": [[0, 0, 1], [1, 0, 1]], "inward_normal": [1, 0, 0]}
    elig_case("segment_normal_along", _with(base, ("elements", 5), seg), ERROR)
    pt = {"kind": "point", "vertices": [[0, 0, 1], [1, 0, 1]], "inward_normal": [0, 0, -1]}
    elig_case("point_two_vertices", _with(base, ("elements", 5), pt), ERROR)
    for label, pair in [
        ("99", [0, 99]),
        ("negative", [0, -1]),
        ("self", [1, 1]),
        ("bool", [True, 0]),
        ("string", ["0", 1]),
        ("triple", [0, 1, 2]),
        ("float", [0.0, 1]),
    ]:
        elig_case(f"adjacency={label}", _with(base, ("adjacency", 0), pair), ERROR)
    for label, point in [("1e200", [0, 0, 1e200]), ("str", ["0", 0, 1]), ("short", [0, 0])]:
        elig_case(f"reference_point={label}", {**base, "reference_point": point}, ERROR)
    elig_case("elements=empty", _with(base, ("elements",), []), ERROR)
    elig_case("elements=object", _with(base, ("elements",), {}), ERROR)
    elig_case("name=number", _with(base, ("name",), 3), ERROR)
    elig_case("mesh=number", _with(base, ("mesh",), 3), ERROR)
    elig_case("nested_5000", "[" * 5000 + "]" * 5000, ERROR)
    elig_case("box", base, ANSWER)
    elig_case("box_ids_repeat", base, ANSWER, ids="0,0,1,1")
    for label, mesh in [
        ("outside_dotdot", "../elsewhere.stl"),
        ("outside_absolute", "/etc/hostname"),
    ]:
        elig_case(f"mesh={label}", _with(base, ("mesh",), mesh), ERROR)
    elig_case("mesh=missing", _with(base, ("mesh",), "gone.stl"), ANSWER)

    def with_mesh(name, mesh_bytes, expect, flip=None, command="eligibility"):
        def make(folder):
            _write(folder, "part.stl", mesh_bytes)
            data = _with(base, ("mesh",), "part.stl")
            if flip is not None:
                data = _with(
                    data,
                    ("elements", flip, "inward_normal"),
                    [-x for x in base["elements"][flip]["inward_normal"]],
                )
            path = _write(folder, "m.model.json", data)
            if command == "show":
                return ["show", path, "--out", folder / "x.glb", "--json"]
            return ["eligibility", path, "--elements", "0,1,2,3", "--json"]

        cases.append(Case("models", name, make, expect))

    import trimesh

    cube = trimesh.creation.box(extents=(2, 2, 2))
    cube_stl = trimesh.exchange.stl.export_stl(cube)
    with_mesh("mesh=own_cube", cube_stl, ANSWER)
    for i in range(6):
        with_mesh(f"mesh=own_cube_flipped_facet_{i}", cube_stl, ERROR, flip=i)
    with_mesh("mesh=text_as_stl", b"hello", ANSWER)
    with_mesh("mesh=random_bytes_show_glb", bytes(range(256)) * 8, ANSWER, command="show")
    with_mesh("mesh=own_cube_show_glb", cube_stl, ANSWER, command="show")
    return cases


def _mesh_cases() -> list[Case]:
    import trimesh

    cases = []
    rng = np.random.default_rng(7)

    def char_case(name, filename, content, expect, extra=()):
        def make(folder):
            path = _write(folder, filename, content) if content is not None else folder / filename
            return ["characterize", path, "--out", folder / "out.model.json", "--json", *extra]

        cases.append(Case("meshes", name, make, expect))

    for suffix in ("stl", "obj", "ply", "glb", "off", "3mf", "dae"):
        char_case(
            f"random_bytes.{suffix}",
            f"r.{suffix}",
            bytes(rng.integers(0, 256, 3000, dtype=np.uint8)),
            ERROR,
        )
        char_case(f"empty.{suffix}", f"e.{suffix}", b"", ERROR)
    char_case("ascii_solid_garbage.stl", "g.stl", "solid x\n garbage\nendsolid\n", ERROR)
    char_case("text.txt", "t.txt", "hello", ERROR)
    char_case("json_as_mesh.json", "m.json", json.dumps(_box_model()), ERROR)
    char_case("missing.stl", "none.stl", None, ERROR)
    char_case("binary_count_lies.stl", "b.stl", b"\0" * 80 + (10**6).to_bytes(4, "little"), ERROR)
    tet = trimesh.creation.box(extents=(1, 1, 1))
    char_case("cube.stl", "cube.stl", trimesh.exchange.stl.export_stl(tet), ANSWER)
    char_case("cube.obj", "cube.obj", trimesh.exchange.obj.export_obj(tet), ANSWER)
    char_case("cube.ply", "cube.ply", trimesh.exchange.ply.export_ply(tet), ANSWER)
    big = trimesh.Trimesh(tet.vertices * 1e200, tet.faces, process=False)
    char_case("cube_at_1e200.obj", "big.obj", trimesh.exchange.obj.export_obj(big), ERROR)
    stl = bytearray(trimesh.exchange.stl.export_stl(tet))
    stl[84 + 12 : 84 + 16] = np.float32(np.inf).tobytes()  # first vertex x of a binary STL
    char_case("cube_inf_vertex.stl", "inf.stl", bytes(stl), ERROR)
    huge = tet.copy()
    huge.apply_translation([1e13, 0, 0])
    char_case("cube_at_1e13.stl", "far.stl", trimesh.exchange.stl.export_stl(huge), ERROR)
    opened = trimesh.Trimesh(tet.vertices, tet.faces[:-4])
    # two faces gone: an opening of the part, refused unless the user asks to close it
    char_case("open_box.stl", "open.stl", trimesh.exchange.stl.export_stl(opened), ERROR)
    closing = ("--close-holes",)
    opened_stl = trimesh.exchange.stl.export_stl(opened)
    char_case("open_box.stl_closed", "open.stl", opened_stl, ANSWER, closing)
    torn = trimesh.Trimesh(tet.vertices, tet.faces[::2])  # every other face: no small holes
    char_case("torn_box.stl", "torn.stl", trimesh.exchange.stl.export_stl(torn), ERROR)
    flat = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    char_case("one_triangle.stl", "tri.stl", trimesh.exchange.stl.export_stl(flat), ERROR)
    char_case(
        "cube.stl_spacing_nan",
        "cube2.stl",
        trimesh.exchange.stl.export_stl(tet),
        ERROR,
        ("--point-spacing", "nan"),
    )
    char_case(
        "cube.stl_sharp_-1",
        "cube3.stl",
        trimesh.exchange.stl.export_stl(tet),
        ERROR,
        ("--sharp-angle", "-1"),
    )
    char_case("cup.stl", "cup.stl", CUP_MESH.read_bytes(), ANSWER)
    for out, needle in [("file", "f"), ("under_file", "f/x.model.json"), ("folder", "d")]:

        def make(folder, out=needle):
            _write(folder, "f", "x")
            (folder / "d").mkdir(exist_ok=True)
            path = _write(folder, "cube.stl", trimesh.exchange.stl.export_stl(tet))
            return ["characterize", path, "--out", folder / out]

        cases.append(Case("meshes", f"out={out}", make, ANSWER if out == "file" else ERROR))
    return cases


def _study_cases() -> list[Case]:
    cases = []

    def study_case(name, body, expect, extra=("--limit", "0")):
        def make(folder):
            path = _write(folder, "s.toml", f'models = ["{LAMP.as_posix()}"]\n{body}\n')
            return ["study", path, "--out", folder / "out", "--json", *extra]

        cases.append(Case("studies", name, make, expect))

    for label, body, expect in [
        ("seeds=1e12", "contacts = 4\nseeds = 1_000_000_000_000", ERROR),
        ("seeds=10M", "contacts = 4\nseeds = 10_000_000", ERROR),
        ("seeds=0", "contacts = 4\nseeds = 0", ERROR),
        ("seeds=-1", "contacts = 4\nseeds = -1", ERROR),
        ("seeds=float", "contacts = 4\nseeds = 2.5", ERROR),
        ("seeds=string", 'contacts = 4\nseeds = "3"', ERROR),
        ("seeds=bool", "contacts = 4\nseeds = true", ERROR),
        ("seeds=2**63", "contacts = 4\nseeds = [9223372036854775808]", ERROR),
        ("seeds=repeat", "contacts = 4\nseeds = [1, 1]", ERROR),
        ("seeds=empty", "contacts = 4\nseeds = []", ERROR),
        (
            "grid=over_limit",
            "contacts = [4, 5]\nmu = [0.1, 0.2, 0.3, 0.4, 0.5]\nseeds = 10001",
            ERROR,
        ),
        ("contacts=1000", "contacts = 1000", ERROR),
        ("contacts=0", "contacts = 0", ERROR),
        ("contacts=1", "contacts = 1", ERROR),
        ("mu=1e300", "contacts = 4\nmu = 1e300", ERROR),
        ("mu=nan", "contacts = 4\nmu = nan", ERROR),
        ("f_max=inf", "contacts = 4\nf_max = inf", ERROR),
        ("f_max=1e-20", "contacts = 4\nf_max = 1e-20", ERROR),
        ("torque_scale=0", "contacts = 4\ntorque_scale = 0", ERROR),
        ("type=glue", 'contacts = 4\ntype = "glue"', ERROR),
        ("unknown_key", "contacts = 4\nseed = 3", ERROR),
        ("placement.starts=0", "contacts = 4\n[placement]\nstarts = 0", ERROR),
        ("selection.bogus", "contacts = 4\n[selection]\nbogus = 1", ERROR),
        ("limit0_ok", "contacts = 4\nseeds = 3", ANSWER),
        ("limit0_99999_seeds", "contacts = 4\nseeds = 99999", ANSWER),
    ]:
        study_case(label, body, expect)

    def raw_study(name, text, expect):
        def make(folder):
            path = _write(folder, "s.toml", text)
            return ["study", path, "--out", folder / "out", "--limit", "0"]

        cases.append(Case("studies", name, make, expect))

    raw_study("malformed_toml", "models = [", ERROR)
    raw_study("missing_models", "contacts = 4", ERROR)
    raw_study("model_not_found", 'models = ["none.model.json"]\ncontacts = 4', ERROR)
    raw_study("models_outside_json", 'models = ["/etc/hostname"]\ncontacts = 4', ERROR)
    raw_study("random_bytes", bytes(range(256)) * 10, ERROR)
    raw_study("deep_nesting", "x = " + "[" * 5000 + "]" * 5000, ERROR)

    def out_case(name, out, expect):
        def make(folder):
            _write(folder, "f", "x")
            path = _write(folder, "s.toml", f'models = ["{LAMP.as_posix()}"]\ncontacts = 4\n')
            return ["study", path, "--out", folder / out, "--limit", "0"]

        cases.append(Case("studies", name, make, expect))

    out_case("out=file", "f", ERROR)
    out_case("out=under_file", "f/out", ERROR)
    for flag, value in [("--workers", "0"), ("--workers", "1000000"), ("--limit", "-1")]:
        study_case(f"{flag}={value}", "contacts = 4", ERROR, (flag, value))
    return cases


def _flag_cases() -> list[Case]:
    cases = []
    model = _box_model()

    def flag_case(name, command, args, expect):
        def make(folder):
            path = _write(folder, "m.model.json", model)
            return [command, path, *args]

        cases.append(Case("flags", name, make, expect))

    el = ["--elements", "0,1,2,3"]
    for flag, values in {
        "--mu": ["nan", "inf", "-1", "1e300", "abc", "", "0.2,0.2", "1e6"],
        "--mu-s": ["nan", "-1", "1e300", "1e12"],
        "--f-max": ["0", "1e-13", "1e-12", "1e12", "1e13", "1e300", "nan", "-inf"],
        "--torque-scale": ["0", "-1", "1e-16", "1e16", "1e300", "nan", "x", "1,2", "1e-15"],
        "--type": ["glue", "", "pcwf,fpc", "PCWF", "fpc,fpc,fpc,fpc"],
    }.items():
        for value in values:
            good = {
                ("--mu", "1e6"),
                ("--mu-s", "1e12"),
                ("--f-max", "1e-12"),
                ("--f-max", "1e12"),
                ("--torque-scale", "1e-15"),
                ("--type", "PCWF"),
                ("--type", "fpc,fpc,fpc,fpc"),
            }
            expect = ANSWER if (flag, value) in good else ERROR
            flag_case(
                f"eligibility {flag}={value!r}", "eligibility", [*el, flag, value, "--json"], expect
            )
    for value, expect in [
        ("", ERROR),
        ("0,,1", ERROR),
        ("99", ERROR),
        ("-1", ERROR),
        ("1e3", ERROR),
        ("0," * 32 + "0", ERROR),
        ("a", ERROR),
        ("0,1,2,3,4,5,0,1", ANSWER),
        ("0", ANSWER),
    ]:
        flag_case(
            f"eligibility --elements={value[:20]!r}",
            "eligibility",
            ["--elements", value, "--json"],
            expect,
        )
    for value in ["0", "-1", "1000", "33", "1e3", "x", "1"]:
        flag_case(f"select --contacts={value}", "select", ["--contacts", value], ERROR)
        flag_case(f"plan --contacts={value}", "plan", ["--contacts", value], ERROR)
    for flag, value in [
        ("--seed", "-1"),
        ("--seed", "1e3"),
        ("--seed", str(2**64)),
        ("--start", "0,99"),
        ("--start", "x"),
        ("--algorithm", "magic"),
    ]:
        flag_case(f"select {flag}={value}", "select", ["--contacts", "4", flag, value], ERROR)
    for flag, value in [("--starts", "0"), ("--starts", "1000000"), ("--seed", "-5")]:
        flag_case(f"place {flag}={value}", "place", [*el, flag, value], ERROR)
        flag_case(f"plan {flag}={value}", "plan", ["--contacts", "4", flag, value], ERROR)
    for flag, value in [
        ("--seeds", "0"),
        ("--seeds", "x"),
        ("--budget", "0"),
        ("--budget", "nan"),
        ("--budget", "-1"),
        ("--workers", "0"),
    ]:
        flag_case(f"plan {flag}={value}", "plan", ["--contacts", "4", flag, value], ERROR)
    flag_case("place --elements 0,1 (too few pcwf)", "place", ["--elements", "0,1"], ERROR)
    flag_case("show --out .txt", "show", ["--out", "x.txt"], ERROR)
    flag_case("show --highlight 99", "show", ["--out", "x.png", "--highlight", "99"], ERROR)
    flag_case("show --highlight x", "show", ["--out", "x.png", "--highlight", "x"], ERROR)
    flag_case("show --elev nan", "show", ["--out", "x.png", "--elev", "nan"], ERROR)
    flag_case("show png", "show", ["--out", "x.png", "--json"], ANSWER)

    def out_case(name, command, args, out, expect):
        def make(folder):
            _write(folder, "f", "x")
            (folder / "other").mkdir(exist_ok=True)
            _write(folder / "other", "notes.txt", "mine")
            path = _write(folder, "m.model.json", model)
            return [command, path, *args, "--out", folder / out]

        cases.append(Case("flags", name, make, expect))

    for out in ("f", "f/sub", "/proc/closure_nlp/x", "other"):
        out_case(f"plan --out={out}", "plan", ["--contacts", "4"], out, ERROR)
    out_case("place --out=folder", "place", el, "other", ERROR)
    out_case("place --out=under_file", "place", el, "f/x.json", ERROR)
    out_case("show --out=under_file", "show", [], "f/x.png", ERROR)
    cases.append(Case("flags", "no command", lambda f: [], ERROR))
    cases.append(Case("flags", "unknown command", lambda f: ["fly"], ERROR))
    cases.append(Case("flags", "rho no files", lambda f: ["rho"], ERROR))
    return cases


def _api_cases() -> list[Case]:
    from closure_nlp.base.files import load_json
    from closure_nlp.contact.contact_set import Contact, ContactSet, contact_set_from_dict
    from closure_nlp.criterion.rho_hat import Eligibility
    from closure_nlp.criterion.support_minimum import rho
    from closure_nlp.model.elements import Element, Model, model_from_dict
    from closure_nlp.model.meshes import read_mesh
    from closure_nlp.model.scale import contact_specs

    cases = []

    def api(name, call, expect):
        cases.append(Case("api", name, lambda folder, call=call: call, expect))

    pair = contact_set_from_dict(PAIR)
    for label, kwargs in [
        ("position_str", {"position": ["0", "0", "1"]}),
        ("position_bool", {"position": [True, False, False]}),
        ("position_1e300", {"position": [0, 0, 1e300]}),
        ("position_nan", {"position": [0, 0, float("nan")]}),
        ("position_bigint", {"position": [0, 0, 10**400]}),
        ("position_object_array", {"position": np.array(["0", "0", "1"], dtype=object)}),
        ("position_bool_array", {"position": np.array([True, False, True])}),
        ("normal_zero", {"inward_normal": [0, 0, 0]}),
        ("normal_str", {"inward_normal": "001"}),
        ("mu_1e300", {"mu": 1e300}),
        ("mu_nan", {"mu": float("nan")}),
        ("mu_s_neg", {"mu_s": -1.0}),
        ("f_max_0", {"f_max": 0.0}),
        ("f_max_1e300", {"f_max": 1e300}),
        ("f_max_bool", {"f_max": True}),
        ("type_glue", {"type": "glue"}),
    ]:
        args = {"position": [0, 0, 1], "inward_normal": [0, 0, -1], **kwargs}
        api(f"Contact({label})", lambda args=args: Contact(**args).position, ERROR)
    for label, ts in [("0", 0.0), ("1e300", 1e300), ("nan", float("nan")), ("str", "1")]:
        api(
            f"ContactSet(torque_scale={label})",
            lambda ts=ts: ContactSet(pair.contacts, ts).torque_scale,
            ERROR,
        )
    api("ContactSet(empty)", lambda: ContactSet(()), ERROR)
    api("ContactSet(not contacts)", lambda: ContactSet(([0, 0, 1],)), ERROR)
    api("ContactSet(2001)", lambda: ContactSet(pair.contacts * 1001), ERROR)
    api("contact_specs(1000)", lambda: contact_specs(1000), ERROR)
    api("contact_specs(0)", lambda: contact_specs(0), ERROR)
    api("contact_specs(2.5)", lambda: contact_specs(2.5), ERROR)
    api("contact_specs(mu list short)", lambda: contact_specs(3, mu=[0.1]), ERROR)
    api("rho(pair)", lambda: rho(pair).rho, ANSWER)
    api(
        "rho(normal 1e300)",
        lambda: (
            rho(
                contact_set_from_dict(_with(PAIR, ("contacts", 0, "inward_normal"), [0, 0, -1e300]))
            ).rho
        ),
        ANSWER,
    )
    api("rho(box)", lambda: rho(contact_set_from_dict(BOX)).rho, ANSWER)
    api(
        "rho(box, warm_start=nan)",
        lambda: rho(contact_set_from_dict(BOX), warm_start=[np.nan] * 6).rho,
        ERROR,
    )
    api(
        "rho(box, warm_start=str)",
        lambda: rho(contact_set_from_dict(BOX), warm_start="abc").rho,
        ERROR,
    )
    api(
        "rho(box, warm_start=2 rows)",
        lambda: rho(contact_set_from_dict(BOX), warm_start=np.eye(6)[:2]).rho,
        ANSWER,
    )
    api(
        "rho(box, warm_start=zero row)",
        lambda: rho(contact_set_from_dict(BOX), warm_start=np.zeros((2, 6))).rho,
        ERROR,
    )
    api(
        "rho(box, warm_start=5 columns)",
        lambda: rho(contact_set_from_dict(BOX), warm_start=np.ones((2, 5))).rho,
        ERROR,
    )
    api(
        "rho(box, warm_start=ragged rows)",
        lambda: rho(contact_set_from_dict(BOX), warm_start=[[1] * 6, [1, 0]]).rho,
        ERROR,
    )
    api("rho(not a set)", lambda: rho([1, 2, 3]).rho, ERROR)
    for label, element in [
        ("vertices_str", lambda: Element("point", [["0", 0, 0]], [0, 0, 1])),
        ("vertices_1e200", lambda: Element("point", [[1e200, 0, 0]], [0, 0, 1])),
        ("vertices_ragged", lambda: Element("facet", [[0, 0, 0], [1, 0]], [0, 0, 1])),
        ("kind_glue", lambda: Element("glue", [[0, 0, 0]], [0, 0, 1])),
        ("label_number", lambda: Element("point", [[0, 0, 0]], [0, 0, 1], label=3)),
    ]:
        api(f"Element({label})", lambda element=element: element().vertices, ERROR)
    box = model_from_dict(_box_model())
    api("Model(empty)", lambda: Model(()).elements, ERROR)
    api("Model(adjacency 99)", lambda: Model(box.elements, ((0, 99),)).adjacency, ERROR)
    api("Model(adjacency bool)", lambda: Model(box.elements, ((True, 0),)).adjacency, ERROR)
    api("model.check_id(1.0)", lambda: box.check_id(1.0, "id"), ERROR)
    api("model.check_id(-1)", lambda: box.check_id(-1, "id"), ERROR)
    specs = contact_specs(4)
    api(
        "Eligibility(box)([0,1,2,3])", lambda: Eligibility(box, specs)([0, 1, 2, 3]).rho_hat, ANSWER
    )
    api(
        "Eligibility(box)([0,1,2,99])",
        lambda: Eligibility(box, specs)([0, 1, 2, 99]).rho_hat,
        ERROR,
    )
    api(
        "Eligibility(box)(['0',1,2,3])",
        lambda: Eligibility(box, specs)(["0", 1, 2, 3]).rho_hat,
        ERROR,
    )
    api("Eligibility(box)([0,1])", lambda: Eligibility(box, specs)([0, 1]).rho_hat, ERROR)
    api("Eligibility(torque_scale=0)", lambda: Eligibility(box, specs, 0.0).torque_scale, ERROR)
    api("model_from_dict(list)", lambda: model_from_dict([]).elements, ERROR)
    api("contact_set_from_dict(None)", lambda: contact_set_from_dict(None).contacts, ERROR)

    from closure_nlp.base.files import write_json
    from closure_nlp.model.characterize import characterize
    from closure_nlp.model.elements import save_model, simplex_weights
    from closure_nlp.placement.options import PlacementOptions
    from closure_nlp.selection.algorithms import SelectionOptions, heuristic

    for label, kwargs in [
        ("starts=0", {"starts": 0}),
        ("starts=-1", {"starts": -1}),
        ("starts=2.5", {"starts": 2.5}),
        ("seed=str", {"seed": "1"}),
        ("certify=str", {"certify": "yes"}),
        ("bogus", {"bogus": 1}),
        ("round_search=str", {"round_search": "light"}),
    ]:
        api(f"PlacementOptions({label})", lambda kw=kwargs: PlacementOptions(**kw).starts, ERROR)
    from closure_nlp.criterion.support_minimum import SupportMinimizer

    for label, kwargs in [
        ("search=dict", {"search": {"samples": 8}}),
        ("seed_search=str", {"seed_search": "light"}),
    ]:
        api(f"SupportMinimizer({label})", lambda kw=kwargs: SupportMinimizer(**kw).search, ERROR)
    for label, kwargs in [
        ("initial=0", {"initial": 0}),
        ("restarts=0", {"restarts": 0}),
        ("max_iterations=-1", {"max_iterations": -1}),
        ("descent=nan", {"descent": float("nan")}),
    ]:
        api(f"SelectionOptions({label})", lambda kw=kwargs: SelectionOptions(**kw).initial, ERROR)
    elig = Eligibility(box, specs)
    api("heuristic(start=[99])", lambda: heuristic(elig, start=[99]).rho_hat, ERROR)
    api("heuristic(start='01')", lambda: heuristic(elig, start="01").rho_hat, ERROR)
    api("heuristic(seed=-1)", lambda: heuristic(elig, seed=-1).rho_hat, ERROR)
    for label, weights in [
        ("negative", [-0.5, 1.5]),
        ("nan", [np.nan, 1.0]),
        ("str", ["a", 1]),
        ("short", [1.0]),
        ("sum_2", [1.0, 1.0]),
    ]:
        api(f"simplex_weights({label})", lambda w=weights: simplex_weights(w, 2, "w"), ERROR)
    api("simplex_weights(ok)", lambda: simplex_weights([0.25, 0.75], 2, "w"), ANSWER)
    api("characterize(3)", lambda: characterize(3).elements, ERROR)
    api("characterize(missing)", lambda: characterize("/nonexistent/x.stl").elements, ERROR)

    def char_option(folder, key, value):
        import trimesh

        path = folder / "cube.stl"
        trimesh.creation.box(extents=(1, 1, 1)).export(path)
        return lambda: characterize(path, **{key: value}).elements

    for key, value in [
        ("sharp_angle", -1.0),
        ("sharp_angle", float("nan")),
        ("point_spacing", -2.0),
        ("segment_spacing", "x"),
        ("bogus", 1),
    ]:
        cases.append(
            Case(
                "api",
                f"characterize({key}={value!r})",
                lambda f, k=key, v=value: char_option(f, k, v),
                ERROR,
            )
        )

    def writes(folder, data):
        return lambda: write_json(folder / "x.json", data)

    cases.append(Case("api", "write_json(nan)", lambda f: writes(f, {"rho": float("nan")}), ERROR))
    cases.append(
        Case(
            "api", "write_json(inf in list)", lambda f: writes(f, {"a": [1.0, float("inf")]}), ERROR
        )
    )
    cases.append(
        Case(
            "api",
            "save_model(under a file)",
            lambda f: (
                (f / "file").write_text("x"),
                lambda: save_model(box, f / "file" / "m.json"),
            )[1],
            ERROR,
        )
    )

    def deep(folder):
        path = _write(folder, "deep.json", "[" * 100000 + "]" * 100000)
        return lambda: load_json(path)

    cases.append(Case("api", "load_json(deep)", deep, ERROR))

    def noise(folder):
        path = _write(folder, "n.stl", bytes(range(256)) * 4)
        return lambda: read_mesh(path).vertices

    cases.append(Case("api", "read_mesh(random bytes)", noise, ERROR))
    return cases


def _mesh_scale_cases() -> list[Case]:
    """Degeneracy judged against the part's size, and files of several separate bodies."""
    import trimesh

    cases = []

    def char_case(name, mesh, expect, suffix="obj", extra=()):
        def make(folder):
            path = _write(folder, f"part.{suffix}", mesh.export(file_type=suffix))
            return ["characterize", path, "--out", folder / "out.model.json", "--json", *extra]

        cases.append(Case("mesh_scale", name, make, expect))

    for scale in (1e-3, 1.0, 1e11):
        cube = trimesh.creation.box(extents=(scale, 2 * scale, 3 * scale))
        char_case(f"cube_at_{scale:g}.obj", cube, ANSWER)
        char_case(f"cube_at_{scale:g}.stl", cube, ANSWER, "stl")
    boxes = trimesh.util.concatenate(
        [
            trimesh.creation.box(extents=(1, 1, 1)).apply_translation([3.0 * k, 0, 0])
            for k in range(200)
        ]
    )
    char_case("200_separate_boxes.glb", boxes, ERROR, "glb")
    char_case("200_separate_boxes.glb_merge_bodies", boxes, ANSWER, "glb", ("--merge-bodies",))

    def elig_case(name, content, expect):
        def make(folder):
            path = _write(folder, "m.model.json", content)
            return ["eligibility", path, "--elements", "0,1,2,3", "--type", "pcwf", "--json"]

        cases.append(Case("mesh_scale", name, make, expect))

    base = _box_model()
    for scale in (1e-15, 1e-3, 1e11):
        scaled = json.loads(json.dumps(base))
        for e in scaled["elements"]:
            e["vertices"] = [[x * scale for x in v] for v in e["vertices"]]
        elig_case(f"box_model_at_{scale:g}", scaled, ANSWER)
        for label, size in (("triangle", 1e-15), ("sliver", 1.0)):
            tri = [
                [-1, 0, 0],
                [-1, size, 0],
                [-1, size / 2, 1e-9 * size if label == "sliver" else size],
            ]
            facet = {
                "kind": "facet",
                "vertices": [[x * scale for x in v] for v in tri],
                "inward_normal": [1, 0, 0],
            }
            elig_case(
                f"{label}_{size:g}_in_box_at_{scale:g}",
                {**scaled, "elements": [*scaled["elements"], facet]},
                ERROR,
            )
    return cases


# --- the file system, the environment, strict reading -----------------------------------------

FIFO = "is a FIFO (named pipe), not a regular file"
CHAR_DEVICE = "is a character device, not a regular file"


def _fifo(folder: Path, name: str) -> Path:
    path = folder / name
    os.mkfifo(path)
    return path


def _sparse(folder: Path, name: str, size: int = 2 * 2**30) -> Path:
    path = folder / name
    with path.open("wb") as handle:
        handle.truncate(size)
    return path


def _special_input_cases() -> list[Case]:
    """Inputs that are not regular files, or too large: refused at once, naming them (each runs
    in a child process, so that one that blocks is a hang, not a stuck corpus)."""
    cases = []
    model_path = LAMP

    def commands(path: Path, folder: Path) -> dict:
        return {
            "rho": ["rho", path],
            "eligibility": ["eligibility", path, "--elements", "0,1,2,3"],
            "study": ["study", path, "--out", folder / "out", "--limit", "0"],
            "show --contacts": ["show", model_path, "--contacts", path, "--out", folder / "x.png"],
            "characterize": ["characterize", path, "--out", folder / "o.model.json"],
        }

    sources = {
        "fifo": (lambda f, n: _fifo(f, n), FIFO),
        "dev_zero": (lambda f, n: Path("/dev/zero"), CHAR_DEVICE),
        "dev_urandom": (lambda f, n: Path("/dev/urandom"), CHAR_DEVICE),
        "sparse_2GiB": (lambda f, n: _sparse(f, n), "file of 2 GiB is over the 256 MiB limit"),
        "folder": (lambda f, n: f, "is a folder, not a regular file"),
    }
    names = {
        "rho": "c.contacts.json",
        "eligibility": "m.model.json",
        "study": "s.toml",
        "show --contacts": "c.contacts.json",
        "characterize": "m.stl",
    }
    for command, filename in names.items():
        for label, (make_path, needle) in sources.items():
            if command == "characterize" and label == "sparse_2GiB":
                needle = needle.replace("256 MiB", "1 GiB")

            def make(folder, command=command, filename=filename, make_path=make_path):
                path = make_path(folder, filename)
                return Process(commands(path, folder)[command])

            cases.append(Case("special files", f"{command} {label}", make, ERROR, 2, needle))

    def symlink(folder):
        (folder / "c.contacts.json").symlink_to(ROOT / "examples" / "box_7fpc.contacts.json")
        return ["rho", folder / "c.contacts.json", "--json"]

    cases.append(Case("special files", "rho symlink to a file", symlink, ANSWER, 0))

    def mesh_fifo(folder):  # a model whose mesh is a FIFO: the mesh only serves pictures
        _fifo(folder, "part.stl")
        data = _with(_box_model(), ("mesh",), "part.stl")
        path = _write(folder, "m.model.json", data)
        return Process(["eligibility", path, "--elements", "0,1,2,3", "--json"])

    cases.append(Case("special files", "model's mesh is a FIFO", mesh_fifo, ANSWER, 0))

    def study_model_fifo(folder):
        _fifo(folder, "fifo.model.json")
        path = _write(folder, "s.toml", 'models = ["fifo.model.json"]\ncontacts = 4\n')
        return Process(["study", path, "--out", folder / "out", "--limit", "0"])

    cases.append(Case("special files", "study of a FIFO model", study_model_fifo, ERROR, 2, FIFO))
    return cases


def _special_outputs(folder: Path) -> dict:
    """A FIFO, a socket and a copy of /dev/null (a device node: root may make one; else the
    system's own stands in) to write onto."""
    fifo = _fifo(folder, "out.fifo")
    sock = folder / "out.sock"
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(sock))
    server.close()  # the socket file stays
    null = folder / "null"
    try:
        os.mknod(null, 0o666 | 0o020000, os.makedev(1, 3))
    except PermissionError:
        null = Path("/dev/null")
    return {
        "fifo": (fifo, "a FIFO"),
        "socket": (sock, "a socket"),
        "device": (null, "a character device"),
    }


def _output_cases() -> list[Case]:
    """Outputs onto special files are refused (exit 2), never replaced by a regular file."""
    cases = []
    box = _box_model()
    for kind in ("fifo", "socket", "device"):
        for command in ("place", "show", "characterize", "plan"):

            def make(folder, kind=kind, command=command):
                out, _ = _special_outputs(folder)[kind]
                model = _write(folder, "m.model.json", box)
                return {
                    "place": ["place", model, "--elements", "0,1,2,3", "--out", out],
                    "show": ["show", model, "--out", out],
                    "characterize": ["characterize", CUP_MESH, "--out", out],
                    "plan": ["plan", model, "--contacts", "4", "--out", out],
                }[command]

            words = dict(fifo="a FIFO", socket="a socket", device="a character device")[kind]
            needle = "exists and is not a folder" if command == "plan" else f"exists and is {words}"
            cases.append(Case("outputs", f"{command} --out {kind}", make, ERROR, 2, needle))
    return cases


def _environment_cases() -> list[Case]:
    """Faults of the environment: exit 1 and one error line (never 3, never a lost answer);
    a malformed scheduler address is bad input (2); names shown escaped."""
    cases = []
    box_contacts = ROOT / "examples" / "box_7fpc.contacts.json"
    cases.append(
        Case(
            "environment",
            "stdout /dev/full",
            lambda f: Process(["rho", box_contacts], stdout="full"),
            ANSWER,
            1,
            "error: stdout: cannot write: No space left on device",
        )
    )
    cases.append(
        Case(
            "environment",
            "stdout closed",
            lambda f: Process(["rho", box_contacts], stdout="closed"),
            ANSWER,
            1,
            "error: stdout: closed",
        )
    )

    def copy(folder, name):
        path = folder / name
        path.write_bytes(box_contacts.read_bytes())
        return path

    cases.append(
        Case(
            "environment",
            "non-ASCII name, PYTHONIOENCODING=ascii",
            lambda f: Process(
                ["rho", copy(f, "caf\u00e9.contacts.json")], env={"PYTHONIOENCODING": "ascii"}
            ),
            ANSWER,
            1,
            "error: stdout: cannot print",
        )
    )
    cases.append(
        Case(
            "environment",
            "non-ASCII name, ascii, --json",
            lambda f: Process(
                ["rho", copy(f, "caf\u00e9.contacts.json"), "--json"],
                env={"PYTHONIOENCODING": "ascii"},
            ),
            ANSWER,
            0,
        )
    )
    cases.append(
        Case(
            "environment",
            "characterize onto a full disk",
            lambda f: Process(
                ["characterize", CUP_MESH, "--out", f / "c.model.json"], file_size=2000
            ),
            ANSWER,
            1,
            "cannot write: File too large",
        )
    )
    study = f'models = ["{LAMP.as_posix()}"]\ncontacts = 4\n'
    for address in ("garbage", "tcp://host", "tcp://host:0", "ftp://host:1", "host:\uff18"):
        cases.append(
            Case(
                "environment",
                f"--scheduler {address}",
                lambda f, a=address: [
                    "study",
                    _write(f, "s.toml", study),
                    "--out",
                    f / "out",
                    "--scheduler",
                    a,
                ],
                ERROR,
                2,
                "--scheduler: ",
            )
        )
    for label, name, shown in [
        ("newline", "a\nb.json", "a\\nb.json"),
        ("escape", "x\x1b[2J.json", "x\\x1b[2J.json"),
        ("bell", "x\x07.json", "x\\x07.json"),
    ]:
        cases.append(
            Case(
                "environment",
                f"missing file with a {label} in its name",
                lambda f, n=name: ["rho", f / n],
                ERROR,
                2,
                shown,
            )
        )
        cases.append(
            Case(
                "environment",
                f"answer for a file with a {label} in its name",
                lambda f, n=name: Process(["rho", copy(f, n)]),
                ANSWER,
                0,
            )
        )
    return cases


def _strict_cases() -> list[Case]:
    """Closed lists compared exactly, duplicate keys, ASCII digits, ordered ids, numpy
    scalars, and API objects that keep copies of what they validated."""
    cases = []
    box = _box_model()

    def contacts_case(name, content, expect, code, message):
        cases.append(
            Case(
                "strict",
                name,
                lambda f, c=content: ["rho", _write(f, "c.contacts.json", c)],
                expect,
                code,
                message,
            )
        )

    for label, value in [
        ("nbsp", "fpc\u00a0"),
        ("space", "fpc "),
        ("tab", "\tfpc"),
        ("fullwidth", "\uff46\uff50\uff43"),
        ("zero_width", "fp\u200bc"),
    ]:
        contacts_case(
            f"type {label}",
            _with(PAIR, ("contacts", 0, "type"), value),
            ERROR,
            2,
            "contacts[0].type: unknown contact type",
        )
    for units in ("km", "mm ", "MM", "\u00b5m"):
        contacts_case(
            f"contacts units {units!r}", {**PAIR, "units": units}, ERROR, 2, "units: unknown unit"
        )
        cases.append(
            Case(
                "strict",
                f"model units {units!r}",
                lambda f, u=units: [
                    "eligibility",
                    _write(f, "m.model.json", {**box, "units": u}),
                    "--elements",
                    "0,1,2,3",
                ],
                ERROR,
                2,
                "units: unknown unit",
            )
        )
    text = json.dumps(PAIR)
    contacts_case(
        "duplicate 'contacts'",
        text[:-1] + ', "contacts": []}',
        ERROR,
        2,
        "duplicate key 'contacts'",
    )
    contacts_case(
        "duplicate nested 'type'",
        text.replace('"type": "sfce"', '"type": "sfce", "type": "fpc"', 1),
        ERROR,
        2,
        "duplicate key 'type'",
    )
    cases.append(
        Case(
            "strict",
            "duplicate model key",
            lambda f: [
                "eligibility",
                _write(f, "m.model.json", json.dumps(box)[:-1] + ', "name": "x"}'),
                "--elements",
                "0,1,2,3",
            ],
            ERROR,
            2,
            "duplicate key 'name'",
        )
    )
    for flag, value in [
        ("--elements", "\uff14\uff18,1,2,3"),
        ("--elements", "0,1,2,\u0663"),
        ("--mu", "\uff10.5"),
        ("--f-max", "\uff11"),
        ("--type", "fpc\u00a0"),
    ]:
        args = ["--elements", "0,1,2,3"] if flag != "--elements" else []
        cases.append(
            Case(
                "strict",
                f"eligibility {flag}={value!r}",
                lambda f, fl=flag, v=value, a=args: [
                    "eligibility",
                    _write(f, "m.model.json", box),
                    *a,
                    fl,
                    v,
                ],
                ERROR,
                2,
                None,
            )
        )
    cases.append(
        Case(
            "strict",
            "plan --contacts \uff14",
            lambda f: ["plan", _write(f, "m.model.json", box), "--contacts", "\uff14"],
            ERROR,
            2,
            None,
        )
    )

    from closure_nlp.contact.contact_set import Contact, ContactSet, contact_set_from_dict
    from closure_nlp.criterion.rho_hat import Eligibility
    from closure_nlp.criterion.support_minimum import rho
    from closure_nlp.model.elements import model_from_dict
    from closure_nlp.model.scale import contact_specs
    from closure_nlp.placement.options import PlacementOptions
    from closure_nlp.selection.algorithms import heuristic

    model = model_from_dict(box)
    specs = contact_specs(4)

    def api(name, call, expect, message=None):
        cases.append(Case("strict", name, lambda folder, call=call: call, expect, None, message))

    api(
        "Eligibility(set of ids)",
        lambda: Eligibility(model, specs)({0, 1, 2, 3}).rho_hat,
        ERROR,
        "(no order)",
    )
    api(
        "heuristic(start=set)",
        lambda: heuristic(Eligibility(model, specs), start={0}).rho_hat,
        ERROR,
        "(no order)",
    )
    api(
        "Eligibility(certify=np.bool_)",
        lambda: Eligibility(model, specs)([0, 1, 2, 3], certify=np.bool_(True)).rho_hat,
        ANSWER,
    )
    api(
        "Eligibility(numpy ids)",
        lambda: Eligibility(model, contact_specs(np.int64(4)))(np.array([0, 1, 2, 3])).rho_hat,
        ANSWER,
    )
    api(
        "PlacementOptions(numpy scalars)",
        lambda: PlacementOptions(starts=np.int64(2), certify=np.bool_(False)).starts,
        ANSWER,
    )
    api(
        "rho(certify=np.bool_)",
        lambda: rho(contact_set_from_dict(BOX), certify=np.bool_(True)).rho,
        ANSWER,
    )

    def reused_buffer():
        """Every contact built from one buffer, then the buffer filled with NaN."""
        position, normal, made = np.empty(3), np.empty(3), []
        for entry in BOX["contacts"]:
            position[:], normal[:] = entry["position"], entry["inward_normal"]
            made.append(Contact(position, normal, "fpc"))
        position[:], normal[:] = np.nan, np.nan
        value = rho(ContactSet(tuple(made))).rho
        expected = rho(contact_set_from_dict(BOX)).rho
        if abs(value - expected) > 1e-9 * max(1.0, abs(expected)):
            raise RuntimeError(f"rho {value} of the reused buffer, {expected} of the file")
        return value

    api("Contact(reused buffer, then NaN)", reused_buffer, ANSWER)
    return cases


def _reliability_cases() -> list[Case]:
    """Verdicts that must follow their certified bracket, numbers the kernels must not take in
    silently, results that must stay as certified, and counts the parser must refuse."""
    from closure_nlp.contact.contact_set import Contact, contact_set_from_dict
    from closure_nlp.contact.wrenches import WrenchSlots
    from closure_nlp.criterion.certificate import certified_bounds, tolerance_unit
    from closure_nlp.criterion.hull_distance import min_norm_point
    from closure_nlp.criterion.rho_hat import Eligibility
    from closure_nlp.criterion.support_minimum import rho
    from closure_nlp.model.elements import model_from_dict
    from closure_nlp.model.scale import contact_specs

    cases = []

    def api(name, call, expect, message=None):
        cases.append(
            Case("reliability", name, lambda folder, call=call: call, expect, None, message)
        )

    def sphere_verdict():
        """6 SFCe at +-e_k of a unit sphere, mu 1e6, mu_s 1e12: once force closure with the
        bracket reaching 0."""
        contacts = [
            {"position": list(s * axis), "inward_normal": list(-s * axis)}
            for axis in np.eye(3)
            for s in (1.0, -1.0)
        ]
        data = {"defaults": {"type": "sfce", "mu": 1e6, "mu_s": 1e12}, "contacts": contacts}
        contact_set = contact_set_from_dict(data)
        result = rho(contact_set)
        lo, hi = result.bounds
        zero = 1e-6 * tolerance_unit(WrenchSlots.from_contacts(contact_set))
        if result.force_closure and not hi < -zero:
            raise RuntimeError(f"force closure with bounds {result.bounds}")
        if result.marginal and result.force_closure:
            raise RuntimeError("marginal and force closure")
        if not (result.force_closure or result.marginal or lo > zero):
            raise RuntimeError(f"neither verdict with bounds {result.bounds}")
        return [result.rho, lo, hi]

    api("rho(6 SFCe, mu 1e6, mu_s 1e12): verdict of the bracket", sphere_verdict, ANSWER)
    api(
        "min_norm_point(NaN row)",
        lambda: min_norm_point(np.array([[1.0, 0.0], [np.nan, 1.0]]))[0],
        ERROR,
        "points",
    )
    api(
        "min_norm_point(inf row)",
        lambda: min_norm_point(np.array([[1.0, 0.0], [np.inf, 1.0]]))[0],
        ERROR,
        "points",
    )
    pair = contact_set_from_dict(PAIR)

    def write_into(get):
        def call():
            array = get()
            array[0] = 7.0  # must raise: a certified result does not change
            return array

        return call

    api("RhoResult.direction written", write_into(lambda: rho(pair).direction), ERROR, "read-only")
    api(
        "RhoResult.support_point written",
        write_into(lambda: rho(pair).support_point),
        ERROR,
        "read-only",
    )
    api(
        "CertifiedBounds.direction written",
        write_into(lambda: certified_bounds(pair).direction),
        ERROR,
        "read-only",
    )
    box = model_from_dict(_box_model())
    api(
        "EligibilityResult.direction written",
        write_into(lambda: Eligibility(box, contact_specs(4))([0, 1, 2, 3]).direction),
        ERROR,
        "read-only",
    )
    masked = np.ma.array([0.0, 0.0, -1.0], mask=[False, True, False])
    for label, kwargs, expect, message in [
        ("normal bool array", {"inward_normal": np.array([False, False, True])}, ERROR, "normal"),
        ("normal masked entry", {"inward_normal": masked}, ERROR, "inward_normal"),
        ("position masked entry", {"position": np.ma.array([0, 0, 1.0], mask=[1, 0, 0])}, ERROR,
         "position"),
        ("normal masked, none masked", {"inward_normal": np.ma.array([0, 0, -1.0])}, ANSWER, None),
    ]:  # fmt: skip
        args = {"position": [0, 0, 1], "inward_normal": [0, 0, -1], **kwargs}
        api(f"Contact({label})", lambda args=args: Contact(**args).inward_normal, expect, message)

    def plan_flag(flag, value):
        def make(folder):
            path = _write(folder, "m.model.json", _box_model())
            return ["plan", path, "--contacts", "4", flag, value]

        return make

    cases.append(
        Case(
            "reliability",
            "plan --alternatives=-1",
            plan_flag("--alternatives", "-1"),
            ERROR,
            2,
            "--alternatives",
        )
    )
    return cases


def corpus() -> list[Case]:
    """Every case, in group order."""
    return [
        *_contact_cases(),
        *_model_cases(),
        *_mesh_cases(),
        *_mesh_scale_cases(),
        *_study_cases(),
        *_flag_cases(),
        *_api_cases(),
        *_special_input_cases(),
        *_output_cases(),
        *_environment_cases(),
        *_strict_cases(),
        *_reliability_cases(),
    ]


def table(results) -> str:
    """The table of outcomes: per group, inputs tried and how each ended."""
    groups: dict[str, dict[str, int]] = {}
    for case, outcome in results:
        row = groups.setdefault(case.group, {})
        row[outcome.kind] = row.get(outcome.kind, 0) + 1
    lines = [
        "| group | inputs | clear error | answer | traceback | NaN | hang | as expected |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for group, row in groups.items():
        tried = sum(row.values())
        expected = sum(1 for c, o in results if c.group == group and as_expected(c, o))
        lines.append(
            f"| {group} | {tried} | {row.get('error', 0)} | {row.get('answer', 0)} | "
            f"{row.get('traceback', 0)} | {row.get('nan', 0)} | {row.get('hang', 0)} | "
            f"{expected} |"
        )
    return "\n".join(lines)


def listing(results) -> str:
    """Each case by group: the input, what it must end with (kind, exit status, message) and
    what it did."""
    lines, group = [], None
    for case, outcome in results:
        if case.group != group:
            group = case.group
            lines.append(f"\n## {group}")
        wanted = case.expect + (f", exit {case.code}" if case.code is not None else "")
        if case.message:
            wanted += f", {case.message!r}"
        got = outcome.kind + (f", exit {outcome.code}" if outcome.code is not None else "")
        mark = "ok" if as_expected(case, outcome) else "UNEXPECTED"
        lines.append(f"- {mark}: {case.name!r}: expected {wanted}; got {got}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """``python -m tests.hostile [--list] [GROUP...]``: the table by group (and with ``--list``
    every case); groups name the ones to run (default all)."""
    import tempfile

    args = sys.argv[1:] if argv is None else argv
    groups = [a for a in args if not a.startswith("--")]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, case in enumerate(corpus()):
            if groups and case.group not in groups:
                continue
            outcome = run_case(case, Path(tmp) / f"case{k}")
            results.append((case, outcome))
            if not as_expected(case, outcome):
                pending = f" (pending: {case.pending})" if case.pending else ""
                print(
                    f"UNEXPECTED {case.id}: expected {case.expect} {case.code} "
                    f"{case.message!r}, got {outcome.kind}: {outcome.detail[:300]}{pending}",
                    flush=True,
                )
    if "--list" in args:
        print(listing(results))
    print(table(results))
    slow = sorted(results, key=lambda r: -r[1].seconds)[:5]
    print("slowest:", ", ".join(f"{c.id} {o.seconds:.1f} s" for c, o in slow))


if __name__ == "__main__":
    os.environ.setdefault("MPLBACKEND", "Agg")
    main()
