"""Exceptions of the 35670A driver.

Every fault the driver reports is an :class:`InstrumentError` (or a :class:`SettingOutOfRange`
for a value refused before anything is sent). Messages name the resource and, where there is
one, the command, because they are often all the operator sees.
"""

from __future__ import annotations

#: The error queue's overflow entry (the queue holds 5; the last says errors were lost).
QUEUE_OVERFLOW = -350


class InstrumentError(Exception):
    """A fault of the analyser or of the connection to it.

    Parameters
    ----------
    message
        What went wrong.
    resource
        The VISA resource string of the analyser, prefixed to the message when given.
    """

    def __init__(self, message: str, resource: str | None = None) -> None:
        self.resource = resource
        self.detail = message
        super().__init__(f"{resource}: {message}" if resource else message)


class InstrumentTimeout(InstrumentError):  # noqa: N818 (names of the driver's API)
    """The analyser did not answer, or a measurement did not finish, within the allowed time."""


class ConnectionLost(InstrumentError):  # noqa: N818 (names of the driver's API)
    """The connection to the analyser (or its GPIB adapter) failed and could not be restored."""


class WrongInstrument(InstrumentError):  # noqa: N818 (names of the driver's API)
    """``*IDN?`` does not name a 35670A."""


class MissingOption(InstrumentError):  # noqa: N818 (names of the driver's API)
    """An option the measurement needs (1D2 swept sine, AY6 four channels) is not installed.

    Attributes
    ----------
    missing
        The option codes that are missing, e.g. ``("AY6",)``.
    """

    def __init__(self, message: str, missing: tuple[str, ...], resource: str | None = None):
        self.missing = missing
        super().__init__(message, resource)


class MalformedReply(InstrumentError):  # noqa: N818 (names of the driver's API)
    """A reply that cannot be decoded, or that does not hold what was asked for."""


class MeasurementAborted(InstrumentError):  # noqa: N818 (names of the driver's API)
    """The measurement was aborted (:meth:`Agilent35670A.abort`) before it completed."""


class SCPIError(InstrumentError):
    """The analyser's error queue held an error.

    Attributes
    ----------
    code
        SCPI error number (negative for standard errors, e.g. -222 "Data out of range").
    text
        The analyser's text for the error.
    command
        The command after which the error was found, if known.
    others
        Further ``(code, text)`` entries read from the queue in the same check.
    """

    def __init__(
        self,
        code: int,
        text: str,
        command: str | None = None,
        resource: str | None = None,
        others: tuple[tuple[int, str], ...] = (),
    ) -> None:
        self.code = code
        self.text = text
        self.command = command
        self.others = others
        message = f"SCPI error {code}, {text!r}"
        if command:
            message += f" after {command!r}"
        if others:
            message += "; also " + "; ".join(f"{c}, {t!r}" for c, t in others)
        if any(c == QUEUE_OVERFLOW for c, _ in others) or code == QUEUE_OVERFLOW:
            message += " (the error queue overflowed: later errors were lost)"
        super().__init__(message, resource)


class SettingNotApplied(InstrumentError):  # noqa: N818 (names of the driver's API)
    """The analyser accepted a setting without error but reads back something else."""


class SettingOutOfRange(ValueError):  # noqa: N818 (names of the driver's API)
    """A value outside the analyser's documented range; refused before anything is sent."""


def parse_error_entry(reply: str, resource: str) -> tuple[int, str]:
    """Parse a ``SYST:ERR?`` reply ``<code>,"<text>"`` into ``(code, text)``.

    Raises
    ------
    MalformedReply
        The code is not an integer.
    """
    code_text, _, text = reply.partition(",")
    try:
        code = int(code_text.strip())
    except ValueError:
        raise MalformedReply(f"SYST:ERR? answered {reply!r}, not <code>,\"<text>\"",
                             resource) from None
    return code, text.strip().strip('"')
