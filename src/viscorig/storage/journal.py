"""The campaign's journal: what happened at the bench, with its time (an addition to the layout).

``/journal`` holds four 1-D, resizable UTF-8 string datasets of equal length, one element per
entry, in the order written:

- ``time_utc``: ISO 8601 UTC, to the second;
- ``kind``: one of :data:`KINDS` (``note`` is the technician's text; the others are events of
  the run engine: ``pause``, ``resume``, ``hold``, ``hold_cleared``, ``abort``);
- ``run``: the run measured at the time ("" between runs);
- ``text``: the note, or the reason of the event.

A reader that ignores ``/journal`` reads the file as before (format_version stays 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py

from viscorig.errors import InputError
from viscorig.storage.text import printable

JOURNAL_GROUP = "journal"
COLUMNS = ("time_utc", "kind", "run", "text")
KINDS = ("note", "pause", "resume", "hold", "hold_cleared", "abort")
#: Entries one file may hold, and characters one entry's text may hold.
MAX_ENTRIES = 10_000
MAX_TEXT = 2_000

_TEXT = h5py.string_dtype("utf-8")


@dataclass(frozen=True)
class JournalEntry:
    """One line of the journal."""

    time_utc: str
    kind: str
    run: str
    text: str


def check_entry(kind: str, text: str, where: str) -> str:
    """The entry's text, checked: a known kind, one to :data:`MAX_TEXT` characters.

    Raises
    ------
    InputError
        An unknown kind, an empty text or one too long.
    """
    if kind not in KINDS:
        raise InputError(f"journal kind {kind!r} is not one of {', '.join(KINDS)}", where)
    text = str(text).strip()
    if not text:
        raise InputError("empty text", where)
    if len(text) > MAX_TEXT:
        raise InputError(f"{len(text)} characters; at most {MAX_TEXT}", where)
    return text


def append(h5: h5py.File, entry: JournalEntry, path: Path) -> int:
    """Append one entry inside a commit; return the number of entries after it.

    Raises
    ------
    InputError
        The journal is not as :func:`read` describes it, or its columns cannot grow (named).
    """
    existing = h5.get(JOURNAL_GROUP)
    if existing is not None and not (isinstance(existing, h5py.Group) and len(existing) == 0):
        read(h5, path)
        for name in COLUMNS:
            if h5[JOURNAL_GROUP][name].maxshape[0] is not None:
                raise InputError("a column of fixed length: no entry can be added",
                                 f"{path}: /{JOURNAL_GROUP}/{name}")
    group = h5.require_group(JOURNAL_GROUP)
    for name in COLUMNS:
        if name not in group:
            group.create_dataset(name, shape=(0,), maxshape=(None,), dtype=_TEXT, chunks=(64,))
    count = int(group["time_utc"].shape[0])
    if count >= MAX_ENTRIES:
        raise InputError(f"the journal holds {MAX_ENTRIES} entries, the most it may",
                         f"{path}: /{JOURNAL_GROUP}")
    for name in COLUMNS:
        column = group[name]
        column.resize((count + 1,))
        column[count] = getattr(entry, name)
    return count + 1


def read(h5: h5py.File, path: Path) -> list[JournalEntry]:
    """Every entry (none when the file has no journal), its texts without control characters
    (a note keeps its line breaks).

    Raises
    ------
    InputError
        The journal is not as described here (named).
    """
    group = h5.get(JOURNAL_GROUP, getlink=True)
    if group is None:
        return []
    if not isinstance(group, h5py.HardLink) or not isinstance(h5[JOURNAL_GROUP], h5py.Group):
        raise InputError("not a group", f"{path}: /{JOURNAL_GROUP}")
    group = h5[JOURNAL_GROUP]
    columns = []
    for name in COLUMNS:
        item = group.get(name)
        if not (isinstance(item, h5py.Dataset) and item.ndim == 1
                and h5py.check_string_dtype(item.dtype) is not None):
            raise InputError("missing or not a 1-D string dataset",
                             f"{path}: /{JOURNAL_GROUP}/{name}")
        if item.shape[0] > MAX_ENTRIES:
            raise InputError(f"more than {MAX_ENTRIES} entries", f"{path}: {item.name}")
        columns.append([value.decode("utf-8", "replace") if isinstance(value, bytes)
                        else str(value) for value in item[()]])
    if len({len(column) for column in columns}) > 1:
        raise InputError("columns of different lengths", f"{path}: /{JOURNAL_GROUP}")
    return [JournalEntry(*(printable(column[i][:MAX_TEXT], keep="\n" if name == "text" else "")
                           for name, column in zip(COLUMNS, columns, strict=True)))
            for i in range(len(columns[0]))]
