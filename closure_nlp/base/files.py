"""Reading and writing files: JSON with errors that say what is wrong, writes that are atomic.

Inputs
------
Every file a command or the API reads (contact sets, models, meshes, studies) goes through
:func:`check_input` first: it must be a regular file (or a symbolic link to one) of at most
``MAX_INPUT_BYTES`` (256 MiB; meshes ``MAX_MESH_BYTES``, 1 GiB). A FIFO, a device (``/dev/zero``,
``/dev/urandom``), a socket or a folder is refused before it is read, and so is a file over the
limit (a 2 GiB sparse file included), so reading never blocks and its memory is bounded.

Outputs
-------
Files are written through a temporary file and a rename (:func:`write_atomic`); an existing
device, FIFO or socket at the path is refused, never replaced. Folders are written as a set
(:func:`staged_folder`) and exchanged with the previous one in one step where the system has it.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import glob
import json
import math
import os
import shutil
import stat
import tempfile
from pathlib import Path

MAX_INPUT_BYTES = 256 * 2**20  # a JSON or TOML input: models of ~10^5 elements fit
MAX_MESH_BYTES = 2**30  # a mesh file: ~2 * 10^7 triangles of binary STL


def _kind(mode: int) -> str:
    """A file type in words, for the message that refuses it."""
    for test, name in (
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def _size_text(size: int) -> str:
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{size} bytes"


def _check_regular(info: os.stat_result, limit: int) -> None:
    if not stat.S_ISREG(info.st_mode):
        kind = _kind(info.st_mode)
        raise ValueError(f"is {kind}, not a regular file" if kind.startswith("a ") else kind)
    if info.st_size > limit:
        raise ValueError(
            f"file of {_size_text(info.st_size)} is over the {_size_text(limit)} limit for "
            "input files"
        )


def check_input(path, limit: int = MAX_INPUT_BYTES) -> Path:
    """Refuse, before it is opened, an input that is not a regular file of at most ``limit``
    bytes (a symbolic link to one is followed): a FIFO would block, a device never end.

    Raises
    ------
    ValueError
        ``file not found``, ``is a FIFO (named pipe), not a regular file``, ``file of 2 GiB is
        over the 256 MiB limit for input files``...
    """
    path = Path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise ValueError("file not found") from None
    except OSError as exc:
        raise ValueError(f"cannot read file: {exc.strerror or exc}") from None
    _check_regular(info, limit)
    return path


def read_input(path, limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of an input file, checked by :func:`check_input` and read in at most ``limit``
    bytes: opened without blocking, checked again on the open file (it may have been swapped),
    and refused if it grew past the limit while read."""
    path = check_input(path, limit)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise ValueError("file not found") from None
    except OSError as exc:
        raise ValueError(f"cannot read file: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb", buffering=0) as handle:
        _check_regular(os.fstat(fd), limit)
        try:
            data = handle.read(limit + 1)
        except OSError as exc:
            raise ValueError(f"cannot read file: {exc.strerror or exc}") from None
    if data is None or len(data) > limit:
        raise ValueError(f"file grew over the {_size_text(limit)} limit for input files")
    return data


def _no_duplicates(pairs: list) -> dict:
    """``object_pairs_hook``: a key given twice is refused (json keeps the last silently)."""
    out = dict(pairs)
    if len(out) != len(pairs):
        seen = set()
        for key, _ in pairs:
            if key in seen:
                raise _DuplicateKey(key)
            seen.add(key)
    return out


class _DuplicateKey(ValueError):
    def __init__(self, key: str):
        super().__init__(key)
        self.key = key


def parse_json(text: str | bytes) -> object:
    """JSON text as Python values; malformed text and a key given twice in one object are a
    ``ValueError`` that says where (line and column) or which key."""
    try:
        return json.loads(text, object_pairs_hook=_no_duplicates)
    except _DuplicateKey as exc:
        raise ValueError(f"duplicate key {escape(repr(exc.key))} in one object") from None
    except json.JSONDecodeError as exc:
        raise ValueError(
            f"malformed JSON at line {exc.lineno} column {exc.colno}: {exc.msg}"
        ) from None
    except RecursionError:
        raise ValueError("JSON nested too deeply to read") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"cannot read file: not UTF-8 text ({exc.reason})") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise ValueError(f"malformed JSON: {exc}") from None


def load_json(path) -> object:
    """Read a JSON file (:func:`read_input`); a missing, special, oversized, unreadable or
    malformed file, or one with a duplicate key, is a ``ValueError``."""
    data = read_input(path)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"cannot read file: not UTF-8 text ({exc.reason})") from None
    return parse_json(text)


def escape(text: str) -> str:
    """``text`` with control characters shown as escapes (``\\n``, ``\\x1b``), so that a name
    in a message stays on one line and cannot drive the terminal."""
    if text.isprintable():
        return text
    return "".join(
        ch if ch.isprintable() or ch == " " else ch.encode("unicode_escape").decode("ascii")
        for ch in text
    )


def write_atomic(path, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and a rename.

    A crash or an exception while writing never leaves a half-written ``path``: readers see the
    old file or the whole new one. An existing device, FIFO, socket or folder at ``path`` is a
    ``ValueError``: it is never replaced by a regular file.
    """
    path = Path(path)
    _check_replaceable(path, str(path))
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
        _check_replaceable(path, str(path))  # again: it may have appeared while writing
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _check_replaceable(path: Path, field: str) -> None:
    """An output file may replace a regular file (or a link to one), never anything else."""
    try:
        info = os.stat(path)
    except OSError:  # missing (or a dangling link): written anew
        return
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"{field}: exists and is {_kind(info.st_mode)}, not a regular file")


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


def non_finite_key(value) -> str | None:
    """The key path (``placement.rho``, ``history[3]``) of the first NaN or infinity in a
    JSON-able value, or None when every number is finite."""
    path = _non_finite_path(value)
    if path is None:
        return None
    key = "".join(f".{k}" if isinstance(k, str) else f"[{k}]" for k in reversed(path))
    return key.lstrip(".") or "value"


def _non_finite_path(value) -> list | None:
    """The keys down to the first NaN or infinity in ``value``, innermost first (named only
    when one is found: an answer's every number is checked before it is printed)."""
    if isinstance(value, float):
        return None if math.isfinite(value) else []
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, (list, tuple)):
        items = enumerate(value)
    else:
        return None
    for k, v in items:
        found = _non_finite_path(v)
        if found is not None:
            found.append(k)
            return found
    return None


# --- output paths: checked before any work, folders written as a set ------------------------


def check_output_file(path, field: str = "--out") -> Path:
    """Refuse, before any work, an output file that could not be written: a folder, a device,
    a FIFO or a socket of that name, a path under a file, or a place this process cannot
    write."""
    path = Path(path)
    try:
        _check_replaceable(path, field)
    except ValueError as exc:
        message = str(exc).replace("is a folder, not a regular file", "is a folder, not a file")
        raise ValueError(message) from None
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


# Called with the name of each step of staged_folder as it is reached: tests make a fault
# (an exception, a kill) there to show that the previous folder survives every one.
_step_hook = None


def _step(name: str) -> None:
    if _step_hook is not None:
        _step_hook(name)


@contextlib.contextmanager
def staged_folder(path):
    """Write a folder as a set: yields a temporary folder beside ``path`` that replaces it only
    when the block ends without an exception, so readers never see a mix of two runs or a
    partial set.

    The two folders are exchanged in one step (Linux ``renameat2(RENAME_EXCHANGE)``), so a kill
    at any instant leaves the old folder or the new one at ``path``. Where the system has no
    exchange, two renames are used; a kill between them leaves the old folder as
    ``.NAME.old-PID``, which the next writer (or :func:`recover_folder`) moves back to ``path``.
    Stale temporary folders of killed runs are removed by the next writer.
    """
    out = Path(path).absolute()
    out.parent.mkdir(parents=True, exist_ok=True)
    recover_folder(out)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-{os.getpid()}-", dir=out.parent))
    try:
        _step("staged")
        yield tmp
        _step("written")
        os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700
        if out.exists() and _exchange(tmp, out):
            _step("exchanged")  # tmp now holds the old folder, removed below
        elif out.exists():
            old = out.parent / f".{out.name}.old-{os.getpid()}"
            os.rename(out, old)
            try:
                _step("moved-old")
                os.rename(tmp, out)
            except BaseException:
                os.rename(old, out)
                raise
            try:
                _step("moved-new")
            finally:
                shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(tmp, out)
            _step("moved-new")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _renameat2():
    """libc's ``renameat2`` (Linux, glibc >= 2.28), or None."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
        function = libc.renameat2
    except (OSError, AttributeError):
        return None
    function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p]
    function.argtypes += [ctypes.c_uint]
    function.restype = ctypes.c_int
    return function


_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_RENAMEAT2 = _renameat2() if os.name == "posix" else None


def _exchange(a: Path, b: Path) -> bool:
    """Swap two existing paths atomically; False where the system or file system cannot."""
    if _RENAMEAT2 is None:
        return False
    result = _RENAMEAT2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if result == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(code, os.strerror(code), str(b))


def recover_folder(path) -> None:
    """Finish what killed writers of the folder ``path`` left: a previous folder moved aside
    (``.NAME.old-PID``) goes back to ``path`` when ``path`` is missing, else it is removed
    with the other temporary folders of processes that are gone."""
    out = Path(path).absolute()
    if not out.exists():
        for entry in sorted(out.parent.glob(f".{glob.escape(out.name)}.old-*")):
            pid = entry.name.rsplit("-", 1)[-1]
            if entry.is_dir() and pid.isdigit() and not _alive(int(pid)):
                os.rename(entry, out)
                break
    _remove_stale(out)


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
