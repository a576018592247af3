"""What one measurement gives back: a sweep segment's data, and progress while it runs."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Spectra", "SweepProgress", "SweepSegment"]


@dataclass(frozen=True)
class SweepProgress:
    """State of a running measurement, passed to the progress callback.

    Attributes
    ----------
    elapsed_s
        Seconds since the measurement started (pauses included).
    expected_s
        Settle and integration time of the whole segment from the settings (a lower bound).
    paused
        The measurement is paused.
    settling, ranging, measuring, calibrating
        Bits of ``STAT:OPER:COND?`` at this poll.
    calibrating_s
        Time the analyser spent calibrating during this measurement so far (it does not count
        against the deadline).
    """

    elapsed_s: float
    expected_s: float
    paused: bool
    settling: bool
    ranging: bool
    measuring: bool
    calibrating: bool = False
    calibrating_s: float = 0.0


@dataclass(frozen=True)
class SweepSegment:
    """Everything the analyser gives for one measured sub-band (or set of manual points).

    Attributes
    ----------
    frequency_hz
        The analyser's own frequency axis (``TRAC:X?``), never computed.
    frf_21
        Frequency response channel 2 / channel 1, complex, in channel 2's engineering unit per
        channel 1's. What it is physically (a table or a support accelerance) is the caller's
        wiring; the driver does not say.
    frf_43
        Channel 4 / channel 3 in the same way, or ``None`` with two channels.
    amplitude_eu
        Channel number -> magnitude of its linear spectrum at each point, in that channel's
        engineering unit (``eu_labels``), as the analyser scales it (peak in swept sine,
        inferred).
    variance
        Channel number -> the analyser's normalized variance of that channel at each point
        (dimensionless).
    eu_labels
        Channel number -> engineering-unit label sent to the analyser (``"N"``, ``"M/S2"``).
    overload_channels, half_range_channels
        Channels whose input exceeded its range (or half of it) at any point of this segment
        (``STAT:QUES:VOLT:EVEN?`` latches over the sweep, so it is known per segment only).
    started_at_s, finished_at_s
        Wall-clock times (``time.time()``) at the start and end of the measurement.
    no_data
        Points where the analyser's trace held its no-data marker in any quantity read (their
        values are NaN); all false for a complete sweep.
    extras
        Further data by name: with ``REF SING`` (input 1 the reference of every input),
        ``frf_31`` and ``frf_41``, the responses of inputs 3 and 4 over input 1.
    ended_early
        The sweep was ended at a point boundary (``end_after_point``): it holds the first
        points of the band asked for, in sweep order (possibly none).

    Notes
    -----
    The source level used at each point is not readable from the 35670A in swept sine (no
    command for it in the programming guide), so it is not part of a segment.
    """

    frequency_hz: np.ndarray
    frf_21: np.ndarray
    frf_43: np.ndarray | None
    amplitude_eu: Mapping[int, np.ndarray]
    variance: Mapping[int, np.ndarray]
    eu_labels: Mapping[int, str]
    overload_channels: tuple[int, ...]
    half_range_channels: tuple[int, ...]
    started_at_s: float
    finished_at_s: float
    extras: Mapping[str, np.ndarray] = field(default_factory=dict)
    no_data: np.ndarray | None = None
    ended_early: bool = False

    def __len__(self) -> int:
        return int(self.frequency_hz.size)

    @property
    def variance_21(self) -> np.ndarray | None:
        """Normalized variance of ``frf_21``: channel 1 and 2 variances added (first order)."""
        return self._ratio_variance(2, 1)

    @property
    def variance_43(self) -> np.ndarray | None:
        """Normalized variance of ``frf_43``: channel 3 and 4 variances added (first order)."""
        return self._ratio_variance(4, 3)

    def _ratio_variance(self, numerator: int, denominator: int) -> np.ndarray | None:
        if numerator in self.variance and denominator in self.variance:
            return self.variance[numerator] + self.variance[denominator]
        return None


@dataclass(frozen=True)
class Spectra:
    """An FFT measurement's spectra (``XFR:POW n`` per input), as the bench check reads them.

    Attributes
    ----------
    frequency_hz
        The analyser's frequency axis (displayed lines).
    power
        Input -> power spectrum, rms² in the input's unit (V² or EU²); NaN where the analyser
        put its no-data marker (the dB value of a zero line).
    line_width_hz
        Spacing of the lines (span / lines).
    ranges_dbvrms
        Input -> range the analyser chose or was given (``VOLTn:RANG?``), dBVrms.
    overload_channels
        Inputs that overloaded during the measurement.
    """

    frequency_hz: np.ndarray
    power: Mapping[int, np.ndarray]
    line_width_hz: float
    ranges_dbvrms: Mapping[int, float]
    overload_channels: tuple[int, ...]
