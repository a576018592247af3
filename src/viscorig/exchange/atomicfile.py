"""Write an output file so that a failure never leaves a partial or changed file behind."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from viscorig.errors import InputError


def replace_atomically(path: Path, write: Callable[[IO[Any]], None], *, text: bool) -> None:
    """Call ``write(handle)`` on a temporary file next to ``path``, then rename it to ``path``.

    Raises
    ------
    InputError
        The folder is missing or not writable.
    """
    folder = path.parent if str(path.parent) else Path(".")
    try:
        handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=folder)
    except OSError as error:
        raise InputError(f"cannot write here ({error.strerror})", str(path)) from None
    try:
        with os.fdopen(handle, "w" if text else "wb", **({"encoding": "utf-8"} if text else {})) \
                as stream:
            write(stream)
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise


def write_via_path(path: Path, write: Callable[[Path], None]) -> None:
    """Like :func:`replace_atomically` for libraries that want a file name, not a handle."""
    folder = path.parent if str(path.parent) else Path(".")
    try:
        handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=folder)
    except OSError as error:
        raise InputError(f"cannot write here ({error.strerror})", str(path)) from None
    os.close(handle)
    os.unlink(temporary)  # the library creates the file itself
    try:
        write(Path(temporary))
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
