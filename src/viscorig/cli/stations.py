"""Wiring of a station for ``viscorig run``: a real analyser, or the embedded simulated rig.

This is the one place where the driver (``agilent35670a``) and the simulator (``rigsim``) meet
the core. The embedded rig is a virtual 35670A served on 127.0.0.1 (a free port) and reached
through the real driver over pyvisa-py (``TCPIP::127.0.0.1::<port>::SOCKET``), exactly as a lab
analyser behind a socket would be; sequence prompts with ``simulated_rig = "..."`` mount that
rig preset, standing in for the technician.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from viscorig.errors import InputError, InstrumentError
from viscorig.sequences import (
    Channels,
    PromptStep,
    Sensitivities,
    Sequence,
    Station,
)

#: Preset mounted when a sequence names no simulated rig.
DEFAULT_PRESET = "table"
#: The virtual analyser's source can give 5 V; the shaker's gain and limit lower it.
SIMULATED_SOURCE_LIMIT_V = 5.0


@dataclass
class OpenStation:
    """A connected analyser and what the runner needs to know about it."""

    station: Station
    analyser: Any
    simulated: bool
    mount: Any = None
    instrument_errors: tuple[type[BaseException], ...] = ()


def instrument_errors() -> tuple[type[BaseException], ...]:
    """The driver's exception types that mean an instrument fault."""
    from agilent35670a import InstrumentError as DriverError
    from agilent35670a import SettingOutOfRange

    return (DriverError, SettingOutOfRange)


def _first_preset(sequence: Sequence) -> str:
    for step in sequence.steps:
        if isinstance(step, PromptStep) and step.simulated_rig:
            return step.simulated_rig
    return DEFAULT_PRESET


def check_presets(sequence: Sequence) -> None:
    """Every ``simulated_rig`` a sequence names is a shipped preset (before anything runs)."""
    from rigsim.rigfile import preset_names

    known = set(preset_names())
    for index, step in enumerate(sequence.steps):
        if isinstance(step, PromptStep) and step.simulated_rig and step.simulated_rig not in known:
            raise InputError(
                f"{step.simulated_rig!r} is not a simulated rig preset "
                f"(known: {', '.join(sorted(known))})",
                f"{sequence.source}: steps[{index}].simulated_rig",
            )


@contextlib.contextmanager
def simulated_station(sequence: Sequence, pace: float | None = None) -> Iterator[OpenStation]:
    """The embedded simulated rig: a virtual 35670A on loopback, through the real driver.

    The station's transducers, shaker gain and force limit are those of the first preset the
    sequence mounts (every shipped preset has the same ones).
    """
    from agilent35670a import Agilent35670A
    from rigsim.rigfile import load_preset
    from rigsim.server import SimulatedAnalyserServer

    check_presets(sequence)
    preset = _first_preset(sequence)
    rig = load_preset(preset)
    server = SimulatedAnalyserServer(rig, pace=pace)
    server.start()
    try:
        errors = instrument_errors()
        try:
            analyser = Agilent35670A.open(server.socket_resource, timeout_s=5.0)
        except errors as error:
            raise InstrumentError(f"simulated analyser: {error}") from None
        sensors = rig.sensors
        station = Station(
            resource=server.socket_resource,
            channels=Channels(excitation_force=1, table_acceleration=2, device_force=3,
                              device_acceleration=4),
            sensitivity=Sensitivities(
                excitation_force_v_per_n=sensors.force_v_per_n,
                table_acceleration_v_per_m_s2=sensors.acceleration_v_per_m_s2,
                device_force_v_per_n=sensors.force_v_per_n,
                device_acceleration_v_per_m_s2=sensors.acceleration_v_per_m_s2,
            ),
            shaker_force_limit_n=rig.shaker.force_limit_n,
            shaker_gain_n_per_v=rig.shaker.force_n_per_v,
            source_limit_v=SIMULATED_SOURCE_LIMIT_V,
            source="embedded simulated rig",
        )
        try:
            yield OpenStation(station, analyser, True, server.analyser.mount, errors)
        finally:
            with contextlib.suppress(Exception):
                analyser.close()
    finally:
        server.close()


@contextlib.contextmanager
def lab_station(station: Station) -> Iterator[OpenStation]:
    """The analyser a station file names (GPIB, a Prologix adapter, or a socket)."""
    from agilent35670a import Agilent35670A

    errors = instrument_errors()
    try:
        analyser = Agilent35670A.open(station.resource, adapter=station.adapter)
    except errors as error:
        raise InstrumentError(f"cannot reach the analyser: {error}") from None
    try:
        yield OpenStation(station, analyser, False, None, errors)
    finally:
        with contextlib.suppress(Exception):
            analyser.close()

