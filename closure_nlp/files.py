"""Reading and writing files: JSON with errors that say what is wrong, writes that are atomic."""

from __future__ import annotations

import contextlib
import glob
import json
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np


def load_json(path) -> object:
    """Read a JSON file; a missing, unreadable or malformed file is a ``ValueError``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError("file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read file: {exc.__class__.__name__}: {exc}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(
            f"malformed JSON at line {exc.lineno} column {exc.colno}: {exc.msg}"
        ) from None
    except RecursionError:
        raise ValueError("JSON nested too deeply to read") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise ValueError(f"malformed JSON: {exc}") from None


def write_atomic(path, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and a rename.

    A crash or an exception while writing never leaves a half-written ``path``: readers see the
    old file or the whole new one.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = "wb" if isinstance(data, bytes) else "w"
    _remove_stale(path, ".tmp")
    fd, tmp = tempfile.mkstemp(
        prefix=f".{path.name}.partial-{os.getpid()}-", suffix=".tmp", dir=path.parent
    )
    try:
        with os.fdopen(fd, mode, **({} if mode == "wb" else {"encoding": "utf-8"})) as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; a plain file respects the umask
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_json(path, data) -> Path:
    """Write ``data`` as indented JSON, atomically; NaN and infinity are refused, naming the key
    (json's own "Out of range float values are not JSON compliant" names none)."""
    key = non_finite_key(data)
    if key is not None:
        raise ValueError(f"{path}: refusing to write the non-finite number at {key}")
    return write_atomic(path, json.dumps(data, indent=1, allow_nan=False) + "\n")


def non_finite_key(value, key: str = "") -> str | None:
    """The key path (``placement.rho``, ``history[3]``) of the first NaN or infinity in a
    JSON-able value, or None when every number is finite."""
    if isinstance(value, float):
        return None if math.isfinite(value) else key or "value"
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, (list, tuple)):
        items = enumerate(value)
    else:
        return None
    for k, v in items:
        found = non_finite_key(v, f"{key}.{k}" if isinstance(k, str) else f"{key}[{k}]")
        if found:
            return found.lstrip(".")
    return None


def read_mesh(path, source: str | None = None):
    """A ``trimesh.Trimesh`` from a mesh file (STL, OBJ, PLY, GLB, OFF...).

    Every way a file can fail is a ``ValueError`` that names it: missing, a format trimesh does
    not read, bytes that are not a mesh of that format (trimesh's own errors for those are
    ``ModuleNotFoundError`` or ``NotImplementedError``), no triangles, coordinates out of range.
    """
    import trimesh

    from .validation import MAX_COORDINATE

    path = Path(path)
    source = source or str(path)
    if not path.is_file():
        raise ValueError(f"{source}: file not found")
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in trimesh.available_formats():
        raise ValueError(
            f"{source}: not a mesh file (unknown suffix {path.suffix!r}; "
            "use .stl, .obj, .ply, .glb, .off...)"
        )
    if suffix == "stl":
        _check_stl(path, source)
    try:  # unprocessed first: processing silently drops non-finite vertices
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds for a bad file
        # A text format that is not text ends in trimesh's search for a charset module.
        detail = "bytes that are not text" if isinstance(exc, ImportError) else str(exc)
        raise ValueError(
            f"{source}: not a valid {suffix.upper()} mesh: {detail[:100] or type(exc).__name__}"
        ) from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ValueError(f"{source}: no triangles found (not a mesh file, or an empty mesh)")
    vertices = np.asarray(loaded.vertices)
    if not np.all(np.isfinite(vertices)):
        raise ValueError(f"{source}: vertices: numbers must be finite")
    if float(np.abs(vertices).max()) > MAX_COORDINATE:
        raise ValueError(
            f"{source}: vertices: |coordinate| {float(np.abs(vertices).max()):.3g} is beyond "
            f"the accepted range [-{MAX_COORDINATE:g}, {MAX_COORDINATE:g}]"
        )
    loaded.process()  # merge duplicate vertices, drop degenerate faces (as process=True would)
    return loaded


def _check_stl(path: Path, source: str) -> None:
    """Binary STL: 80-byte header, triangle count, 50 bytes per triangle; or ASCII 'solid'."""
    size = path.stat().st_size
    with path.open("rb") as handle:
        head = handle.read(84)
    if size >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little"):
        return
    if head.lstrip().lower().startswith(b"solid"):
        try:
            head.decode("ascii")
            return
        except UnicodeDecodeError:
            pass
    raise ValueError(
        f"{source}: not an STL file (neither ASCII 'solid ...' nor a binary STL whose "
        f"triangle count matches its {size} bytes)"
    )


# --- output paths: checked before any work, folders written as a set ------------------------


def check_output_file(path, field: str = "--out") -> Path:
    """Refuse, before any work, an output file that could not be written: a folder of that
    name, a path under a file, or a place this process cannot write."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{field}: is a folder, not a file")
    _check_writable_parent(path, field)
    return path


def check_output_dir(path, field: str = "--out", marker: str | None = "report.json") -> Path:
    """Refuse, before any work, an output folder that could not be written as a set: an existing
    file, a path under a file, an unwritable place, or a folder holding files of something else
    (a rerun replaces the whole folder, so only an empty one or a previous run's, recognised by
    ``marker``, is accepted; ``marker=None`` accepts any folder, for outputs that add to it)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{field}: exists and is not a folder")
    if path.is_dir() and marker is not None:
        entries = [p.name for p in path.iterdir()]
        if entries and marker not in entries:
            raise ValueError(
                f"{field}: the folder holds other files ({', '.join(sorted(entries)[:3])}...); "
                f"use a new or empty folder, or one with a previous {marker}, which is replaced"
            )
    _check_writable_parent(path, field)
    return path


def _check_writable_parent(path: Path, field: str) -> None:
    ancestor = path.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ValueError(f"{field}: is under {ancestor}, which is a file")
    try:  # a real probe: permissions, read-only file systems, /proc all answer the same way
        fd, probe = tempfile.mkstemp(prefix=".closure_nlp-probe-", dir=ancestor)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ValueError(f"{field}: cannot write in {ancestor}: {exc.strerror or exc}") from None


@contextlib.contextmanager
def staged_folder(path):
    """Write a folder as a set: yields a temporary folder beside ``path`` that replaces it (by
    renames) only when the block ends without an exception, so readers never see a mix of two
    runs or a partial set. Stale temporary folders of killed runs are removed on the next one."""
    out = Path(path).absolute()
    out.parent.mkdir(parents=True, exist_ok=True)
    _remove_stale(out)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-{os.getpid()}-", dir=out.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700
        if out.exists():
            old = out.parent / f".{out.name}.old-{os.getpid()}"
            os.rename(out, old)
            try:
                os.rename(tmp, out)
            except BaseException:
                os.rename(old, out)
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _remove_stale(out: Path, suffix: str = "") -> None:
    """Temporary files or folders ``.NAME.partial-PID-*`` / ``.NAME.old-PID`` of processes that
    are gone (killed while writing): a kill -9 cannot clean up, so the next writer does."""
    for entry in out.parent.glob(f".{glob.escape(out.name)}.*{suffix}"):
        rest = entry.name[len(out.name) + 2 :]
        kind, _, tail = rest.partition("-")
        pid = tail.split("-", 1)[0]
        if kind in ("partial", "old") and pid.isdigit() and not _alive(int(pid)):
            if entry.is_dir():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True
