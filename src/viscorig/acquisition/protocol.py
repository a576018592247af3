"""What the acquisition layer needs from an analyser driver: a structural protocol.

The core never imports a driver. Any object with these members works: the 35670A driver
(``agilent35670a.Agilent35670A``) satisfies it as it is, and a second analyser model only has
to provide the same few calls. Only the command line wires a concrete driver to the core.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Protocol, runtime_checkable

import numpy as np


class SweepProgressReport(Protocol):
    """A driver's report while a segment is being measured."""

    @property
    def elapsed_s(self) -> float:
        """Seconds since the segment started (pauses included)."""

    @property
    def expected_s(self) -> float:
        """Settle and integration time of the whole segment, s."""


class MeasuredSegment(Protocol):
    """What a driver returns for one measured sub-band (one analyser sweep).

    Channels are analyser inputs 1..4; the FRFs are input 2 over input 1 and 4 over 3 (the
    analyser's ``REF PAIR``), in engineering units.
    """

    @property
    def frequency_hz(self) -> np.ndarray:
        """The analyser's own frequency axis, in measurement order."""

    @property
    def frf_21(self) -> np.ndarray:
        """Input 2 / input 1, complex."""

    @property
    def frf_43(self) -> np.ndarray | None:
        """Input 4 / input 3, complex (``None`` with two channels)."""

    @property
    def amplitude_eu(self) -> Mapping[int, np.ndarray]:
        """Input -> peak amplitude at each point, engineering units."""

    @property
    def variance(self) -> Mapping[int, np.ndarray]:
        """Input -> normalized variance at each point."""

    @property
    def overload_channels(self) -> tuple[int, ...]:
        """Inputs that overloaded at any point of the segment (latched per segment)."""

    @property
    def started_at_s(self) -> float:
        """Wall-clock time (``time.time()``) the segment started.

        A driver may also give ``no_data``: a boolean per point, true where the analyser's
        trace held its no-data marker (the values there are NaN); the sweep measures such a
        segment again and never stores those points as measured.
        """

    @property
    def finished_at_s(self) -> float:
        """Wall-clock time the segment ended."""


ProgressCallback = Callable[[SweepProgressReport], None]


@runtime_checkable
class Analyser(Protocol):
    """A swept-sine analyser with auto level, as the acquisition layer drives it.

    Faults are raised as the driver's own exceptions; the caller says which types are
    instrument faults (see :class:`viscorig.acquisition.runner.Runner`).
    """

    @property
    def resource(self) -> str:
        """The VISA resource string (named in every fault message)."""

    def identify(self) -> str:
        """The ``*IDN?`` answer."""

    def configure_swept_sine(
        self,
        *,
        inputs: Sequence[tuple[int, str, float]],
        reference_channel: int,
        reference_level_eu: float,
        source_limit_vpk: float,
        input_limit_eu: float | None,
        pairing: str | None,
        resolution_hz: float,
        start_hz: float,
        stop_hz: float,
        settle_cycles: float,
        integrate_cycles: float,
        direction: str,
        tolerance_db: float,
        start_level_vpk: float,
        source_slew_v_per_s: float,
    ) -> None:
        """Set up the sweep with the source off; the source limit is set before anything that
        could switch the source on; the source ramps at ``source_slew_v_per_s`` when a sweep
        starts and stops (0: at once). ``inputs`` is ``(input, label, sensitivity V/EU)`` per
        transducer and ``reference_channel`` the auto-level input, both from
        :class:`~viscorig.acquisition.sweep.Wiring` (the driver knows no wiring)."""

    def measure(
        self,
        start_hz: float,
        stop_hz: float,
        *,
        progress: ProgressCallback | None = None,
        poll_interval_s: float = 0.2,
    ) -> MeasuredSegment:
        """Measure ``start_hz`` .. ``stop_hz`` (at least two points) on the configured grid."""

    def measure_point(
        self,
        frequency_hz: float,
        *,
        progress: ProgressCallback | None = None,
        poll_interval_s: float = 0.2,
    ) -> MeasuredSegment:
        """Measure a single frequency."""

    def abort(self) -> None:
        """Stop the running measurement and switch the source off; ``measure`` then raises."""

    def close(self) -> None:
        """Release the connection."""


@runtime_checkable
class PointAnalyser(Analyser, Protocol):
    """An analyser that also measures chosen frequencies with their own timing (what an
    adaptive plan needs): manual sweep mode at arbitrary frequencies, and short linear
    sub-sweeps with a resolution, settle and integration of their own."""

    def measure_points(
        self,
        frequencies_hz: Sequence[float],
        *,
        settle_cycles: float | None = None,
        integrate_cycles: float | None = None,
        start_levels_vpk: Sequence[float] | None = None,
        progress: ProgressCallback | None = None,
        poll_interval_s: float = 0.2,
    ) -> MeasuredSegment:
        """Measure the frequencies in the order given (the analyser's own axis returned), each
        starting the auto-level controller at its start level when given."""

    def measure(
        self,
        start_hz: float,
        stop_hz: float,
        *,
        resolution_hz: float | None = None,
        settle_cycles: float | None = None,
        integrate_cycles: float | None = None,
        start_level_vpk: float | None = None,
        progress: ProgressCallback | None = None,
        poll_interval_s: float = 0.2,
    ) -> MeasuredSegment:
        """Measure a linear sub-band, with this call's grid, timing and start level when
        given."""

    def expected_duration_s(self, grid_hz: Iterable[float]) -> float:
        """Time the analyser takes for these points with the settings sent (s)."""
