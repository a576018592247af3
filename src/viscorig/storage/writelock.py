"""One writer per campaign file: an exclusive lock from before the first write to the end.

Every writer (``run``, ``resume``, ``import``, ``identify`` storing a fit, any program opening a
:class:`~viscorig.storage.CampaignFile` with ``mode="a"``) takes the lock of the campaign file when
it opens it and holds it until it closes it or exits. A second writer is refused at once with
an error naming the holder (command, process id, host, since when); readers never take it and
keep working, because a commit replaces the file atomically (:mod:`viscorig.storage.atomic`).

Why a lock file of our own, and not HDF5's: HDF5 (1.10 and later) locks a file only while it is
open, and a campaign file is closed between commits and replaced by a new file at each commit,
so HDF5's lock never spans a whole run; on file systems without ``flock`` HDF5 refuses to open
files unless ``HDF5_USE_FILE_LOCKING=FALSE`` turns it off. The lock is therefore kept on a
stable file next to the campaign file, ``.NAME.lock``, which also holds who has it (JSON).

The lock itself is the operating system's, so it dies with its process, whatever killed it:

- POSIX: ``flock`` on the lock file. Linux carries ``flock`` over NFS as a byte-range lock
  (NFSv4, or NFSv3 with lockd), and over SMB/CIFS as an SMB lock; local on macOS.
- Windows: ``msvcrt.locking`` on one byte of the lock file (released when the handle closes).
- A file system that refuses locks altogether (``ENOLCK``, ``EOPNOTSUPP``: NFS mounted
  ``nolock`` on some systems, some cluster file systems): the lock file is created with
  ``O_EXCL`` instead, and the holder's record decides. A record left by a process of this host
  that no longer runs is stale and taken over (pid, and on Linux its start time against pid
  reuse); a record from another host cannot be checked, so the writer is refused and told which
  file to delete once that process is known to be gone.

Where it does not hold: a lock that the file system accepts but does not share between hosts
(Linux NFS mounted with ``nolock`` or ``local_lock=all``) keeps writers of one host apart but
not writers of two hosts; and a writer that ignores the lock (plain h5py) is not stopped.

A stale record (its process was killed) is simply overwritten: the operating system released
the lock when the process died, so the next writer gets it at once.

Within one process the lock is counted, not exclusive: several :class:`CampaignFile` objects of the
same file in one program are one writer.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import socket
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

from viscorig import jsontext
from viscorig.errors import InputError
from viscorig.storage.text import printable

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]
try:
    import msvcrt
except ImportError:
    msvcrt = None  # type: ignore[assignment]

#: Errors that say "someone else holds the lock".
_BUSY = frozenset({errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK, getattr(errno, "EDEADLOCK", -1)})
#: Errors that say "this file system does not lock".
_NO_LOCKS = frozenset({errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL,
                       getattr(errno, "ENOTSUP", errno.EOPNOTSUPP)})
#: Windows locks one byte far past the record, so the record stays readable by others.
_WINDOWS_LOCK_OFFSET = 1 << 20
#: At most this much of a lock file is read (a record is a few hundred bytes).
_RECORD_BYTES = 4096
#: A record-less lock file older than this (fallback mode) is from a writer killed between
#: creating it and writing its record.
_EMPTY_STALE_S = 30.0
_FLAGS = os.O_RDWR | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOINHERIT", 0) \
    | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_BINARY", 0)


class CampaignInUseError(InputError):
    """Another process is writing the campaign file; nothing was written."""


@dataclass(frozen=True)
class Holder:
    """Who holds (or held) a campaign file's writer lock."""

    command: str
    pid: int
    host: str
    since: str
    """ISO 8601 UTC."""
    start_ticks: int | None = None
    """The process's start time in clock ticks since boot (Linux), to tell a reused pid."""

    def describe(self) -> str:
        """``viscorig run paper.toml (pid 4242 on lab-pc, since 2024-05-01T12:00:00Z)``."""
        return f"{self.command} (pid {self.pid} on {self.host}, since {self.since})"


def lock_path(path: Path) -> Path:
    """The lock file of campaign file ``path``."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


def _process_start_ticks(pid: int) -> int | None:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat.rsplit(")", 1)[-1].split()
    try:
        return int(fields[19])  # field 22 of proc(5); fields[0] is field 3
    except (IndexError, ValueError):
        return None


def _command_line() -> str:
    program = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python"
    if program in ("__main__.py", "-m"):
        program = Path(sys.argv[0]).parent.name or "python"
    elif program == "-c":
        program = "python -c"
    words = [program, *sys.argv[1:]] if program != "python -c" else [program]
    return printable(" ".join(words))[:200]


def this_process() -> Holder:
    """The record this process writes when it takes a lock."""
    since = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    return Holder(_command_line(), os.getpid(), socket.gethostname(), since,
                  _process_start_ticks(os.getpid()))


def _parse_record(raw: bytes) -> Holder | None:
    try:
        data = json.loads(raw.decode("utf-8"))
        ticks = data.get("start_ticks")
        return Holder(
            command=printable(str(data["command"]))[:200], pid=int(data["pid"]),
            host=printable(str(data["host"]))[:100], since=printable(str(data["since"]))[:40],
            start_ticks=int(ticks) if isinstance(ticks, int) else None,
        )
    except (ValueError, KeyError, TypeError, AttributeError, UnicodeDecodeError):
        return None


def _read_record(descriptor: int) -> Holder | None:
    try:
        return _parse_record(os.pread(descriptor, _RECORD_BYTES, 0) if hasattr(os, "pread")
                             else _read_from_start(descriptor))
    except OSError:
        return None


def _read_from_start(descriptor: int) -> bytes:  # pragma: no cover - Windows
    os.lseek(descriptor, 0, os.SEEK_SET)
    return os.read(descriptor, _RECORD_BYTES)


def _write_record(descriptor: int, holder: Holder) -> None:
    data = jsontext.dumps(asdict(holder)).encode("utf-8")
    os.ftruncate(descriptor, 0)
    os.lseek(descriptor, 0, os.SEEK_SET)
    os.write(descriptor, data)


def read_holder(path: Path) -> Holder | None:
    """The record in campaign file ``path``'s lock file (``None`` when there is none).

    Only tells who took the lock last: a record stays after its writer was killed.
    """
    try:
        descriptor = os.open(lock_path(path), os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return None
    try:
        return _read_record(descriptor)
    finally:
        os.close(descriptor)


def writer_may_hold(path: Path) -> bool:
    """Whether a writer may be writing campaign file ``path`` now, as its lock file's record
    tells: a process of this host that still runs, or one of another host (which cannot be
    checked). Reads the record only; the lock is never tried, so no writer is ever refused for
    it."""
    lock = lock_path(path)
    return lock.exists() and not _stale(lock, read_holder(path))


def _alive(holder: Holder) -> bool:
    """Whether the process of a record from this host still runs (True when unsure)."""
    if sys.platform == "win32":  # os.kill would terminate it; never guess there
        return True
    try:
        os.kill(holder.pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    ticks = _process_start_ticks(holder.pid)
    return holder.start_ticks is None or ticks is None or ticks == holder.start_ticks


def _refusal(path: Path, holder: Holder | None, advice: str = "") -> CampaignInUseError:
    who = holder.describe() if holder is not None else "a process that has not said who yet"
    return CampaignInUseError(
        f"in use by another writer: {who}; commands that only read (show, summary, report, "
        f"export) work meanwhile{advice}", str(path))


@dataclass
class _Held:
    descriptor: int | None
    """The open lock file (None when held through an ``O_EXCL`` record)."""
    count: int


_held: dict[str, _Held] = {}
_registry = threading.RLock()


def _key(path: Path) -> str:
    path = Path(path)
    folder = os.path.realpath(path.parent if str(path.parent) else ".")
    return os.path.join(folder, lock_path(path).name)


def holds(path: Path) -> bool:
    """Whether this process holds campaign file ``path``'s writer lock."""
    with _registry:
        return _key(path) in _held


def acquire(path: Path) -> None:
    """Take campaign file ``path``'s writer lock for this process (counted; see :func:`release`).

    Raises
    ------
    CampaignInUseError
        Another process holds it.
    OSError
        The lock file cannot be created (read-only folder, disk full...).
    """
    key = _key(path)
    with _registry:
        held = _held.get(key)
        if held is not None:
            held.count += 1
            return
        descriptor = _lock(Path(key), Path(path))
        _held[key] = _Held(descriptor, 1)


def release(path: Path) -> None:
    """Give back one count of the lock; the last one removes the lock file and unlocks."""
    key = _key(path)
    with _registry:
        held = _held.get(key)
        if held is None:
            return
        held.count -= 1
        if held.count > 0:
            return
        del _held[key]
        _unlock(Path(key), held.descriptor)


def _lock(lock: Path, path: Path) -> int | None:
    """Lock ``lock`` with the operating system's lock; return its descriptor."""
    for _ in range(20):
        descriptor = os.open(lock, _FLAGS | os.O_CREAT, 0o666)
        try:
            _os_lock(descriptor)
        except OSError as error:
            holder = _current_holder(descriptor) if error.errno in _BUSY else None
            os.close(descriptor)
            if error.errno in _BUSY:
                raise _refusal(path, holder) from None
            if error.errno in _NO_LOCKS:
                _lock_by_record(lock, path)
                return None
            raise
        if not _same_file(descriptor, lock):  # removed by its last holder meanwhile: again
            os.close(descriptor)
            continue
        try:
            _write_record(descriptor, this_process())
        except OSError:
            _unlock(lock, descriptor)
            raise
        return descriptor
    raise _refusal(path, None)  # pragma: no cover - twenty holders in a row


def _current_holder(descriptor: int, wait_s: float = 1.0) -> Holder | None:
    """The record of the process that holds the lock on ``descriptor``'s file.

    A new holder writes its record just after taking the lock, so for a moment the file still
    holds the record of a killed writer (or none): wait briefly for a living one to appear.
    """
    deadline = time.monotonic() + wait_s
    while True:
        holder = _read_record(descriptor)
        if holder is not None and (holder.host != socket.gethostname() or _alive(holder)):
            return holder
        if time.monotonic() >= deadline:
            return holder
        time.sleep(0.02)


def _os_lock(descriptor: int) -> None:
    if fcntl is not None:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    elif msvcrt is not None:  # pragma: no cover - Windows
        os.lseek(descriptor, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
        msvcrt.locking(descriptor, msvcrt.LK_NBLCK, 1)
    else:  # pragma: no cover
        raise OSError(errno.ENOLCK, "no file locks on this system")


def _same_file(descriptor: int, lock: Path) -> bool:
    try:
        now = os.stat(lock, follow_symlinks=False)
    except OSError:
        return False
    mine = os.fstat(descriptor)
    return (now.st_dev, now.st_ino) == (mine.st_dev, mine.st_ino)


def _unlock(lock: Path, descriptor: int | None) -> None:
    if descriptor is None:
        _remove_own_record(lock)
        return
    try:
        if msvcrt is not None and fcntl is None:  # pragma: no cover - Windows
            os.ftruncate(descriptor, 0)  # the file stays: it cannot be removed while open
            os.lseek(descriptor, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
            msvcrt.locking(descriptor, msvcrt.LK_UNLCK, 1)
        elif _same_file(descriptor, lock):
            os.unlink(lock)  # while still locked, so no one locks a file about to vanish
    except OSError:
        pass
    finally:
        os.close(descriptor)


# -- file systems without locks: an O_EXCL record decides ------------------------------------


@contextlib.contextmanager
def _host_guard(lock: Path):
    """Serialise the takeover of a stale record among the processes of this host (a lock in
    the local temporary folder, which does lock)."""
    digest = hashlib.sha256(str(lock).encode()).hexdigest()[:24]
    guard = Path(tempfile.gettempdir()) / f"viscorig-{digest}.lock"
    descriptor = os.open(guard, _FLAGS | os.O_CREAT, 0o666)
    try:
        if fcntl is not None:
            fcntl.flock(descriptor, fcntl.LOCK_EX)
        yield
    finally:
        os.close(descriptor)


def _lock_by_record(lock: Path, path: Path) -> None:
    with _host_guard(lock):
        for _ in range(2):
            try:
                descriptor = os.open(lock, _FLAGS | os.O_CREAT | os.O_EXCL, 0o666)
            except FileExistsError:
                holder = read_holder(path)
                if not _stale(lock, holder):
                    here = holder is None or holder.host == socket.gethostname()
                    advice = "" if here else (
                        f". viscorig cannot check a process on another host (this file system "
                        f"has no locks): if it no longer runs, delete {lock}")
                    raise _refusal(path, holder, advice) from None
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(lock)
                continue
            try:
                _write_record(descriptor, this_process())
            except OSError:
                os.close(descriptor)
                os.unlink(lock)
                raise
            os.close(descriptor)
            return None
    raise _refusal(path, read_holder(path))  # pragma: no cover


def _stale(lock: Path, holder: Holder | None) -> bool:
    if holder is None:
        try:
            return time.time() - os.stat(lock).st_mtime > _EMPTY_STALE_S
        except OSError:
            return True
    return holder.host == socket.gethostname() and not _alive(holder)


def _remove_own_record(lock: Path) -> None:
    descriptor = None
    with contextlib.suppress(OSError):
        descriptor = os.open(lock, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        holder = _read_record(descriptor)
        if holder is not None and holder.pid == os.getpid() \
                and holder.host == socket.gethostname():
            os.unlink(lock)
    if descriptor is not None:
        os.close(descriptor)


def _forget_after_fork() -> None:
    """A forked child is another process: it does not hold its parent's locks."""
    for held in _held.values():
        if held.descriptor is not None:
            with contextlib.suppress(OSError):
                os.close(held.descriptor)
    _held.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)
