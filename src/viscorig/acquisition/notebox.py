"""Notes for a campaign file that another process is writing: a mailbox beside the file.

A campaign file has one writer at a time (:mod:`viscorig.storage.writelock`). ``viscorig note
FILE.h5 TEXT`` writes the note itself when nobody writes the file; while ``viscorig run``
measures into it, the note is posted to the file's mailbox, the folder ``.NAME.notes`` beside
it, as one small JSON file (written whole, then renamed into place), and the running process
(:class:`NoteCarrier`) stores it in the campaign's journal within :data:`CARRY_EVERY_S`, with
the run being measured. The carrier claims a note by renaming it before it reads it, so a note is
stored once, or, if nobody claims it in time, taken back by its poster.
"""

from __future__ import annotations

import contextlib
import json
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

from viscorig import jsontext
from viscorig.storage.journal import JOURNAL_GROUP, check_entry

__all__ = ["CARRY_EVERY_S", "NoteCarrier", "inbox", "post", "take", "withdraw"]

#: How often a running process looks for notes (s).
CARRY_EVERY_S = 0.5
#: Notes one mailbox may hold before a poster is refused.
MAX_WAITING = 100


def inbox(path: Path) -> Path:
    """The mailbox folder of a campaign file."""
    return path.parent / f".{path.name}.notes"


def post(path: Path, text: str) -> Path:
    """Post a note for the process writing ``path``; return the note's file.

    Raises
    ------
    InputError
        The text is empty or too long (as for any journal entry).
    OSError
        The mailbox cannot be written.
    """
    text = check_entry("note", text, f"{path}: /{JOURNAL_GROUP}")
    folder = inbox(path)
    folder.mkdir(exist_ok=True)
    if sum(1 for _ in folder.glob("*.note")) >= MAX_WAITING:
        raise OSError(f"{folder}: {MAX_WAITING} notes are waiting already")
    name = f"{time.time_ns():020d}-{os.getpid()}"
    temporary = folder / f"{name}.tmp"
    temporary.write_text(jsontext.dumps({"text": text}), encoding="utf-8")
    final = folder / f"{name}.note"
    os.replace(temporary, final)
    return final


def withdraw(note: Path) -> bool:
    """Take a posted note back; false when the writer has claimed it already."""
    try:
        note.unlink()
    except FileNotFoundError:
        return False
    return True


def take(path: Path) -> list[str]:
    """Claim and return every note waiting for ``path``, oldest first (unreadable ones are
    dropped)."""
    folder = inbox(path)
    if not folder.is_dir():
        return []
    texts = []
    for note in sorted(folder.glob("*.note")):
        claimed = note.with_suffix(".taken")
        try:
            os.replace(note, claimed)
        except FileNotFoundError:  # taken back by its poster
            continue
        try:
            text = json.loads(claimed.read_text(encoding="utf-8"))["text"]
            if isinstance(text, str):
                texts.append(text)
        except (OSError, ValueError, KeyError, TypeError):
            pass
        finally:
            with contextlib.suppress(OSError):
                claimed.unlink()
    return texts


class NoteCarrier:
    """A thread that stores the notes posted for a campaign file while a run writes it.

    Parameters
    ----------
    path
        The campaign file.
    store
        ``store(text)`` writes one note into the journal (under the writer's file lock).
    warn
        Says a note that could not be stored.
    """

    def __init__(self, path: Path, store: Callable[[str], object],
                 warn: Callable[[str], None]) -> None:
        self.path = path
        self.store = store
        self.warn = warn
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="viscorig-notes", daemon=True)

    def __enter__(self) -> NoteCarrier:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(10.0)
        self.carry()  # the last ones

    def carry(self) -> int:
        """Store the notes waiting now; return how many were stored."""
        stored = 0
        for text in take(self.path):
            try:
                self.store(text)
                stored += 1
            except Exception as error:  # a full journal, a full disk: said, never fatal
                self.warn(f"note not stored ({error}): {text[:80]}")
        return stored

    def _loop(self) -> None:
        while not self._stop.wait(CARRY_EVERY_S):
            self.carry()
