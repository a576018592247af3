"""The station file (TOML): what is attached to the analyser in this lab, validated.

::

    resource = "GPIB0::11::INSTR"                  # VISA resource of the 35670A
    adapter = "PRLGX-TCPIP::192.168.1.20::1234::INTFC"   # optional: Prologix adapter to open first

    [channels]                 # analyser inputs; REF PAIR makes 1 the reference of 2, 3 of 4
    excitation_force = 1       # F_e
    table_acceleration = 2     # ẍ_s
    device_force = 3           # F_v
    device_acceleration = 4    # ẍ_v

    [sensitivity]
    excitation_force_v_per_n = 0.01124
    table_acceleration_v_per_m_s2 = 0.0102
    device_force_v_per_n = 0.01124
    device_acceleration_v_per_m_s2 = 0.0102

    [shaker]
    force_limit_n = 100.0
    gain_n_per_v = 40.0        # optional, if known

    [source]
    limit_v = 2.0              # at most 5 Vpk
    slew_v_per_s = 1.0         # optional: the source ramps down at this rate (0: at once)

    [table]                    # optional: known M_s, K_s, C_s
    mass_kg = 3.4
    stiffness_n_per_m = 50194.0
    damping_ns_per_m = 5.05

    [chamber]                  # optional: a Eurotherm 3200-class chamber controller (Modbus)
    address = "/dev/ttyUSB1"   # or "tcp://192.168.1.30:502"
    unit = 1
    specimen_unit = 2          # optional: a second 3200 reading the specimen thermocouple
    low_limit_c = -40.0
    high_limit_c = 90.0
    safe_set_point_c = 25.0

    [specimen]                 # optional geometry
    diameter_m = 0.02
    height_m = 0.012
    count = 2
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from viscorig.errors import InputError
from viscorig.sequences.problems import Problems
from viscorig.sequences.schema import STATION_SECTIONS, STATION_TOP, ReadTable, read_table
from viscorig.sequences.sequence import parse_toml, read_text

#: A chamber controller's address: Modbus TCP, or a serial port (a path or COMn).
CHAMBER_ADDRESS = re.compile(r"^(tcp://[^\s:/]+(:\d{1,5})?|/\S+|COM\d+)\Z")
#: The analyser's source output limit, V peak.
SOURCE_MAX_V = 5.0


@dataclass(frozen=True)
class Channels:
    """Analyser input (1-4) of each transducer."""

    excitation_force: int
    table_acceleration: int
    device_force: int
    device_acceleration: int


@dataclass(frozen=True)
class Sensitivities:
    """Transducer sensitivities: V/N for forces, V/(m/s²) for accelerations."""

    excitation_force_v_per_n: float
    table_acceleration_v_per_m_s2: float
    device_force_v_per_n: float
    device_acceleration_v_per_m_s2: float


@dataclass(frozen=True)
class TableParameters:
    """Known parameters of the vibratory table."""

    mass_kg: float
    stiffness_n_per_m: float
    damping_ns_per_m: float


@dataclass(frozen=True)
class SpecimenGeometry:
    """Specimen cylinders: diameter and height in m, how many."""

    diameter_m: float
    height_m: float
    count: int
    geometry_factor_m: float | None = None
    """θ if set explicitly; otherwise the identification computes it from the arrangement."""


@dataclass(frozen=True)
class ChamberStation:
    """The temperature chamber's controller (``[chamber]``)."""

    address: str
    low_limit_c: float
    high_limit_c: float
    safe_set_point_c: float
    unit: int = 1
    specimen_unit: int | None = None
    baudrate: int = 19200
    decimals: int = 1
    specimen_time_constant_s: float = 600.0
    heating_rate_k_per_min: float | None = None
    cooling_rate_k_per_min: float | None = None

    def soak_forecast(self) -> dict[str, float | None]:
        """What a soak's forecast needs to know of the chamber
        (:func:`viscorig.acquisition.forecast_sequence`'s keywords)."""
        return {"chamber_start_c": self.safe_set_point_c,
                "specimen_time_constant_s": self.specimen_time_constant_s,
                "heating_rate_k_per_min": self.heating_rate_k_per_min,
                "cooling_rate_k_per_min": self.cooling_rate_k_per_min}

    def allows(self, temperature_c: float) -> bool:
        """Is a set point within the station's limits?"""
        return self.low_limit_c <= temperature_c <= self.high_limit_c


@dataclass(frozen=True)
class BenchSettings:
    """The bench page's address and its automatic holds (the station's ``[bench]``)."""

    address: str = "127.0.0.1"
    hold_resume: str = "technician"
    hold_level_points: int = 5
    hold_overload_points: int = 3
    hold_force_fraction: float = 0.97
    hold_temperature_points: int = 3
    hold_retry_s: float = 60.0


@dataclass(frozen=True)
class Station:
    """A validated station file."""

    resource: str
    channels: Channels
    sensitivity: Sensitivities
    shaker_force_limit_n: float
    source_limit_v: float
    shaker_gain_n_per_v: float | None = None
    adapter: str | None = None
    table: TableParameters | None = None
    specimen: SpecimenGeometry | None = None
    chamber: ChamberStation | None = None
    source: str = ""
    bench: BenchSettings = BenchSettings()
    source_slew_v_per_s: float = 1.0
    """Ramp rate of the analyser's source at the start and end of a sweep, V/s."""

    def rig_attributes(self) -> dict[str, float | int]:
        """The ``/rig`` attributes of a campaign file that this station knows."""
        attributes: dict[str, float | int] = {}
        if self.table is not None:
            attributes["table_mass_kg"] = self.table.mass_kg
            attributes["table_stiffness_n_per_m"] = self.table.stiffness_n_per_m
            attributes["table_damping_ns_per_m"] = self.table.damping_ns_per_m
        if self.specimen is not None:
            attributes["specimen_diameter_m"] = self.specimen.diameter_m
            attributes["specimen_height_m"] = self.specimen.height_m
            attributes["specimen_count"] = self.specimen.count
            if self.specimen.geometry_factor_m is not None:
                attributes["geometry_factor_m"] = self.specimen.geometry_factor_m
        return attributes


def load_station(path: str | Path) -> Station:
    """Read and validate a station file.

    Raises
    ------
    InputError
        Missing or unreadable file, or bad TOML.
    FileCheckError
        Every wrong field, named with the file and line.
    """
    return parse_station(read_text(path), source=str(path))


def parse_station(text: str, source: str = "station") -> Station:
    """Validate a station given as TOML text; ``source`` names it in messages.

    Raises
    ------
    InputError
        Not TOML.
    FileCheckError
        Every problem of the file.
    """
    document = parse_toml(text, source)
    if "steps" in document:
        raise InputError("a test sequence ([[steps]]), not a station file: give it first, as "
                         "the sequence, and the station with --station", source)
    problems = Problems(source, text)
    names = tuple(section.name for section in STATION_SECTIONS)
    top = read_table(problems, (), document, STATION_TOP, also_known=names)
    adapter = top.values.get("adapter")
    if adapter is not None and not adapter.endswith("::INTFC"):
        problems.add(("adapter",), "a GPIB adapter resource ends with ::INTFC")
    sections: dict[str, ReadTable | None] = {}
    for section in STATION_SECTIONS:
        if section.name not in document:
            sections[section.name] = None
            if section.required:
                example = "; ".join(f"{item.name} = {item.example}" for item in section.fields
                                    if item.required)
                problems.add((section.name,), "missing",
                             f"add a [{section.name}] table: {example}")
            continue
        sections[section.name] = read_table(problems, (section.name,), document[section.name],
                                            section)
    _check_channels(problems, sections["channels"])
    _check_chamber(problems, sections["chamber"])
    problems.raise_if_any()
    return _station(top, sections, source)


def _check_channels(problems: Problems, channels: ReadTable | None) -> None:
    if channels is None or not channels.ok:
        return
    numbers = channels.values
    if len(set(numbers.values())) != 4:
        problems.add(("channels",), "the four transducers need four different inputs")
        return
    for force, acceleration in (("excitation_force", "table_acceleration"),
                                ("device_force", "device_acceleration")):
        if numbers[force] % 2 != 1 or numbers[acceleration] != numbers[force] + 1:
            problems.add(
                ("channels", acceleration),
                f"{force} must be on input 1 or 3 and {acceleration} on the next input: the "
                "analyser's REF PAIR takes input 1 as reference of 2 and 3 of 4",
            )


def _check_chamber(problems: Problems, chamber: ReadTable | None) -> None:
    if chamber is None or not chamber.ok:
        return
    values = chamber.values
    if not CHAMBER_ADDRESS.fullmatch(values["address"]):
        problems.add(("chamber", "address"), f"{values['address']!r} is neither "
                     "tcp://HOST:PORT nor a serial port", 'e.g. address = "/dev/ttyUSB1"')
    low, high = values["low_limit_c"], values["high_limit_c"]
    if low >= high:
        problems.add(("chamber", "high_limit_c"), f"{high:g} °C is not above low_limit_c "
                     f"{low:g} °C")
    elif not low <= values["safe_set_point_c"] <= high:
        problems.add(("chamber", "safe_set_point_c"), f"{values['safe_set_point_c']:g} °C is "
                     f"outside the limits [{low:g}, {high:g}] °C")
    if values["specimen_unit"] is not None and values["specimen_unit"] == values["unit"]:
        problems.add(("chamber", "specimen_unit"), "the same unit as the controller",
                     "leave specimen_unit out when the controller's thermocouple is the only one")


def _station(top: ReadTable, sections: dict[str, Any], source: str) -> Station:
    # None for an absent optional section; parse_station has refused a missing required one.
    values: dict[str, Any] = {name: (None if table is None else table.values)
                              for name, table in sections.items()}
    shaker, limits = values["shaker"], values["source"]
    table = values["table"]
    specimen = values["specimen"]
    chamber = values["chamber"]
    return Station(
        resource=top["resource"],
        adapter=top.values["adapter"],
        channels=Channels(**values["channels"]),
        sensitivity=Sensitivities(**values["sensitivity"]),
        shaker_force_limit_n=shaker["force_limit_n"],
        shaker_gain_n_per_v=shaker["gain_n_per_v"],
        source_limit_v=limits["limit_v"],
        source_slew_v_per_s=limits["slew_v_per_s"],
        table=None if table is None else TableParameters(**table),
        specimen=None if specimen is None else SpecimenGeometry(**specimen),
        chamber=None if chamber is None else ChamberStation(**chamber),
        bench=BenchSettings() if values["bench"] is None else BenchSettings(**values["bench"]),
        source=source,
    )
