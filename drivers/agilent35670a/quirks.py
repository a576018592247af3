"""Instrument behaviour the driver relies on but the manual leaves open, in one visible place.

Every item here is our reading, to verify on a real 35670A (``tests/test_hardware_35670a.py``
checks some of them).
"""

from __future__ import annotations

__all__ = ["Quirks"]


class Quirks:
    """Instrument behaviour that the driver relies on but the manual leaves open (inferred)."""

    #: ``FORM REAL`` blocks are big-endian (no byte-order command exists).
    REAL_BIG_ENDIAN = True
    #: ``SYST:ERR?`` answers ``+0,"No error"`` when the queue is empty (SCPI standard).
    NO_ERROR_CODE = 0
    #: Error queue depth: 5 entries (the last replaced by -350 on overflow); more reads than
    #: this means the reply is not an error queue.
    ERROR_QUEUE_READS = 8
    #: After a sweep, changing ``CALCn:FEED`` shows other data of the same measurement (the
    #: variance and linear spectra are read that way, through trace A and register D1).
    FEED_CHANGE_KEEPS_DATA = True
    #: A real-valued trace (normalized variance) may come as N values or as N (real, 0) pairs.
    REAL_TRACE_MAY_BE_PAIRED = True
    #: Writing start above the stop moves the stop (and the reverse), so the order of writing
    #: them matters to land on the band asked for.
    START_BELOW_STOP = True
    #: Time per swept-sine point beyond settle and integration (frequency change, ranging,
    #: computing): the specification's 101-point sweep at 100 ms integration takes about 60 s.
    POINT_OVERHEAD_S = 0.45
    #: Longest auto-calibration expected (s); its time does not count against a deadline.
    CALIBRATION_S = 30.0
