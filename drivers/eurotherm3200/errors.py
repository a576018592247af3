"""What can go wrong talking to a temperature controller: each error's message is one line
that names the controller, the parameter and what happened."""

from __future__ import annotations

__all__ = ["BadReplyError", "ChamberError", "NoReplyError", "SensorBreakError",
           "SetPointRefusedError"]


class ChamberError(Exception):
    """A fault of the controller or its link (the base of every error here)."""


class NoReplyError(ChamberError):
    """The controller did not answer (cable, address, power, baud rate)."""


class BadReplyError(ChamberError):
    """The controller answered with something that is not a valid reply (a corrupted frame, an
    exception code)."""


class SensorBreakError(ChamberError):
    """The controller reports its thermocouple broken (StAt bit 5)."""


class SetPointRefusedError(ChamberError):
    """A set point outside the limits the driver was given, or refused by the controller."""
