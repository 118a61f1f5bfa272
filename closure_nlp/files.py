"""Reading and writing files: JSON with errors that say what is wrong, writes that are atomic."""

from __future__ import annotations

import json
import math
import os
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
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
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
    try:
        loaded = trimesh.load(str(path), force="mesh", process=True)
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
