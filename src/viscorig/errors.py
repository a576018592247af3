"""Exceptions that the command line turns into one clear message and an exit status.

Every error caused by what a user gave (a file, a field, a command-line value) is an
:class:`InputError`; every fault of the instrument or its connection is an
:class:`InstrumentError`. Their message must name what is wrong and where, because it is all the
user sees: the command line prints it on one line, without a traceback.
"""

from __future__ import annotations


class ViscorigError(Exception):
    """Base of the errors the command line reports without a traceback."""

    exit_status = 1


class InputError(ViscorigError):
    """Bad input: a sequence, station, rig or campaign file, or a command-line value.

    Parameters
    ----------
    message
        What is wrong, naming the value.
    where
        The file and field (``"paper.toml: steps[3].level"``), prefixed to the message.
    """

    exit_status = 2

    def __init__(self, message: str, where: str | None = None) -> None:
        self.where = where
        self.detail = message
        super().__init__(f"{where}: {message}" if where else message)


class InstrumentError(ViscorigError):
    """A fault of the analyser or its connection; data measured so far is kept."""

    exit_status = 3
