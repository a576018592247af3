"""Measuring for the bench check: what the analyser is asked, in about a minute of rig time.

1. ``*IDN?``, ``*OPT?``.
2. FFT, source off: each input's power spectrum (0-400 Hz, 400 lines, Hann, 8 averages), the
   range autorange chose, and the lines at multiples of the mains frequency (hum).
3. Swept sine, manual points at 10, 25 and 45 Hz, a fixed small source amplitude, ``REF SING``
   so that every input's response is read against input 1 (one phase reference).
4. The level loop closed (auto level) at 10 Hz on the reference accelerometer at a low level.

The analyser is driven through any object with the driver's calls (``agilent35670a``): the core
imports no driver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from viscorig.acquisition.sweep import Wiring
from viscorig.benchcheck.checks import FIXED_DRIVE, Readings, mains_lines

__all__ = ["CheckSettings", "measure"]


@dataclass(frozen=True)
class CheckSettings:
    """How the bench check measures.

    Attributes
    ----------
    frequencies_hz
        Fixed-drive sine frequencies: below, across and above the loaded table's resonance.
    source_vpk
        Fixed source amplitude (volts peak), small: a few newtons through a typical shaker.
    level_m_per_s2, tolerance_db
        The level loop's target on the reference accelerometer, and its tolerance.
    settle_cycles, integrate_cycles
        Per sine point.
    noise_span_hz, noise_averages
        The FFT noise measurement.
    """

    frequencies_hz: tuple[float, ...] = (10.0, 25.0, 45.0)
    source_vpk: float = 0.05
    level_m_per_s2: float = 0.5
    tolerance_db: float = 2.0
    settle_cycles: float = 20.0
    integrate_cycles: float = 40.0
    noise_span_hz: float = 400.0
    noise_averages: int = 8


def _record_overloads(overloads: dict[int, list[str]], channels: tuple[int, ...],
                      where: str) -> None:
    for channel in channels:
        overloads.setdefault(channel, []).append(where)


def measure(analyser: Any, wiring: Wiring, source_limit_v: float, force_limit_n: float | None,
            settings: CheckSettings = CheckSettings()) -> Readings:
    """Run the bench check's measurements on a connected analyser (the 35670A driver).

    Parameters
    ----------
    analyser
        ``agilent35670a.Agilent35670A`` (or anything with its calls).
    wiring
        Which input measures what, and each transducer's sensitivity.
    source_limit_v, force_limit_n
        The station's limits: the source never exceeds them.
    settings
        How to measure.
    """
    identity = analyser.identify()
    options = frozenset(analyser.options)
    overloads: dict[int, list[str]] = {}
    start_vpk = min(settings.source_vpk, source_limit_v)
    low, high = min(settings.frequencies_hz), max(settings.frequencies_hz)
    analyser.configure_swept_sine(
        inputs=wiring.inputs(), reference_channel=wiring.reference_channel(bare_table=False),
        reference_level_eu=settings.level_m_per_s2, source_limit_vpk=source_limit_v,
        input_limit_eu=force_limit_n, pairing=Wiring.PAIRING, resolution_hz=1.0, start_hz=low,
        stop_hz=high, settle_cycles=settings.settle_cycles,
        integrate_cycles=settings.integrate_cycles, tolerance_db=settings.tolerance_db,
        start_level_vpk=start_vpk,
    )
    # 1. noise with the source off
    spectra = analyser.measure_spectra(span_hz=settings.noise_span_hz, lines=400,
                                       averages=settings.noise_averages, window="HANN")
    _record_overloads(overloads, spectra.overload_channels, "the noise measurement")
    density, hum = {}, {}
    band = spectra.frequency_hz >= 5.0
    for channel, power in spectra.power.items():
        # Hann window: a line's noise bandwidth is 1.5 lines
        per_hz = power[band] / (1.5 * spectra.line_width_hz)
        density[channel] = float(math.sqrt(np.nanmedian(per_hz)))
        hum[channel] = mains_lines(spectra.frequency_hz[band], power[band],
                                   spectra.line_width_hz)
    # 2. a fixed small drive, every input read against input 1
    analyser.instrument_mode = "SINE"
    analyser.channels_in_use = (1, 2, 3, 4)
    analyser.sweep.reference_pairing = "SING"
    analyser.source.auto_level = False
    analyser.source.level_vpk = start_vpk
    fixed = analyser.measure_points(list(settings.frequencies_hz),
                                    settle_cycles=settings.settle_cycles,
                                    integrate_cycles=settings.integrate_cycles,
                                    poll_interval_s=0.05)
    _record_overloads(overloads, fixed.overload_channels, FIXED_DRIVE)
    reference = np.asarray(fixed.amplitude_eu[1], dtype=float)
    amplitude = {1: reference.astype(complex), 2: reference * fixed.frf_21,
                 3: reference * fixed.extras["frf_31"], 4: reference * fixed.extras["frf_41"]}
    # 3. the level loop, closed on the disc accelerometer
    analyser.source.auto_level = True
    levelled = analyser.measure_points([low], poll_interval_s=0.05)
    _record_overloads(overloads, levelled.overload_channels, "the level loop")
    held = float(np.asarray(levelled.amplitude_eu[wiring.device_acceleration])[0])
    return Readings(
        identity=identity, options=options, noise_density=density,
        noise_range_dbvrms=dict(spectra.ranges_dbvrms),
        frequency_hz=np.asarray(fixed.frequency_hz, dtype=float), amplitude=amplitude,
        variance={k: np.asarray(v, dtype=float) for k, v in fixed.variance.items()},
        source_vpk=start_vpk, sensitivity=dict(wiring.sensitivities_v_per_eu),
        level_reached_m_per_s2=held if math.isfinite(held) else 0.0,
        level_m_per_s2=settings.level_m_per_s2, tolerance_db=settings.tolerance_db,
        level_input=wiring.device_acceleration, overloads=overloads, hum=hum,
    )
