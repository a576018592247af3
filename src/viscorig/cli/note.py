"""``viscorig note FILE.h5 TEXT``: a note with its time in the campaign's journal.

Works on a file nobody writes (the note is stored at once) and on a file ``viscorig run``,
``resume`` or the bench page is measuring into (the running process stores it, with the run
being measured, within a second: :mod:`viscorig.acquisition.notebox`). Exit status 0 stored; 2
bad input, or the file is held by a writer that does not take notes (nothing stored).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from viscorig.acquisition import notebox
from viscorig.cli import summary_of
from viscorig.errors import InputError
from viscorig.storage import CampaignFile
from viscorig.storage.writelock import CampaignInUseError

#: How long a posted note may wait for the running process to store it (s).
WAIT_S = 10.0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``note`` command."""
    note = subparsers.add_parser(
        "note", help=summary_of("note"),
        description="Store a note with its time (UTC) in the journal of a campaign file, also "
        "while 'viscorig run' measures into it (the note then names the run being measured).")
    note.add_argument("file", metavar="FILE.h5", help="campaign file")
    note.add_argument("text", nargs="+", metavar="TEXT", help="the note (words are joined)")
    note.set_defaults(handler=note_command)


def note_command(args: argparse.Namespace) -> int:
    """Store the note, or hand it to the process writing the file."""
    path = Path(args.file)
    text = " ".join(args.text)
    try:
        with CampaignFile.open(path, "a") as campaign:
            entry = campaign.add_journal_entry("note", text)
    except CampaignInUseError as busy:
        CampaignFile.open(path)  # a campaign file at all? (its own error otherwise)
        try:
            posted = notebox.post(path, text)
        except OSError as error:
            raise InputError(f"cannot post the note beside it ({error})", str(path)) from None
        deadline = time.monotonic() + WAIT_S
        taken = posted.with_suffix(".taken")  # claimed: being stored
        while (posted.exists() or taken.exists()) and time.monotonic() < deadline:
            time.sleep(0.05)
        if notebox.withdraw(posted):
            raise InputError(f"{busy.detail}; it did not take the note within {WAIT_S:g} s "
                             "(only 'viscorig run', 'resume' and 'bench serve' take notes): "
                             "nothing stored", str(path)) from None
        print(f"{path}: note handed to the run in progress")
        return 0
    print(f"{path}: note stored {entry.time_utc}" + (f" (run {entry.run})" if entry.run else ""))
    return 0
