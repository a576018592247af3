"""Frequency responses from SDF files, converted to accelerances and placed in a run.

An SDF file (:mod:`viscorig.exchange.sdf`) may hold any trace the analyser shows; a run takes
frequency responses only (data type 4, frequency domain), from a swept sine or from FFT mode
(H1 from random, chirp or pink noise). Anything else is refused in one line that says what the
file holds.

Units. The stored values are in the analyser's internal units (V/V); each channel header gives
the engineering unit (EU) set on the analyser and its factor ``int2engrUnit`` (V/EU), so the
response in EU is ``H_V · s_ref / s_resp``. When the EU is a unit of acceleration over force
(``m/s2``, ``g``, ``N``, ``lbf``...), that is all. When no EU was set, the channels are in volts
and the response is volt over volt: the station file's ``[channels]`` say which transducer is
on each input and ``[sensitivity]`` its V/N or V/(m/s²), and without a station the file is
refused with that fix named.

Which FRF is which. With a station, an FRF whose response and reference inputs are the table
accelerometer and the excitation force is ẍ_s/F_e, the device accelerometer over the device
force ẍ_v/F_v; any other pair is refused. Without a station, the first FRF read is ẍ_s/F_e and
the second ẍ_v/F_v. One FRF alone makes a run whose ẍ_v/F_v is missing (NaN), as a bare-table
run's is.

Points. Only the points the analyser marks valid are kept (a sweep stopped early saves fewer;
an FFT trace keeps its alias-protected lines), and a first point at 0 Hz (an FFT trace's DC
line) is dropped, since an accelerance there means nothing; any other point at or below 0 Hz
is a damaged axis, refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.exchange import units
from viscorig.exchange.frfset import FrfSet, combine_frfs
from viscorig.exchange.sdf import (
    DOMAINS,
    FREQUENCY_DOMAIN,
    FREQUENCY_RESPONSE,
    SdfFile,
    SdfTrace,
    read_sdf_file,
)

if TYPE_CHECKING:
    from viscorig.sequences import Station

TABLE_PAIR, SUPPORT_PAIR = "ẍ_s/F_e", "ẍ_v/F_v"


@dataclass(frozen=True)
class SdfFrf:
    """One frequency response read from an SDF file, in the units its channels declare."""

    frequency_hz: NDArray[np.float64]
    values: NDArray[np.complex128]
    response_unit: str
    reference_unit: str
    title: str
    response_input: int | None = None
    """Analyser input of the response channel (1-4), None when the file names no channel."""
    reference_input: int | None = None
    where: str = ""
    origin: str = ""
    """The saving instrument and measurement (``"HP 35665A swept sine"``)."""

    def in_volts(self) -> bool:
        """True when either channel is in volts (no engineering unit set on the analyser)."""
        return any(units.lookup(unit, units.VOLTAGE_UNITS) is not None
                   for unit in (self.response_unit, self.reference_unit))

    def accelerance(self, where: str, station: Station | None = None) -> NDArray[np.complex128]:
        """The values in m/s²/N.

        Channels in volts are converted with the station's sensitivities of the transducers on
        their inputs.

        Raises
        ------
        InputError
            Not acceleration over force; volts without a station; an input the station puts
            another transducer on.
        """
        response = self._factor(self.response_unit, self.response_input, "response",
                                where, station)
        reference = self._factor(self.reference_unit, self.reference_input, "reference",
                                 where, station)
        return self.values * (response / reference)

    def _factor(self, unit: str, number: int | None, side: str, where: str,
                station: Station | None) -> float:
        """Factor from the channel's unit to m/s² (response) or N (reference)."""
        quantity, table = (("acceleration", units.ACCELERATION_UNITS) if side == "response"
                           else ("force", units.FORCE_UNITS))
        volts = units.lookup(unit, units.VOLTAGE_UNITS)
        if volts is None:
            return units.factor(unit, table, quantity, f"{where}: {side} channel unit")
        if station is None:
            raise InputError(
                f"a volt-over-volt frequency response (input {self.response_input} over input "
                f"{self.reference_input}, no engineering units set on the analyser): give "
                "--station STATION.toml, whose [channels] and [sensitivity] convert it", where)
        role, expected, sensitivity = _roles(station).get(number or 0, ("", "", 0.0))
        if not role:
            raise InputError(f"{side} input {number} carries no transducer in "
                             f"{station.source or 'the station'} [channels]", where)
        if expected != quantity:
            raise InputError(f"{side} input {number} is the station's {role} (a {expected}), "
                             f"not an {quantity}", where)
        return volts / sensitivity


def _roles(station: Station) -> dict[int, tuple[str, str, float]]:
    """Analyser input -> (transducer, quantity, sensitivity in V per SI unit)."""
    c, s = station.channels, station.sensitivity
    return {
        c.excitation_force: ("excitation_force", "force", s.excitation_force_v_per_n),
        c.table_acceleration: ("table_acceleration", "acceleration",
                               s.table_acceleration_v_per_m_s2),
        c.device_force: ("device_force", "force", s.device_force_v_per_n),
        c.device_acceleration: ("device_acceleration", "acceleration",
                                s.device_acceleration_v_per_m_s2),
    }


def _article(text: str) -> str:
    return ("an " if text[:1].lower() in "aeiou" else "a ") + text


def describe_sdf(file: SdfFile) -> str:
    """What the file holds, in words, for a refusal."""
    kinds: list[str] = []
    for trace in file.traces:
        kind = trace.kind
        if trace.domain != FREQUENCY_DOMAIN:
            kind += f" ({DOMAINS.get(trace.domain, f'domain {trace.domain}')} domain)"
        kind += f" '{trace.title}'" if trace.title else ""
        if kind not in kinds:
            kinds.append(kind)
    held = " and ".join(_article(k) for k in kinds) if kinds else "no trace"
    return f"holds {held} ({file.instrument}, {file.measurement_name})"


def _frf(trace: SdfTrace, where: str, origin: str) -> SdfFrf:
    if not np.iscomplexobj(trace.values):
        raise InputError("a frequency response must be complex; this one is real", where)
    scale = units.factor(trace.x_unit or "Hz", units.FREQUENCY_UNITS, "frequency",
                         f"{where}: X unit")
    valid = np.flatnonzero(trace.valid)
    x = np.asarray(trace.x)[valid]
    dc = x.size > 0 and x[0] == 0.0  # an FFT trace's first line
    wrong = np.flatnonzero(~(x > 0.0))[1 if dc else 0:]
    if wrong.size:
        at = int(valid[wrong[0]])
        raise InputError(f"{wrong.size} valid point(s) at or below 0 Hz or not a number, the "
                         f"first point {at + 1} of {trace.x.size} at {trace.x[at]:g} "
                         f"{trace.x_unit or 'Hz'}: a frequency axis no analyser writes", where)
    keep = trace.valid & (trace.x > 0)
    if not np.any(keep):
        raise InputError("holds no valid point above 0 Hz", where)
    values = np.asarray(trace.values[keep], dtype=np.complex128)  # complex: checked above
    response, reference = trace.response, trace.reference
    if response is None and reference is None:
        if "/" not in trace.y_unit:
            raise InputError("names no channel and no Y unit of the form EU/EU", where)
        numerator, denominator = trace.y_unit.split("/", 1)
        return SdfFrf(trace.x[keep] * scale, values, numerator, denominator, trace.title,
                      where=where, origin=origin)
    if response is None or reference is None or trace.powers != (48, -48):
        raise InputError(f"channel powers {trace.powers[0]}/48, {trace.powers[1]}/48 are not "
                         "those of a frequency response (+1 over -1)", where)
    if response.number == reference.number:
        raise InputError(f"response and reference are both input {response.number} "
                         f"('{response.label}', '{reference.label}')", where)
    return SdfFrf(
        trace.x[keep] * scale, values * (reference.int2engr / response.int2engr),
        response.unit, reference.unit, trace.title, response.number, reference.number, where,
        origin,
    )


def read_sdf(path: str | Path) -> list[SdfFrf]:
    """Every frequency response of an SDF file, in the units its channels declare.

    Raises
    ------
    InputError
        The file is bad (see :func:`~viscorig.exchange.sdf.read_sdf_file`) or holds no
        frequency response: the message says what it holds.
    """
    file = read_sdf_file(path)
    found: list[SdfFrf] = []
    for trace in file.traces:
        if trace.domain == FREQUENCY_DOMAIN and trace.data_type == FREQUENCY_RESPONSE:
            number = len(found) + 1
            found.append(_frf(trace, f"{file.path} (frequency response {number})",
                              f"{file.instrument} {file.measurement_name}"))
    if not found:
        raise InputError(f"{describe_sdf(file)}; a run takes frequency responses only",
                         file.path)
    return found


def read_sdf_frfs(paths: list[Path], station: Station | None = None) -> FrfSet:
    """The FRFs of one or two SDF files as a run's ẍ_s/F_e and (if present) ẍ_v/F_v.

    Raises
    ------
    InputError
        A file is bad or holds no FRF, volts without a station, more than two FRFs, an FRF
        whose inputs the station does not pair, no ẍ_s/F_e, axes that differ.
    """
    per_file = [read_sdf(Path(path)) for path in paths]
    frfs = [frf for found in per_file for frf in found]
    source = "SDF " + ", ".join(f"{Path(path).name} ({found[0].origin})"
                                for path, found in zip(paths, per_file, strict=True))
    if len(frfs) > 2:
        raise InputError(f"{len(frfs)} frequency responses; a run has two "
                         f"({TABLE_PAIR}, then {SUPPORT_PAIR})", source)
    if station is not None:
        frfs = _by_role(frfs, station, source)
    axes = [frf.frequency_hz for frf in frfs]
    values = [frf.accelerance(frf.where, station) for frf in frfs]
    return combine_frfs(axes, values, [frf.where for frf in frfs], source)


def _by_role(frfs: list[SdfFrf], station: Station, source: str) -> list[SdfFrf]:
    """The FRFs ordered ẍ_s/F_e, ẍ_v/F_v by the station's channel roles."""
    c = station.channels
    pairs = {(c.table_acceleration, c.excitation_force): TABLE_PAIR,
             (c.device_acceleration, c.device_force): SUPPORT_PAIR}
    slots: dict[str, SdfFrf] = {}
    for frf in frfs:
        pair = pairs.get((frf.response_input or 0, frf.reference_input or 0))
        if pair is None:
            raise InputError(
                f"input {frf.response_input} over input {frf.reference_input} is neither "
                f"{TABLE_PAIR} (input {c.table_acceleration} over {c.excitation_force}) nor "
                f"{SUPPORT_PAIR} (input {c.device_acceleration} over {c.device_force}) in "
                f"{station.source or 'the station'}", frf.where)
        if pair in slots:
            raise InputError(f"{pair} given twice (also in {slots[pair].where})", frf.where)
        slots[pair] = frf
    if TABLE_PAIR not in slots:
        raise InputError(f"holds {SUPPORT_PAIR} only; a run needs {TABLE_PAIR} (input "
                         f"{c.table_acceleration} over input {c.excitation_force})", source)
    return [slots[pair] for pair in (TABLE_PAIR, SUPPORT_PAIR) if pair in slots]
