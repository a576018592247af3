"""Crash-safe commits of a campaign file: change a copy in memory, write it beside the original,
rename it over the original.

Why not write in place: HDF5 updates its metadata in several places, so a writer killed in the
middle of a write (or of the flush at close) can leave a file that no longer opens. SWMR
(single-writer/multiple-reader) avoids that for appends, but it forbids creating groups and
attributes while in SWMR mode (a new run, a status change, a fit) and leaves a "file in use"
status flag in the superblock after a crash that readers must clear with ``h5clear``.

Why in memory: HDF5 handles a failed write badly. When the disk fills or ``ulimit -f`` is
reached while HDF5 writes a file, the library reports errors from object destructors and may
crash the process (SIGSEGV) when the file is closed. Here HDF5 never writes to a disk: it
changes an in-memory image of the file, and Python writes that image out, where a full disk is
an ordinary ``OSError``.

A commit (the caller holds the campaign file's writer lock, :mod:`viscorig.storage.writelock`):

1. reads the campaign file into memory and opens that image with h5py;
2. makes the change and closes the image (HDF5 flushes everything into it);
3. checks there is room for the new image (free space, ``ulimit -f``), writes it to a hidden
   staging file next to the campaign file (``.NAME.commit``) and ``fsync``\\ s it;
4. ``os.replace``\\ s the staging file over the campaign file, which is atomic on POSIX file
   systems and on NTFS, and ``fsync``\\ s the folder so the rename itself is durable.

A process killed at any instant leaves either the previous file or the new one, never a mix; a
stale staging file is harmless and is overwritten by the next commit. A write that fails
removes the staging file and leaves the campaign file as it was. Readers never take a lock:
they open whichever complete file the name points to at that moment. The cost is one read and
one write of the file per commit, a few milliseconds for a campaign (under a few megabytes);
``benchmarks/bench_storage.py`` measures it. Memory: about twice the file's size, during the
commit.
"""

from __future__ import annotations

import contextlib
import io
import os
import stat
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import h5py

from viscorig.storage import room

#: On Windows a file open by a reader cannot be replaced: retry the rename this long.
_REPLACE_RETRY_S = 5.0


def staging_path(path: Path) -> Path:
    """The hidden file a commit to ``path`` is prepared in."""
    return path.with_name(f".{path.name}.commit")


def _fsync_folder(folder: Path) -> None:
    if sys.platform == "win32":  # pragma: no cover - folders cannot be opened there
        return
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _replace(staging: Path, path: Path) -> None:
    deadline = time.monotonic() + _REPLACE_RETRY_S
    while True:
        try:
            os.replace(staging, path)
            return
        except PermissionError:
            if sys.platform != "win32" or time.monotonic() > deadline:
                raise
            time.sleep(0.05)  # pragma: no cover - a reader has it open on Windows


def write_image(image: bytes, path: Path, *, mode: int, durable: bool) -> None:
    """Write ``image`` as the new content of ``path``, atomically (steps 3 and 4 above).

    Raises
    ------
    NoRoomError
        Not enough room, or the write failed; ``path`` is unchanged, no staging file is left.
    """
    folder = path.parent if str(path.parent) else Path(".")
    staging = staging_path(path)
    room.ignore_file_size_signal()
    room.check_room(path, len(image))
    try:
        staging.unlink(missing_ok=True)
        descriptor = os.open(staging, os.O_WRONLY | os.O_CREAT | os.O_EXCL
                             | getattr(os, "O_BINARY", 0), mode)
        try:
            with open(descriptor, "wb", closefd=False) as handle:
                handle.write(image)
            if durable:
                os.fsync(descriptor)
        finally:
            os.close(descriptor)
        _replace(staging, path)
    except OSError as error:
        with contextlib.suppress(OSError):
            staging.unlink(missing_ok=True)
        raise room.write_failure(error, path) from None
    if durable:
        with contextlib.suppress(OSError):  # the new file is in place; durability is a bonus
            _fsync_folder(folder)


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
    NoRoomError
        The new file cannot be written (disk full, ``ulimit -f``, read-only, ...).
    OSError
        The campaign file cannot be read.

    Notes
    -----
    If the body raises, nothing is written. The caller must hold the file's writer lock.
    """
    path = Path(path)
    if create:
        if path.exists():
            raise FileExistsError(path)
        buffer = io.BytesIO()
        mode = 0o666  # the new file gets the user's umask
    else:
        buffer = io.BytesIO(path.read_bytes())
        mode = stat.S_IMODE(path.stat().st_mode)
    h5 = h5py.File(buffer, "w" if create else "r+")
    try:
        yield h5
    finally:
        h5.close()
    write_image(buffer.getvalue(), path, mode=mode, durable=durable)
