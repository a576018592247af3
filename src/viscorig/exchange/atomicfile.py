"""Write an output file so that a failure never leaves a partial or changed file behind.

The new content goes to a hidden file next to the target, created with mode 0666 so that the
user's umask decides its permissions (as for any file a program creates), and is then renamed
over the target.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from viscorig.errors import InputError
from viscorig.storage.room import cause


def _temporary_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.{secrets.token_hex(6)}.partial")


def _create(path: Path) -> tuple[int, Path]:
    """A new, empty hidden file next to ``path`` (mode 0666 less the umask); refused where
    ``path`` names no file, or something that is not one (the rename would replace a device
    such as ``/dev/null`` by a file)."""
    if not path.name or path.name in (".", ".."):
        raise InputError("names no file", str(path) or "''")
    try:
        # (over a folder the rename fails, and says so)
        if path.exists() and not path.is_file() and not path.is_dir():
            raise InputError("exists and is not a file: it would be replaced by one, not "
                             "written to", str(path))
    except OSError as error:
        raise InputError(cause(error, path), str(path)) from None
    temporary = _temporary_name(path)
    try:
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
        return os.open(temporary, flags, 0o666), temporary
    except OSError as error:
        raise InputError(cause(error, path), str(path)) from None


def _failed(error: OSError, path: Path) -> InputError:
    return InputError(cause(error, path), str(path))


def replace_atomically(path: Path, write: Callable[[IO[Any]], object], *, text: bool) -> None:
    """Call ``write(handle)`` on a temporary file next to ``path``, then rename it to ``path``.

    Text is written as UTF-8 with the line endings ``write`` gives (no translation).

    Raises
    ------
    InputError
        The folder is missing or not writable, or the disk is full.
    """
    descriptor, temporary = _create(path)
    try:
        options: dict[str, Any] = {"encoding": "utf-8", "newline": ""} if text else {}
        with os.fdopen(descriptor, "w" if text else "wb", **options) as stream:
            write(stream)
        os.replace(temporary, path)
    except OSError as error:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise _failed(error, path) from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise


def write_via_path(path: Path, write: Callable[[Path], None]) -> None:
    """Like :func:`replace_atomically` for libraries that want a file name, not a handle.

    The library writes into an existing empty file, which keeps the mode it was created with.
    """
    descriptor, temporary = _create(path)
    os.close(descriptor)
    try:
        write(temporary)
        os.replace(temporary, path)
    except OSError as error:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise _failed(error, path) from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
