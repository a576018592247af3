"""Instrument behaviour the driver relies on but the manual leaves open, in one visible place.

Facts marked *inferred* in ``shared/docs/35670a.md`` are gathered here so they can be checked on
hardware and changed in one place.
"""

from __future__ import annotations

__all__ = ["Quirks"]


class Quirks:
    """Instrument behaviour that the driver relies on but the manual leaves open (inferred).

    Every item here is our reading, to verify on a real 35670A (``tests/test_hardware_35670a.py``
    checks the first two).
    """

    #: ``FORM REAL`` blocks are big-endian (no byte-order command exists).
    REAL_BIG_ENDIAN = True
    #: ``SYST:ERR?`` answers ``+0,"No error"`` when the queue is empty (SCPI standard).
    NO_ERROR_CODE = 0
    #: Error queue depth: 5 entries plus the overflow entry; more reads than this means a fault.
    ERROR_QUEUE_READS = 8
    #: After a sweep, changing ``CALCn:FEED`` shows other data of the same measurement (the
    #: variance and linear spectra are read that way, through trace A and register D1).
    FEED_CHANGE_KEEPS_DATA = True
    #: A real-valued trace (normalized variance) may come as N values or as N (real, 0) pairs.
    REAL_TRACE_MAY_BE_PAIRED = True
    #: The analyser rejects a start above the stop frequency, so the order of writing them matters.
    START_BELOW_STOP = True
