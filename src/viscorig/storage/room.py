"""Room to write: free space and the file-size limit checked before a commit, and every write
failure told as one cause a technician can act on ("disk full: 0 bytes free on /data").

A commit needs room for a whole new copy of the campaign file beside the old one (see
:mod:`viscorig.storage.atomic`), so the room is checked against the size of the copy before the
first byte is written; a failure that still happens (space taken meanwhile, a quota) is turned
into the same kind of line by :func:`write_failure`.
"""

from __future__ import annotations

import errno
import math
import os
import shutil
import signal
import threading
from pathlib import Path

from viscorig.errors import InputError

try:
    import resource
except ImportError:  # pragma: no cover - Windows
    resource = None  # type: ignore[assignment]

#: Room asked beyond the file's size when a writer opens a campaign: a segment of a few
#: hundred points and its chunk allocation, with margin.
HEADROOM_BYTES = 64 * 1024


class NoRoomError(InputError):
    """A campaign file cannot be written: the disk is full, a limit is reached, or the folder
    is read-only. Every segment committed before is kept."""


def human(size: float) -> str:
    """``0 bytes``, ``512 bytes``, ``37 KiB``, ``1.2 MiB``."""
    if size < 1024:
        return f"{int(size)} bytes"
    for unit in ("KiB", "MiB", "GiB", "TiB"):
        size /= 1024
        if size < 1024 or unit == "TiB":
            return f"{size:.3g} {unit}"
    raise AssertionError  # pragma: no cover


def mount_point(path: Path) -> Path:
    """The mount point of the file system that holds ``path`` (a folder or a file)."""
    current = Path(os.path.abspath(path))
    while not current.exists() and current != current.parent:
        current = current.parent
    while not os.path.ismount(current) and current != current.parent:
        current = current.parent
    return current


def free_bytes(folder: Path) -> int:
    """Bytes an unprivileged writer may still use in ``folder``'s file system."""
    return shutil.disk_usage(folder).free


def file_size_limit() -> float:
    """The process's file-size limit in bytes (``ulimit -f``); infinity when none."""
    if resource is None:  # pragma: no cover - Windows
        return math.inf
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    return math.inf if soft == resource.RLIM_INFINITY else float(soft)


def ignore_file_size_signal() -> None:
    """Make a write past ``ulimit -f`` fail with EFBIG instead of killing the process.

    The Python interpreter ignores SIGXFSZ at start-up; an embedding program may not have.
    """
    sigxfsz = getattr(signal, "SIGXFSZ", None)
    if sigxfsz is None or threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(sigxfsz) == signal.SIG_DFL:
        signal.signal(sigxfsz, signal.SIG_IGN)


def _kept(path: Path) -> str:
    return "; the file keeps every committed segment" if path.exists() else ""


def check_room(path: Path, needed: int) -> None:
    """Raise :class:`NoRoomError` unless ``needed`` bytes can be written next to ``path``.

    Raises
    ------
    NoRoomError
        Too little free space, or a file-size limit below ``needed``.
    """
    folder = path.parent if str(path.parent) else Path(".")
    limit = file_size_limit()
    if needed > limit:
        raise NoRoomError(f"file size limit reached: {human(limit)} (ulimit -f), writing "
                          f"needs {human(needed)}{_kept(path)}", str(path))
    try:
        free = free_bytes(folder)
    except OSError:
        return  # cannot tell; the write itself will say
    if free < needed:
        raise NoRoomError(f"disk full: {human(free)} free on {mount_point(folder)}, writing "
                          f"needs {human(needed)}{_kept(path)}", str(path))


def cause(error: OSError, path: Path) -> str:
    """What a technician should know about a failed write, in a few words."""
    folder = path.parent if str(path.parent) else Path(".")
    number = error.errno
    if number == errno.ENOSPC:
        try:
            free = human(free_bytes(folder))
        except OSError:
            free = "no space"
        return f"disk full: {free} free on {mount_point(folder)}"
    if number == getattr(errno, "EDQUOT", -1):
        return f"disk quota exceeded on {mount_point(folder)}"
    if number == errno.EFBIG:
        limit = file_size_limit()
        if math.isfinite(limit):
            return f"file size limit reached: {human(limit)} (ulimit -f)"
        return f"file too large for the file system on {mount_point(folder)}"
    if number == errno.EROFS:
        return f"read-only file system: {mount_point(folder)}"
    if number in (errno.EACCES, errno.EPERM):
        return f"permission denied: cannot write in {folder}"
    if number == errno.ENOENT:
        return f"folder does not exist: {folder}"
    if number == errno.EISDIR:
        return f"a folder has this name: {path}"
    return f"cannot write ({error.strerror or type(error).__name__})"


def write_failure(error: OSError, path: Path, *, before_writing: bool = False) -> NoRoomError:
    """The one-line error for a write to campaign file ``path`` that failed (or, with
    ``before_writing``, for a writer refused before its first write)."""
    outcome = "; nothing was written" if before_writing else _kept(path)
    return NoRoomError(f"{cause(error, path)}{outcome}", str(path))
