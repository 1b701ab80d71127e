"""Files that never lose the last good one and never trust what they read.

Writing: every file goes to a temporary beside its path, is flushed to disk and replaces
the path in one step (`write_atomically`), so a crash or a kill keeps the last good file;
`.npz` files record the morphojax version and a format number (`stamp`). Reading: a file
must be a regular file, an archive's members are checked from their headers (sizes,
compression ratio, metadata length) before anything is loaded, a newer file warns, and
every failure is one ValueError naming the file. Objects' plain-data forms are
`_serialise`'s; this module knows only paths, bytes and arrays.
"""

from __future__ import annotations

import json
import math
import os
import stat
import struct
import tempfile
import tokenize
import warnings
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from numpy.lib import format as npformat

from ._checks import cells_of, check_memory
from ._version import __version__


def to_jsonable(value):
    """Arrays and numbers to JSON-safe Python (lists, floats, 'inf' strings)."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return to_jsonable(np.asarray(value).tolist())
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return to_jsonable(float(value))
    return value


def from_jsonable(value):
    """Inverse of `to_jsonable` for numbers: 'inf', '-inf', 'nan' strings back to floats."""
    if isinstance(value, dict):
        return {k: from_jsonable(v) for k, v in value.items()}
    if isinstance(value, list):
        return [from_jsonable(v) for v in value]
    if value in ("inf", "-inf", "nan"):
        return float(value)
    return value


def dumps(obj, **kwargs) -> str:
    return json.dumps(to_jsonable(obj), allow_nan=False, **kwargs)


FORMAT_VERSION = 1  # the format number every file's metadata records (with the morphojax version)


def stamp(meta: dict) -> dict:
    """`meta` with the morphojax version and the format number that wrote it."""
    return {**meta, "morphojax": meta.get("morphojax") or __version__,
            "format_version": meta.get("format_version", FORMAT_VERSION)}


def _version_tuple(text) -> tuple:
    parts = []
    for piece in str(text).split("."):
        digits = "".join(ch for ch in piece if ch.isdigit()) if piece[:1].isdigit() else ""
        if not digits:
            break
        parts.append(int(digits))
    return tuple(parts)


def check_file_version(meta: dict, path=None) -> None:
    """Warn when a file was written by a newer morphojax or format than this one reads."""
    where = f"{path} was" if path is not None else "this file was"
    written, fmt = meta.get("morphojax"), meta.get("format_version")
    if isinstance(fmt, int) and not isinstance(fmt, bool) and fmt > FORMAT_VERSION:
        warnings.warn(f"{where} written in file format {fmt} (morphojax {written}); this morphojax "
                      f"{__version__} reads format {FORMAT_VERSION}, and fields it does not know are ignored",
                      stacklevel=3)
    elif isinstance(written, str) and _version_tuple(written) > _version_tuple(__version__):
        warnings.warn(f"{where} written by morphojax {written}, newer than this morphojax {__version__}",
                      stacklevel=3)


def write_npz(path, **arrays) -> Path:
    """`np.savez_compressed` that never leaves a half-written file (see `write_atomically`).
    Like NumPy, adds `.npz` when `path` has no such suffix. A JSON `metadata` entry gets the
    morphojax version and the format number (`stamp`)."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    if "metadata" in arrays:
        meta = json.loads(str(np.asarray(arrays["metadata"])))
        if isinstance(meta, dict):
            arrays["metadata"] = np.asarray(json.dumps(stamp(meta)))

    def write(tmp):
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, **arrays)

    return write_atomically(path, write)


def make_folder_of(path: Path) -> None:
    """Create the folder `path` goes in; one that cannot be made is a ValueError naming `path`."""
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(f"cannot write {path}: {err.strerror or err}") from None


def write_atomically(path, write) -> Path:
    """Write a file so that a crash never destroys the last good one: `write(temporary)`
    fills a temporary beside `path` (same suffix), which is flushed to disk and then replaces
    `path` in one step; a temporary whose writing failed is removed."""
    path = Path(path)
    check_output_path(path)
    make_folder_of(path)
    remove_stale_temporaries(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.{os.getpid()}-", suffix=path.suffix, dir=path.parent)
    except OSError as err:
        raise ValueError(f"cannot write {path}: {err.strerror or err}") from None
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # the user's umask, like any file (mkstemp makes 0600)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


# ---- reading: every archive checked before it is loaded, every failure one ValueError ---------
METADATA_LIMIT = 64 * 2**20  # bytes of JSON metadata a file may declare
BOMB_SIZE = 256 * 2**20  # a member declaring more than this ...
BOMB_RATIO = 200  # ... that expands more than this from its compressed size is refused
# what a broken archive raises inside zipfile, zlib and numpy (flipped bytes give "Bad CRC-32",
# a truncated member EOFError, a lying header TypeError / IndexError / struct.error)
READ_ERRORS = (KeyError, OSError, ValueError, EOFError, TypeError, IndexError, AttributeError, OverflowError,
               MemoryError, UnicodeError, SyntaxError, json.JSONDecodeError, zipfile.BadZipFile, zlib.error,
               struct.error, tokenize.TokenError)  # a garbled .npy header fails NumPy's literal parser
# ... and what zipfile alone raises on opening a member whose flag bits were flipped: RuntimeError
# ("encrypted, password required") or its NotImplementedError ("strong encryption", "compressed
# patched data"); `npz_members` opens every member first, so nothing later meets them
ARCHIVE_ERRORS = READ_ERRORS + (RuntimeError,)


def check_regular_file(path, what: str) -> Path:
    """`path` as a Path when it names an existing regular file; a folder, a named pipe or a
    device (`/dev/zero`) is refused, so a read never blocks or runs forever."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise ValueError(f"no such {what} file: {path}") from None
    except OSError as err:
        raise ValueError(f"cannot read {what} file {path}: {err.strerror or err}") from None
    if not stat.S_ISREG(mode):
        kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file (a pipe, a device or a socket)"
        raise ValueError(f"{what} file {path} is {kind}")
    return path


def npz_members(path, what: str = "npz") -> dict:
    """{member name: (shape, dtype)} of a `.npz`, read from each member's header without
    loading its data; refuses an archive whose members would need more memory than the limit
    (`_checks.memory_limit`), expand like a decompression bomb, or disagree with their headers."""
    path = check_regular_file(path, what)
    members, total = {}, 0
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                with archive.open(info) as handle:
                    version = npformat.read_magic(handle)
                    reader = {(1, 0): npformat.read_array_header_1_0, (2, 0): npformat.read_array_header_2_0,
                              (3, 0): getattr(npformat, "_read_array_header", None)}.get(version)
                    if reader is None:
                        raise ValueError(f"member {name!r} has an unknown .npy version {version}")
                    shape, _, dtype = (reader(handle) if version != (3, 0) else reader(handle, version))
                if dtype.hasobject:
                    raise ValueError(f"member {name!r} holds Python objects, which morphojax never writes")
                nbytes = cells_of(shape) * dtype.itemsize
                if nbytes > info.file_size:  # the header claims more data than the member holds
                    raise ValueError(f"member {name!r} declares {nbytes} bytes of data but holds {info.file_size}")
                if name == "metadata" and nbytes > METADATA_LIMIT:
                    raise ValueError(f"its metadata declares {nbytes / 2**20:.0f} MB; at most "
                                     f"{METADATA_LIMIT // 2**20} MB is read")
                if info.file_size > BOMB_SIZE and info.file_size > BOMB_RATIO * max(info.compress_size, 1):
                    raise ValueError(f"member {name!r} expands from {info.compress_size / 1e6:.3g} MB to "
                                     f"{info.file_size / 1e9:.3g} GB, more than {BOMB_RATIO} times (a decompression "
                                     "bomb?)")
                members[name] = (tuple(shape), dtype)
                total += nbytes
    except ARCHIVE_ERRORS as err:
        raise ValueError(f"{path} is not a morphojax {what} file ({_why(err)})") from None
    check_memory(total, f"reading {path}")
    return members


@contextmanager
def open_npz(path, what: str = "npz"):
    """`np.load(path)` of a checked archive (`npz_members`); any error while it is read, in the
    archive or in what the caller does with its arrays, is a ValueError naming the file."""
    path = Path(path)
    npz_members(path, what)
    try:
        with np.load(path, allow_pickle=False) as data:
            yield data
    except READ_ERRORS as err:
        if isinstance(err, ValueError) and str(err).startswith(str(path)):
            raise
        raise ValueError(f"{path} is not a morphojax {what} file ({_why(err)})") from None


def read_metadata(data, path=None) -> dict:
    """The JSON `metadata` member of an open archive as a dict (infinities restored)."""
    if "metadata" not in data.files:
        raise KeyError("metadata")
    meta = json.loads(str(data["metadata"]))
    if not isinstance(meta, dict):
        raise ValueError(f"its metadata is a JSON {type(meta).__name__}, not an object")
    check_file_version(meta, path)
    return from_jsonable(meta)


def _why(err) -> str:
    """What went wrong, in words: the exception's message, or its kind when it has none."""
    if isinstance(err, KeyError):
        key = str(err.args[0]) if err.args else ""
        if key.endswith(" is not a file in the archive"):  # NumPy's words for a missing member
            return f"no member {key.split(' ')[0]!r}"
        return f"no {key!r} entry" if key else "a missing entry"
    text = str(err).strip()
    return f"{type(err).__name__}: {text}" if text and not isinstance(err, ValueError) else (text or type(err).__name__)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


STALE_SECONDS = 60  # a temporary without its writer's process id is stale after this long


def remove_stale_temporaries(path) -> list[Path]:
    """Remove the temporaries (`.NAME.PID-*SUFFIX`) that a killed write of `path` left beside
    it: those whose writing process is gone (older ones, without a process id, once older than
    STALE_SECONDS), so a write running in another live process keeps its own."""
    import time

    path = Path(path)
    removed = []
    try:
        candidates = list(path.parent.glob(f".{glob_escape(path.stem)}.*{glob_escape(path.suffix)}"))
    except OSError:
        return removed
    for tmp in candidates:
        try:
            info = tmp.lstat()
            if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid():
                continue
            pid = tmp.name[len(path.stem) + 2:].split("-", 1)[0]
            if pid.isdigit() and int(pid) > 0:
                if int(pid) == os.getpid() or _alive(int(pid)):
                    continue
            elif time.time() - info.st_mtime <= STALE_SECONDS:
                continue
            tmp.unlink()
            removed.append(tmp)
        except OSError:
            continue
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def glob_escape(text: str) -> str:
    import glob

    return glob.escape(text)


def check_output_path(path) -> Path:
    """Refuse, before any work, an output path whose parent is a file, that is a folder, or
    whose folder cannot be written (ValueError naming the path)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"output {path} is a folder; name a file inside it")
    for parent in (path.parent, *path.parent.parents):
        if parent.exists():
            if not parent.is_dir():
                raise ValueError(f"cannot write {path}: {parent} is a file, not a folder")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise ValueError(f"cannot write {path}: the folder {parent} is not writable")
            break
    return path


def read_npz(path, what: str, parse):
    """Open a morphojax `.npz` and return (metadata, parse(metadata, data)).

    `data` is the open archive; a missing file, or one that is not what `parse` expects
    (it raises KeyError or ValueError), is a ValueError naming `what` ("result", "sweep").
    """
    with open_npz(path, what) as data:
        meta = read_metadata(data, path)
        return meta, parse(meta, data)
