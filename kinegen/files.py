"""Files read within bounds and written whole or not at all.

Reading: :func:`read_bounded` takes a regular file (or ``-``, standard input, read once per
stream: its bytes are kept, as a model named ``-`` is read more than once), refuses devices and
FIFOs before it would block or read forever, and stops at a size limit while reading.
Writing: :func:`atomic_writer` / :func:`write_atomic` write through a temporary file beside the
target, named after the writing process, and ``os.replace`` it: a
reader sees the previous file or the new one; disk full keeps the previous one; a temporary file
left by a killed process is removed by the next write to the same folder. A target that exists
and is not a regular file (``/dev/stdout``, a FIFO, ``/dev/full``) is written in place, its
errors reported like any other.
"""

from __future__ import annotations

import contextlib
import os
import stat
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

#: What ``-`` names on the command line: standard input (read) or standard output (written).
STDIN = STDOUT = "-"
_stdin_read: tuple[object, bytes] | None = None  # (the stream, its bytes): a model given as `-` is read again by path


class FileTooLarge(OSError):
    """A file longer than the limit its reader sets."""


def read_bounded(path: str | Path, limit: int) -> bytes:
    """The bytes of ``path`` (``-``: standard input), at most ``limit`` of them. OSError with a
    ``strerror`` that says what is wrong: not a regular file (a directory, device or FIFO, refused
    without blocking on it), or :class:`FileTooLarge` when it holds more than ``limit`` bytes
    (checked while reading, so ``/dev/zero``-like sources end)."""
    global _stdin_read
    if str(path) == STDIN:
        if _stdin_read is None or _stdin_read[0] is not sys.stdin:  # once per stream (a test's runner swaps it)
            _stdin_read = (sys.stdin, _read_limited(sys.stdin.buffer, limit))
        return _stdin_read[1]
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = "a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "a device or socket"
            raise OSError(0, f"not a regular file ({kind}); give a model file, or - for standard input")
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as handle:
            return _read_limited(handle, limit)
    finally:
        os.close(fd)


def _read_limited(handle: BinaryIO, limit: int) -> bytes:
    data = handle.read(limit + 1)
    if data is None:
        data = b""
    if len(data) > limit:
        raise FileTooLarge(0, f"larger than {limit:,} bytes")
    return data


@contextlib.contextmanager
def atomic_path(path: Path, suffix: bool = True) -> Iterator[Path]:
    """A temporary path beside ``path`` (named after this process; ending in ``path``'s suffix
    unless ``suffix`` is false, for a writer that picks its format by it) for a writer that
    wants a file name; it becomes ``path`` when the block ends without an exception (with the mode
    a new file gets under the umask, not the temporary file's 0600), else it is removed. A target
    that exists and is not a regular file is yielded itself: written in place, never replaced."""
    path = Path(path)
    if _is_special(path):  # /dev/stdout, a FIFO, /dev/full
        yield path
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    _sweep(path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=f".tmp{path.suffix if suffix else ''}", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def atomic_writer(path: Path) -> Iterator[BinaryIO]:
    """A binary handle whose content becomes ``path`` (:func:`atomic_path`) when the block ends
    without an exception, flushed and fsynced first; on an exception (disk full, interrupted) the
    previous file is untouched and the temporary file removed. An OSError names the file (a full
    device's ENOSPC does not by itself)."""
    try:
        with atomic_path(Path(path), suffix=False) as target, open(target, "wb") as handle:
            yield handle
            handle.flush()
            if stat.S_ISREG(os.fstat(handle.fileno()).st_mode):  # (a pipe or device has nothing to sync)
                os.fsync(handle.fileno())
    except OSError as exc:
        if exc.filename is None and exc.errno is not None:
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        raise


#: the largest model file kinegen reads (bytes)
MAX_MODEL_BYTES = 5_000_000


def cache_folder() -> Path:
    """kinegen's cache (``$KINEGEN_CACHE``, default ``~/.cache/kinegen``): compiled libraries, and
    what a command computes once per model version (``kinegen info``)."""
    return Path(os.environ.get("KINEGEN_CACHE", Path.home() / ".cache" / "kinegen"))


def write_atomic(path: Path, content: str | bytes) -> None:
    """Write ``content`` (text as UTF-8, or bytes) to ``path`` all or nothing (:func:`atomic_writer`);
    an OSError names the file."""
    with atomic_writer(Path(path)) as handle:
        handle.write(content.encode("utf-8") if isinstance(content, str) else content)


def writable(path: str | Path) -> str | None:
    """Why ``path`` cannot be written, checked before any work (None: it can, as far as can be told
    without writing): a folder in its place, a file that is not writable, or -- its missing folders
    are made when it is written -- a file where a folder belongs or a folder that is not writable."""
    target = Path(path)
    if target.is_dir():
        return f"{target} is a folder, not a file"
    if target.exists():
        return None if os.access(target, os.W_OK) else f"{target} is not writable"
    folder = target.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        return f"{folder} is a file, not a folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"the folder {folder} is not writable"
    return None


def _is_special(path: Path) -> bool:
    try:
        return not stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


def _sweep(folder: Path) -> None:
    """Remove the temporary files of writers in ``folder`` that no longer run (killed mid-write)."""
    for tmp in folder.glob(".*.tmp*"):
        parts = tmp.name.rpartition(".tmp")[0].rsplit(".", 2)  # .<name>.<pid>.<random>.tmp[<suffix>]
        if len(parts) == 3 and parts[1].isdigit() and not _running(int(parts[1])):
            tmp.unlink(missing_ok=True)


def _running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process
        return True
    return True


def _umask() -> int:
    """The process's umask (read by setting it, then setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
