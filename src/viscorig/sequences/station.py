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

    [table]                    # optional: known M_s, K_s, C_s
    mass_kg = 3.4
    stiffness_n_per_m = 50194.0
    damping_ns_per_m = 5.05

    [specimen]                 # optional geometry
    diameter_m = 0.02
    height_m = 0.012
    count = 2
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from viscorig.errors import InputError
from viscorig.sequences.fields import TableReader
from viscorig.sequences.sequence import parse_toml

_RESOURCE = re.compile(r"^[A-Za-z][A-Za-z0-9-]*::\S+::(INSTR|SOCKET|INTFC)$")
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
    source: str = ""

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
        Missing or unreadable file, bad TOML, or a wrong field (named with the file).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"cannot be read ({type(error).__name__}: {error})", str(path)) from None
    return parse_station(text, source=str(path))


def _resource(fields: TableReader, key: str) -> str:
    value = fields.text(key)
    if not _RESOURCE.match(value):
        raise fields.fail(key, f"{value!r} is not a VISA resource like \"GPIB0::11::INSTR\"")
    return value


def parse_station(text: str, source: str = "station") -> Station:
    """Validate a station given as TOML text; ``source`` names it in messages."""
    top = TableReader(parse_toml(text, source), source, top_level=True)
    resource = _resource(top, "resource")
    adapter = _resource(top, "adapter") if top.raw("adapter", None) is not None else None
    if adapter is not None and not adapter.endswith("::INTFC"):
        raise top.fail("adapter", "a GPIB adapter resource ends with ::INTFC")

    channels = TableReader(top.subtable("channels"), f"{source}: channels")
    numbers = {key: channels.integer(key, low=1, high=4) for key in
               ("excitation_force", "table_acceleration", "device_force", "device_acceleration")}
    channels.finish()
    if len(set(numbers.values())) != 4:
        raise InputError("the four transducers need four different inputs", f"{source}: channels")
    for force, acceleration in (("excitation_force", "table_acceleration"),
                                ("device_force", "device_acceleration")):
        if numbers[force] % 2 != 1 or numbers[acceleration] != numbers[force] + 1:
            raise InputError(
                f"{force} must be on input 1 or 3 and {acceleration} on the next input: the "
                "analyser's REF PAIR takes input 1 as reference of 2 and 3 of 4",
                f"{source}: channels.{acceleration}",
            )

    sensitivity = TableReader(top.subtable("sensitivity"), f"{source}: sensitivity")
    sensitivities = Sensitivities(
        excitation_force_v_per_n=sensitivity.number(
            "excitation_force_v_per_n", low=1e-6, high=10.0, unit="V/N"),
        table_acceleration_v_per_m_s2=sensitivity.number(
            "table_acceleration_v_per_m_s2", low=1e-6, high=10.0, unit="V/(m/s^2)"),
        device_force_v_per_n=sensitivity.number(
            "device_force_v_per_n", low=1e-6, high=10.0, unit="V/N"),
        device_acceleration_v_per_m_s2=sensitivity.number(
            "device_acceleration_v_per_m_s2", low=1e-6, high=10.0, unit="V/(m/s^2)"),
    )
    sensitivity.finish()

    shaker = TableReader(top.subtable("shaker"), f"{source}: shaker")
    force_limit = shaker.number("force_limit_n", low=0.0, high=1e5, low_open=True, unit="N")
    gain = shaker.number("gain_n_per_v", math.nan, low=0.0, high=1e6, low_open=True, unit="N/V")
    shaker.finish()

    source_table = TableReader(top.subtable("source"), f"{source}: source")
    limit_v = source_table.number("limit_v", low=0.0, high=SOURCE_MAX_V, low_open=True, unit="V")
    source_table.finish()

    table = None
    raw_table = top.subtable("table", required=False)
    if raw_table is not None:
        reader = TableReader(raw_table, f"{source}: table")
        table = TableParameters(
            mass_kg=reader.number("mass_kg", low=0.0, high=1e4, low_open=True, unit="kg"),
            stiffness_n_per_m=reader.number("stiffness_n_per_m", low=0.0, high=1e10,
                                            low_open=True, unit="N/m"),
            damping_ns_per_m=reader.number("damping_ns_per_m", low=0.0, high=1e7,
                                           unit="N*s/m"),
        )
        reader.finish()

    specimen = None
    raw_specimen = top.subtable("specimen", required=False)
    if raw_specimen is not None:
        reader = TableReader(raw_specimen, f"{source}: specimen")
        factor = reader.number("geometry_factor_m", math.nan, low=0.0, high=100.0,
                               low_open=True, unit="m")
        specimen = SpecimenGeometry(
            diameter_m=reader.number("diameter_m", low=0.0, high=1.0, low_open=True, unit="m"),
            height_m=reader.number("height_m", low=0.0, high=1.0, low_open=True, unit="m"),
            count=reader.integer("count", low=1, high=16),
            geometry_factor_m=None if math.isnan(factor) else factor,
        )
        reader.finish()
    top.finish()
    return Station(
        resource=resource,
        adapter=adapter,
        channels=Channels(**numbers),
        sensitivity=sensitivities,
        shaker_force_limit_n=force_limit,
        shaker_gain_n_per_v=None if math.isnan(gain) else gain,
        source_limit_v=limit_v,
        table=table,
        specimen=specimen,
        source=source,
    )
