"""Decoding of the analyser's data replies, validated.

``FORM REAL,64`` (or ``REAL,32``) makes data queries answer an IEEE 488.2 definite-length block,
``#<n><length><bytes>`` followed by a line feed; ``FORM ASC`` answers comma-separated numbers.
Every decoder here checks what it is given and raises :class:`MalformedReply` with a message that
says what was expected and what came, so a damaged reply can never become silently wrong data.
"""

from __future__ import annotations

import numpy as np

from .errors import MalformedReply

#: SCPI's "not a number" (9.91E+37); any magnitude at or above this is not a measured value.
SCPI_NOT_A_NUMBER = 9.91e37
#: What the 35670A puts in a trace where a point holds no data (not measured, beyond the sweep's
#: points, the dB value of zero): the most negative 32-bit float. Programs that read real 35670A
#: data treat anything below -1e37 as this marker.
NO_DATA = -3.40282346639e38
NO_DATA_BELOW = -1e37


def split_definite_block(message: bytes) -> bytes:
    """Return the payload of a definite-length block, checking its header and length.

    Parameters
    ----------
    message
        The whole reply: ``#``, one digit ``n`` (1..9), ``n`` digits of length, the payload, and
        an optional line feed (or carriage return and line feed).

    Raises
    ------
    MalformedReply
        No ``#``, an indefinite (``#0``) or non-numeric header, a payload shorter or longer than
        the header declares, or anything but a line feed after it.
    """
    if not message.startswith(b"#"):
        raise MalformedReply(
            f"expected a definite-length block starting with '#', got {message[:16]!r}"
        )
    if len(message) < 2 or not message[1:2].isdigit() or message[1:2] == b"0":
        raise MalformedReply(f"block header {message[:12]!r} is not '#<1-9><length>'")
    digits = int(message[1:2])
    length_field = message[2 : 2 + digits]
    if len(length_field) != digits or not length_field.isdigit():
        raise MalformedReply(f"block length field {length_field!r} is not {digits} digits")
    length = int(length_field)
    start = 2 + digits
    payload = message[start : start + length]
    if len(payload) != length:
        held = len(message) - start - (1 if message.endswith(b"\n") else 0)
        raise MalformedReply(f"block declares {length} bytes but holds {held}")
    trailer = message[start + length :]
    if trailer not in (b"", b"\n", b"\r\n"):
        raise MalformedReply(
            f"block of {length} bytes is followed by {len(trailer)} unexpected bytes "
            f"{trailer[:16]!r}"
        )
    return payload


def decode_real(payload: bytes, bits: int = 64, big_endian: bool = True) -> np.ndarray:
    """Decode a ``REAL,32`` or ``REAL,64`` payload into float64 values.

    Raises
    ------
    MalformedReply
        If the payload is not a whole number of values.
    """
    if bits not in (32, 64):
        raise ValueError(f"REAL width must be 32 or 64, not {bits}")
    width = bits // 8
    if len(payload) % width:
        raise MalformedReply(
            f"REAL,{bits} payload of {len(payload)} bytes is not a whole number of "
            f"{width}-byte values"
        )
    dtype = np.dtype(f"{'>' if big_endian else '<'}f{width}")
    return np.frombuffer(payload, dtype=dtype).astype(np.float64)


def decode_ascii(text: str) -> np.ndarray:
    """Decode a comma-separated ASCII reply (``FORM ASC``) into float64 values.

    Raises
    ------
    MalformedReply
        If the reply is empty or any field is not a number.
    """
    fields = text.strip().split(",")
    if fields == [""]:
        raise MalformedReply("expected comma-separated numbers, got an empty reply")
    try:
        return np.array([float(field) for field in fields], dtype=np.float64)
    except ValueError:
        bad = next(f for f in fields if not _is_number(f))
        raise MalformedReply(
            f"field {bad.strip()!r} of an ASCII data reply is not a number"
        ) from None


def _is_number(field: str) -> bool:
    try:
        float(field)
    except ValueError:
        return False
    return True


def no_data(values: np.ndarray) -> np.ndarray:
    """Where values hold the analyser's no-data marker (:data:`NO_DATA`)."""
    return np.isfinite(values) & (values < NO_DATA_BELOW) & (values >= 1.01 * NO_DATA)


def check_values(values: np.ndarray, what: str, points: int | None = None, *,
                 allow_no_data: bool = False) -> np.ndarray:
    """Check that values are finite (not NaN, infinite or SCPI's 9.91E+37) and, if given, count.

    Parameters
    ----------
    values
        Decoded values.
    what
        Name of the data for messages (``"TRAC:X? D1"``).
    points
        Expected number of values, or ``None`` to accept any non-zero count.
    allow_no_data
        The no-data marker is allowed (the caller turns it into NaN and flags the point).
    """
    if values.size == 0:
        raise MalformedReply(f"{what}: no values")
    if points is not None and values.size != points:
        raise MalformedReply(f"{what}: expected {points} values, got {values.size}")
    bad = ~np.isfinite(values) | (np.abs(values) >= SCPI_NOT_A_NUMBER)
    if allow_no_data:
        bad &= ~no_data(values)
    if bad.any():
        index = int(np.flatnonzero(bad)[0])
        raise MalformedReply(
            f"{what}: value {index} is {float(values[index])!r} (not a number); "
            f"{int(bad.sum())} of {values.size} values are invalid"
        )
    return values


def interleaved_to_complex(values: np.ndarray, what: str, points: int | None = None, *,
                           allow_no_data: bool = False) -> np.ndarray:
    """Turn interleaved (real, imag) values into complex numbers, checking the count.

    Parameters
    ----------
    values
        ``2 * points`` finite values, real and imaginary parts alternating.
    what
        Name of the data for messages.
    points
        Expected number of complex points, or ``None``.
    allow_no_data
        Pairs holding the no-data marker become NaN (complex) instead of an error.
    """
    if values.size % 2:
        raise MalformedReply(f"{what}: {values.size} values cannot be (real, imag) pairs")
    check_values(values, what, None if points is None else 2 * points,
                 allow_no_data=allow_no_data)
    complex_values = values[0::2] + 1j * values[1::2]
    if allow_no_data:
        missing = no_data(values[0::2]) | no_data(values[1::2])
        complex_values[missing] = complex(np.nan, np.nan)
    return complex_values


def measured_slots(axis: np.ndarray, what: str) -> int:
    """How many leading slots of a swept-sine trace hold points (the rest hold the no-data
    marker in X too). Markers inside the leading slots, or data after them, are malformed."""
    check_values(axis, what, allow_no_data=True)
    empty = no_data(axis)
    count = int(np.argmax(empty)) if empty.any() else axis.size
    if empty[count:].size and not empty[count:].all():
        raise MalformedReply(f"{what}: frequency values after the sweep's last point")
    return count


def check_axis(axis: np.ndarray, grid: np.ndarray, resolution: float, resource: str) -> None:
    """Refuse a frequency axis that is not the requested grid (in either sweep order).

    Finite but wrong X values (a wrong byte order, a stale or shifted reply) would otherwise be
    stored as frequencies. The axis is still what is returned: it carries the analyser's own
    rounding, which stays well within half a grid step.
    """
    tolerance = 0.5 * resolution
    for expected in (grid, grid[::-1]):
        if axis.shape == expected.shape and np.all(np.abs(axis - expected) <= tolerance):
            return
    ascending = np.abs(axis - grid) > tolerance if axis.shape == grid.shape else None
    index = 0 if ascending is None else int(np.flatnonzero(ascending)[0])
    raise MalformedReply(
        f"TRAC:X? D1: frequency axis value {index} is {float(axis[index])!r} Hz, off the "
        f"requested grid {grid[0]:g}..{grid[-1]:g} Hz in {resolution:g} Hz steps (wrong byte "
        "order, or a stale or damaged reply)",
        resource,
    )
