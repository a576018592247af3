"""What can go wrong talking to a temperature controller: each error's message is one line
that names the controller, the parameter and what happened."""

from __future__ import annotations

__all__ = ["BadReply", "ChamberError", "NoReply", "SensorBreak", "SetPointRefused"]


class ChamberError(Exception):
    """A fault of the controller or its link (the base of every error here)."""


class NoReply(ChamberError):
    """The controller did not answer (cable, address, power, baud rate)."""


class BadReply(ChamberError):
    """The controller answered with something that is not a valid reply (a corrupted frame, an
    exception code)."""


class SensorBreak(ChamberError):
    """The controller reports its thermocouple broken (StAt bit 5)."""


class SetPointRefused(ChamberError):
    """A set point outside the limits the driver was given, or refused by the controller."""
