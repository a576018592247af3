"""Replies a test analyser serves: IEEE 488.2 blocks and canned trace data."""

from __future__ import annotations

import numpy as np


def definite_block(values: np.ndarray, dtype: str = ">f8") -> bytes:
    """``#<n><len><bytes>`` and a line feed, as the 35670A answers in ``FORM REAL``."""
    payload = np.asarray(values, dtype=dtype).tobytes()
    length = str(len(payload)).encode()
    return b"#" + str(len(length)).encode() + length + payload + b"\n"


def interleave(values: np.ndarray) -> np.ndarray:
    """Complex values as the analyser sends them: real, imaginary, real, ..."""
    out = np.empty(2 * values.size)
    out[0::2], out[1::2] = values.real, values.imag
    return out


def canned_trace(feed: str, frf_21: np.ndarray) -> np.ndarray:
    """Data of each trace feed, made up but distinct: the 2/1 FRF given (4/3 twice it), linear
    spectra ``(3+4j)·n``, variances ``1e-4·n`` (real)."""
    kind, _, argument = feed.partition(" ")
    if kind == "XFR:POW:RAT":
        return interleave(frf_21 if argument == "2,1" else 2 * frf_21)
    if kind == "XFR:POW:LIN":
        return interleave((3 + 4j) * int(argument) * np.ones(frf_21.size))
    return np.full(frf_21.size, 1e-4 * int(argument))
