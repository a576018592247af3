"""Judging a station from its readings: one verdict per check, with what to do.

The transducers' roles tie their readings together (per frequency ``f``, ``ω = 2πf``, complex
amplitudes in engineering units, one common phase reference):

- the shaker: excitation force ``F_e = G·V`` for a source amplitude ``V`` (station's gain);
- the table's equation of motion: ``F_e − F_v = (M_s − K_s/ω² − iC_s/ω)·ẍ_s`` (the table's
  mass, stiffness and damping; ``F_v`` the force into the device);
- the stiff load cell: the disc accelerometer reads the table's motion, ``ẍ_v ≈ ẍ_s``.

Each input ``k`` reads ``g_k`` times its transducer's true value (``g_k = 1`` when healthy).
With three frequencies the relations over-determine ``g`` of the four inputs: ``g`` of the
excitation force from the gain, those of the table accelerometer and the device force from the
table's equation (least squares), that of the disc accelerometer from the accelerometers'
agreement. A ``g`` near −1 is a transducer read with the wrong sign, near 10 or 0.1 a
sensitivity off by ten. If two inputs read each other's transducer, no ``g`` explains the
readings, but undoing that swap does: every pair is tried.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from viscorig.acquisition.sweep import Wiring
from viscorig.mains import mains_multiples

__all__ = ["Limits", "Readings", "RigFacts", "Verdict", "assess", "mains_lines",
           "transducer_names"]

#: A healthy input reads its transducer within these bounds (magnitude ratio, phase).
GAIN_TOLERANCE = (0.7, 1.4)
PHASE_TOLERANCE_DEG = 25.0
#: The table's equation must hold to this fraction of the excitation force.
BALANCE_TOLERANCE = 0.15
#: A point whose normalized variance is above this holds no usable signal.
MAX_VARIANCE = 0.01
#: The name of the fixed-drive measurement in :attr:`Readings.overloads`.
FIXED_DRIVE = "the fixed-drive sine"
#: A line at a multiple of the mains frequency this many times the median line's power, with
#: the source off, is hum (30 dB: a sine's line stands alone there; broadband noise does not).
HUM_POWER_RATIO = 1000.0


def mains_lines(frequency_hz: np.ndarray, power: np.ndarray, line_width_hz: float
                ) -> list[tuple[float, float]]:
    """``(Hz, rms)`` of the mains multiples (:mod:`viscorig.mains`) where a power spectrum
    taken with the source off has a line :data:`HUM_POWER_RATIO` times its median line: the
    line's power within one and a half lines of it (a Hann window spreads a sine over three
    lines, its peak line holding the sine's power)."""
    median = float(np.nanmedian(power))
    found = []
    for target in mains_multiples(float(np.max(frequency_hz))):
        lines = power[np.abs(frequency_hz - target) <= 1.5 * line_width_hz]
        if median > 0 and np.isfinite(lines).any():
            peak = float(np.nanmax(lines))
            if peak >= HUM_POWER_RATIO * median:
                found.append((target, math.sqrt(peak)))
    return found


@dataclass(frozen=True)
class Verdict:
    """One check: its name, whether it passed, what was found, what to do."""

    name: str
    passed: bool
    found: str
    advice: str = ""

    def line(self) -> str:
        """One line for the technician."""
        verdict = "PASS" if self.passed else "FAIL"
        text = f"{verdict}  {self.name}: {self.found}"
        return f"{text}; {self.advice}" if self.advice and not self.passed else text


def transducer_names(wiring: Wiring) -> dict[int, str]:
    """Input -> what it measures, for messages."""
    return {wiring.excitation_force: "excitation force",
            wiring.table_acceleration: "table accelerometer",
            wiring.device_force: "device force", wiring.device_acceleration: "disc accelerometer"}


@dataclass(frozen=True)
class RigFacts:
    """What the station file knows of the rig: the table (mass kg, stiffness N/m, damping
    N·s/m) and the shaker's gain (N/V); ``None`` where it is not known."""

    table: tuple[float, float, float] | None
    gain_n_per_v: float | None


@dataclass(frozen=True)
class Limits:
    """Noise a healthy input may show with the source off, per √Hz, in its unit."""

    force_n_per_sqrt_hz: float = 1e-2
    acceleration_m_per_s2_per_sqrt_hz: float = 1e-2
    quiet_range_dbvrms: float = -11.0


@dataclass
class Readings:
    """What the procedure measured.

    Attributes
    ----------
    identity, options
        ``*IDN?`` and the installed options.
    noise_density
        Input -> median noise amplitude density with the source off (unit/√Hz).
    noise_range_dbvrms
        Input -> range autorange chose with the source off.
    frequency_hz
        Frequencies of the fixed-drive sine.
    amplitude
        Input -> complex amplitude at each frequency (engineering units, input 1's phase as
        reference), at the fixed source amplitude ``source_vpk``.
    variance
        Input -> normalized variance at each frequency.
    level_reached_m_per_s2, level_m_per_s2, tolerance_db, level_input
        The level loop: what the reference input held, the target, the tolerance, the input.
    overloads
        Input -> the measurements during which it overloaded.
    hum
        Input -> the mains lines in its noise spectrum, ``(Hz, rms in its unit)``
        (:func:`mains_lines`).
    """

    identity: str
    options: frozenset[str]
    noise_density: Mapping[int, float]
    noise_range_dbvrms: Mapping[int, float]
    frequency_hz: np.ndarray
    amplitude: Mapping[int, np.ndarray]
    variance: Mapping[int, np.ndarray]
    source_vpk: float
    sensitivity: Mapping[int, float]
    level_reached_m_per_s2: float
    level_m_per_s2: float
    tolerance_db: float
    level_input: int
    overloads: Mapping[int, list[str]] = field(default_factory=dict)
    hum: Mapping[int, list[tuple[float, float]]] = field(default_factory=dict)


def assess(readings: Readings, wiring: Wiring, rig: RigFacts,
          limits: Limits = Limits()) -> list[Verdict]:
    """Every check of the station, in the order a technician fixes things."""
    verdicts = [_identity(readings)]
    verdicts += _noise(readings, wiring, limits)
    silent = _silent(readings)
    names = transducer_names(wiring)
    for number in sorted(names):
        if number in silent:
            variance = float(np.median(readings.variance[number]))
            found = (f"normalized variance {variance:.2g}" if math.isfinite(variance)
                     else "no signal above its own noise")
            verdicts.append(Verdict(
                f"input {number} ({names[number]})", False,
                f"reads nothing at {_list(readings.frequency_hz)} Hz ({found})",
                "check the cable or the ICP supply"))
    clipped = {k for k, where in readings.overloads.items() if FIXED_DRIVE in where}
    verdicts += _roles(readings, wiring, rig, silent | clipped)
    verdicts.append(_overload(readings, names))
    verdicts.append(_level(readings))
    return verdicts


def _list(values: Iterable[float]) -> str:
    return ", ".join(f"{v:g}" for v in values)


def _identity(readings: Readings) -> Verdict:
    needed = {"1D2": "swept sine", "AY6": "four inputs"}
    missing = [f"{code} ({what})" for code, what in needed.items()
               if code not in readings.options]
    found = f"{readings.identity}; options {', '.join(sorted(readings.options)) or 'none'}"
    if "35670A" not in readings.identity.upper():
        return Verdict("analyser", False, found, "this is not a 35670A: check the resource")
    if missing:
        return Verdict("analyser", False, f"{found}; missing {', '.join(missing)}",
                       "the campaign needs these options")
    return Verdict("analyser", True, found)


def _noise(readings: Readings, wiring: Wiring, limits: Limits) -> list[Verdict]:
    verdicts = []
    forces = (wiring.excitation_force, wiring.device_force)
    for number in sorted(readings.noise_density):
        density = readings.noise_density[number]
        unit = "N" if number in forces else "m/s²"
        limit = (limits.force_n_per_sqrt_hz if number in forces
                 else limits.acceleration_m_per_s2_per_sqrt_hz)
        range_db = readings.noise_range_dbvrms[number]
        found = (f"noise {density:.2g} {unit}/√Hz with the source off, on the "
                 f"{range_db:+g} dBVrms range")
        lines = readings.hum.get(number, [])
        if lines:
            heard = ", ".join(f"{hz:g} Hz ({rms:.2g} {unit} rms)" for hz, rms in lines)
            verdicts.append(Verdict(
                f"input {number} noise", False, f"{found}; mains lines at {heard}",
                "mains hum: look for a ground loop (INP:LOW FLOat), a cable beside a mains "
                "lead or the amplifier's supply; swept-sine points near those lines will "
                "scatter"))
        elif range_db > limits.quiet_range_dbvrms:
            verdicts.append(Verdict(
                f"input {number} noise", False, found,
                "a large signal with the source off: look for hum, a ground loop (INP:LOW), a "
                "DC offset or a loose connector"))
        elif not density <= limit:
            verdicts.append(Verdict(
                f"input {number} noise", False, f"{found}, above {limit:g} {unit}/√Hz",
                "check the cable's shield, grounding and the transducer"))
        else:
            verdicts.append(Verdict(f"input {number} noise", True, found))
    return verdicts


def _silent(readings: Readings) -> set[int]:
    return {number for number, variance in readings.variance.items()
            if not np.median(variance) <= MAX_VARIANCE}


@dataclass(frozen=True)
class _Solution:
    """Factors ``g`` per input that explain the readings, and how well."""

    gains: dict[int, complex]
    residual: float


def _solve(amplitude: Mapping[int, np.ndarray], wiring: Wiring, rig: RigFacts,
           frequency_hz: np.ndarray, source_vpk: float) -> _Solution | None:
    e, s, v, d = (wiring.excitation_force, wiring.table_acceleration, wiring.device_force,
                  wiring.device_acceleration)
    m_e, m_s, m_v, m_d = (np.asarray(amplitude[k]) for k in (e, s, v, d))
    gains: dict[int, complex] = {}
    # the source's phase is not read back: the gain fixes the force's magnitude only
    gains[e] = (float(np.mean(np.abs(m_e))) / (rig.gain_n_per_v * source_vpk)
                if rig.gain_n_per_v is not None else 1.0)
    residual = 0.0
    if rig.table is None:
        return None
    mass, stiffness, damping = rig.table
    w = 2 * np.pi * frequency_hz
    z = mass - stiffness / w**2 - 1j * damping / w
    # m_v a_v + Z m_s a_s = m_e / g_e, a = 1/g: least squares over the frequencies
    matrix = np.column_stack([m_v, z * m_s])
    target = m_e / gains[e]
    solution, *_ = np.linalg.lstsq(matrix, target, rcond=None)
    if np.any(solution == 0):
        return None
    gains[v], gains[s] = 1 / solution[0], 1 / solution[1]
    residual = float(np.linalg.norm(matrix @ solution - target) / np.linalg.norm(target))
    ratio = m_d / m_s  # the disc accelerometer reads the table's motion
    gains[d] = complex(gains[s] * np.mean(ratio))
    spread = float(np.max(np.abs(ratio / np.mean(ratio) - 1)))
    return _Solution(gains, max(residual, spread))


def _healthy(g: complex) -> bool:
    low, high = GAIN_TOLERANCE
    return low <= abs(g) <= high and abs(math.degrees(np.angle(g))) <= PHASE_TOLERANCE_DEG


def _explained(solution: _Solution | None) -> bool:
    return (solution is not None and solution.residual <= BALANCE_TOLERANCE
            and all(_healthy(g) for g in solution.gains.values()))


def _what_is_wrong(g: complex) -> tuple[str, str]:
    magnitude, phase = abs(g), math.degrees(np.angle(g))
    if abs(abs(phase) - 180) <= PHASE_TOLERANCE_DEG and GAIN_TOLERANCE[0] <= magnitude <= (
            GAIN_TOLERANCE[1]):
        return ("reads with the wrong sign",
                "the transducer is mounted upside down or its cable's polarity is reversed")
    decades = math.log10(magnitude) if magnitude > 0 else -math.inf
    if abs(decades - round(decades)) < 0.15 and round(decades) != 0:
        factor = 10.0 ** round(decades)
        sign = "" if abs(phase) <= PHASE_TOLERANCE_DEG else " and with the wrong sign"
        return (f"reads {factor:g} times what its role implies{sign}",
                "its sensitivity in the station file (or the amplifier's gain) is off by "
                f"{factor:g}: check the transducer's calibration sheet")
    return (f"reads {magnitude:.3g} times (phase {phase:+.0f}°) what its role implies",
            "check its sensitivity in the station file, the transducer and its wiring")


def _roles(readings: Readings, wiring: Wiring, rig: RigFacts, silent: set[int]) -> list[Verdict]:
    names = transducer_names(wiring)
    if silent:
        unusable = ", ".join(str(k) for k in sorted(silent))
        return [Verdict("transducer roles", False,
                        f"not checked: input(s) {unusable} gave no usable reading",
                        "fix the inputs named above, then run the check again")]
    if rig.table is None:
        return [Verdict("transducer roles", True, "not checked: the station file gives no "
                        "[table] parameters (mass, stiffness, damping)")]
    f = readings.frequency_hz
    plain = _solve(readings.amplitude, wiring, rig, f, readings.source_vpk)
    if _explained(plain):
        assert plain is not None
        gains = ", ".join(f"{k}: {abs(g):.2f}" for k, g in sorted(plain.gains.items()))
        return [Verdict("transducer roles", True,
                        f"every input answers as its role implies at {_list(f)} Hz "
                        f"(gains {gains}; balance within {100 * plain.residual:.1f} %)")]
    for a, b in combinations(sorted(names), 2):
        swapped = dict(readings.amplitude)
        ratio = readings.sensitivity[a] / readings.sensitivity[b]
        swapped[a], swapped[b] = (np.asarray(readings.amplitude[b]) / ratio,
                                  np.asarray(readings.amplitude[a]) * ratio)
        if _explained(_solve(swapped, wiring, rig, f, readings.source_vpk)):
            return [Verdict(
                "transducer roles", False,
                f"inputs {a} and {b} read each other's transducer ({names[a]} and "
                f"{names[b]})", f"swap the cables of inputs {a} and {b}")]
    if plain is None:
        return [Verdict("transducer roles", False, "the readings fit no role of the rig",
                        "check every transducer's cable and sensitivity")]
    others = [g for k, g in plain.gains.items() if k != wiring.excitation_force]
    if all(_healthy(-g) for g in others) and _healthy(plain.gains[wiring.excitation_force]):
        # every response turned over: the phase reference (the excitation force) is inverted
        found, advice = _what_is_wrong(-1.0)
        number = wiring.excitation_force
        return [Verdict(f"input {number} ({names[number]})", False, found, advice)]
    verdicts = []
    for number, g in sorted(plain.gains.items()):
        if not _healthy(g):
            found, advice = _what_is_wrong(g)
            verdicts.append(Verdict(f"input {number} ({names[number]})", False, found, advice))
    if not verdicts:
        verdicts.append(Verdict(
            "transducer roles", False,
            f"the table's equation holds only to {100 * plain.residual:.0f} %",
            "check the station's [table] parameters, the load cell and the fixtures"))
    return verdicts


def _overload(readings: Readings, names: Mapping[int, str]) -> Verdict:
    if not readings.overloads:
        return Verdict("overload", True, "no input overloaded")
    parts = [f"input {k} ({names.get(k, '?')}) during {' and '.join(where)}"
             for k, where in sorted(readings.overloads.items())]
    return Verdict("overload", False, "; ".join(parts) + " at a low level",
                   "its range is too small or stuck: set autorange on and check the input's "
                   "range, coupling and grounding")


def _level(readings: Readings) -> Verdict:
    held, target = readings.level_reached_m_per_s2, readings.level_m_per_s2
    error_db = 20 * math.log10(held / target) if held > 0 else -math.inf
    found = (f"input {readings.level_input} held at {held:.3g} m/s² for {target:g} m/s² "
             f"({error_db:+.1f} dB, tolerance ±{readings.tolerance_db:g} dB)")
    if abs(error_db) <= readings.tolerance_db:
        return Verdict("level loop", True, found)
    return Verdict("level loop", False, found,
                   "the source reached its limit or the reference reads wrongly: check the "
                   "reference accelerometer, the amplifier and the station's source limit")
