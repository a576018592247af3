"""What the virtual analyser asks of the simulated rig, and what the rig gives back.

The analyser (``rigsim.analyser``) owns the instrument state: frequencies, timing in cycles or
seconds, channels, ranges, engineering units, traces. The rig simulator
(``rigsim.engine.RigSimulator``) owns the physics and the measuring front end: it integrates the
equations of motion in the time domain through each point's settle and integration windows,
runs the auto-level controller, ranges the inputs and correlates each channel at the source
frequency. These two dataclasses are the whole interface between them; both sides use volts at
the analyser inputs, never engineering units.

Channels are numbered 1..4 as on the analyser's front panel and wired to the rig's sensors as the
paper does: 1 the excitation force ``F_e``, 2 the table acceleration, 3 the force into the device
``F_v``, 4 the disc acceleration. Arrays indexed by channel put channel 1 in column 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

CHANNEL_COUNT = 4

#: Input ranges of the analyser: +27 dBVrms down to -51 dBVrms in 2 dB steps, as peak volts.
INPUT_RANGES_DBVRMS = np.arange(27.0, -51.0 - 1e-9, -2.0)
INPUT_RANGES_VPK = np.sqrt(2.0) * 10.0 ** (INPUT_RANGES_DBVRMS / 20.0)


@dataclass(frozen=True)
class SourceControl:
    """How the source is driven during a sweep.

    Attributes
    ----------
    source_vpk
        Source level in volts peak: the fixed level when ``auto_level`` is off, the starting
        level of the controller when it is on.
    auto_level
        Adjust the source at each point so that the reference channel holds ``reference_vpk``.
    reference_channel
        Channel (1..4) that the controller holds at the reference level.
    reference_vpk
        Target peak voltage at the reference channel's input.
    tolerance_db
        Accept a point when the reference is within this many dB of the target.
    source_limit_vpk
        The controller never drives the source above this level (the analyser's ``SOUR:VOLT:LIM``).
    input_limit_channel, input_limit_vpk
        Optional second limit: the controller never lets this channel's peak voltage exceed this
        level (the analyser's ``SOUR:VOLT:LIM:INP``, used to hold the shaker force below its limit).
    input_limits_vpk
        Optional limit per channel (volts peak, ``None`` for no limit on that channel): the
        analyser's ``SOUR:VOLT:LIM:INP`` holds every input but the reference below one level.
    max_iterations
        Controller iterations per point before it gives up and measures where it is.
    """

    source_vpk: float
    auto_level: bool = False
    reference_channel: int = 4
    reference_vpk: float = 0.0
    tolerance_db: float = 2.0
    source_limit_vpk: float = 2.0
    input_limit_channel: int | None = None
    input_limit_vpk: float | None = None
    input_limits_vpk: tuple[float | None, ...] | None = None
    max_iterations: int = 8


@dataclass(frozen=True)
class SweepRequest:
    """Points to measure, in measurement order, and how.

    Attributes
    ----------
    frequency_hz
        Source frequency of each point, in the order the sweep visits them.
    settle_s
        Wait after each frequency change before integrating, per point (seconds).
    integrate_s
        Integration (dwell) time per point (seconds).
    control
        Source and auto-level settings.
    input_range_vpk
        Fixed input range per channel in volts peak, or ``None`` for autorange on that channel
        (in swept sine the analyser re-ranges at every point). Fixed ranges are snapped to
        :data:`INPUT_RANGES_VPK` by the analyser before they reach the simulator.
    """

    frequency_hz: np.ndarray
    settle_s: np.ndarray
    integrate_s: np.ndarray
    control: SourceControl
    input_range_vpk: tuple[float | None, ...] = (None,) * CHANNEL_COUNT


@dataclass
class SweepRecord:
    """What the front end measured at each point of a :class:`SweepRequest`.

    Every array has one row per point, in measurement order; per-channel arrays have
    :data:`CHANNEL_COUNT` columns.

    Attributes
    ----------
    frequency_hz
        Source frequency of each point.
    channel_v
        Complex amplitude (peak volts) of each channel at the source frequency, from the
        single-frequency correlation over the integration window.
    variance
        Normalized variance of each channel's estimate (the analyser's swept-sine quality
        measure): the variance of the amplitude estimate divided by its squared magnitude.
    range_vpk
        Input range each channel was measured on.
    overload
        The channel's instantaneous signal exceeded its range during the point.
    half_range
        The channel's signal exceeded half its range during the point.
    source_vpk
        Source level used for the point.
    level_reached
        With auto level on: the reference was within tolerance. Always true with auto level off.
    source_limited
        The controller wanted more than ``source_limit_vpk`` and measured at that limit.
    input_limited
        The controller was held back by the input limit (for example the shaker force limit).
    end_time_s
        Simulator clock (seconds of test time since the rig was mounted) at the end of each point.
    """

    frequency_hz: np.ndarray
    channel_v: np.ndarray
    variance: np.ndarray
    range_vpk: np.ndarray
    overload: np.ndarray
    half_range: np.ndarray
    source_vpk: np.ndarray
    level_reached: np.ndarray
    source_limited: np.ndarray
    input_limited: np.ndarray
    end_time_s: np.ndarray
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.frequency_hz.size)
