"""Crash-safe commits of a campaign file: copy, change the copy, rename it over the original.

Why not write in place: HDF5 updates its metadata in several places, so a writer killed in the
middle of a write (or of the flush at close) can leave a file that no longer opens. SWMR
(single-writer/multiple-reader) avoids that for appends, but it forbids creating groups and
attributes while in SWMR mode (a new run, a status change, a fit) and leaves a "file in use"
status flag in the superblock after a crash that readers must clear with ``h5clear``.

The scheme here keeps the campaign file closed between commits. A commit:

1. takes an exclusive lock on the folder (cooperating writers never interleave their commits);
2. copies the campaign file to a hidden staging file next to it (``.NAME.commit``);
3. opens the staging file with h5py, makes the change, closes it (HDF5 flushes everything);
4. ``fsync``\\ s the staging file, then ``os.replace``\\ s it over the campaign file, which is
   atomic on POSIX file systems, and ``fsync``\\ s the folder so the rename itself is durable.

A process killed at any instant leaves either the previous file or the new one, never a mix; a
stale staging file is harmless and is overwritten by the next commit. Readers never take the
lock: they open whichever complete file the name points to at that moment. The cost is one copy
of the file per commit, which for a campaign (a few thousand points, under a megabyte) is a few
milliseconds; ``benchmarks/bench_storage.py`` measures it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import h5py

try:  # POSIX; on other systems commits are still atomic but not serialised between writers.
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]


def staging_path(path: Path) -> Path:
    """The hidden file a commit to ``path`` is prepared in."""
    return path.with_name(f".{path.name}.commit")


@contextlib.contextmanager
def folder_lock(folder: Path) -> Iterator[None]:
    """Hold an exclusive advisory lock on ``folder`` (a no-op where ``fcntl`` is missing)."""
    if fcntl is None:  # pragma: no cover - Windows
        yield
        return
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        yield
    finally:
        os.close(descriptor)  # closing releases the lock


def _fsync_path(path: Path, flags: int = os.O_RDONLY) -> None:
    descriptor = os.open(path, flags)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


@contextlib.contextmanager
def atomic_commit(path: Path, *, create: bool = False, durable: bool = True) -> Iterator[h5py.File]:
    """Yield a writable h5py file whose changes replace ``path`` atomically on success.

    Parameters
    ----------
    path
        The campaign file.
    create
        Start from an empty file; raise :class:`FileExistsError` if ``path`` exists.
    durable
        ``fsync`` the new file and its folder, so a commit also survives a power cut, not only
        a killed process. Costs a few milliseconds per commit on a local disk.

    Raises
    ------
    FileExistsError
        ``create`` was asked and the file exists.
    OSError
        The folder is not writable, the disk is full, or the file cannot be copied.

    Notes
    -----
    If the body raises, nothing is committed and the staging file is removed.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    staging = staging_path(path)
    with folder_lock(folder):
        if create:
            if path.exists():
                raise FileExistsError(path)
            staging.unlink(missing_ok=True)
            h5 = h5py.File(staging, "w")
        else:
            shutil.copyfile(path, staging)
            shutil.copymode(path, staging)
            h5 = h5py.File(staging, "r+")
        try:
            yield h5
            h5.close()
        except BaseException:
            h5.close()
            staging.unlink(missing_ok=True)
            raise
        if durable:
            _fsync_path(staging)
        os.replace(staging, path)
        if durable and fcntl is not None:
            _fsync_path(folder)
