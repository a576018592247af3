"""Opening a station for ``viscorig run`` and the bench: the lab's analyser or the simulated rig.

This is the one place where the driver (``agilent35670a``) and the simulator (``rigsim``) meet
the core. The embedded rig is a virtual 35670A served on 127.0.0.1 (a free port) and reached
through the real driver over pyvisa-py (``TCPIP::127.0.0.1::<port>::SOCKET``), exactly as a lab
analyser behind a socket would be; sequence prompts with ``simulated_rig = "..."`` mount that
rig preset, standing in for the technician.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

from viscorig.acquisition.chamber import ChamberMonitor
from viscorig.acquisition.console import single_line
from viscorig.acquisition.holds import standard_conditions
from viscorig.acquisition.session import RunnerOptions
from viscorig.errors import InstrumentError
from viscorig.sequences import (
    ChamberStation,
    Channels,
    FileCheckError,
    Problem,
    PromptStep,
    Sensitivities,
    Sequence,
    SpecimenGeometry,
    Station,
    SweepStep,
)
from viscorig.sequences.problems import Problems, did_you_mean

#: Preset mounted when a sequence names no simulated rig.
DEFAULT_PRESET = "table"
#: A sweep's hardness matches a preset's within this, Shore A.
HARDNESS_MATCH_SHORE_A = 0.5
#: A sweep's preload strain matches a preset's within this.
PRELOAD_MATCH = 0.005
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
    chamber: Any = None
    """The chamber (:class:`viscorig.acquisition.chamber.ChamberMonitor`), if any."""
    server: Any = None
    """The embedded simulated analyser's server (its ``faults``), None for a lab station."""


def instrument_errors() -> tuple[type[BaseException], ...]:
    """The driver's exception types that mean an instrument fault."""
    from agilent35670a import InstrumentError as DriverError
    from agilent35670a import SettingOutOfRange

    return (DriverError, SettingOutOfRange)


def not_answering_errors() -> tuple[type[BaseException], ...]:
    """The driver's exception types that mean the analyser stopped answering (a timeout, a
    connection lost): an automatic hold waits for it to answer again."""
    from agilent35670a.errors import ConnectionLost, InstrumentTimeout

    return (InstrumentTimeout, ConnectionLost)


def station_holds(opened: OpenStation, bench: Any = None) -> list[Any]:
    """The automatic holds of an open station: its ``[bench]`` settings (or ``bench``), the
    analyser's identity query to see it answer again, and the chamber's thermometer if any. The
    bench page and ``viscorig run --holds`` use these same conditions."""
    station = opened.station
    return standard_conditions(bench or station.bench, station.shaker_force_limit_n,
                               opened.analyser.identify, not_answering_errors(),
                               opened.chamber)


#: The embedded rig's chamber limits and safe set point, °C.
EMBEDDED_CHAMBER_LIMITS_C = (-40.0, 100.0)
EMBEDDED_SAFE_SET_POINT_C = 25.0
#: The embedded rig's controllers show hundredths of a kelvin: at -20 °C the medium rubber
#: shifts by 0.1 decade per kelvin, so tenths would cost up to 0.005 decade of shift factor.
EMBEDDED_DECIMALS = 2


def _chamber_parameters(sequence: Sequence):
    """The simulated chamber of the first preset the sequence mounts that has one (else the
    simulator's default chamber)."""
    from rigsim.chamber import ChamberParameters
    from rigsim.rigfile import load_preset, preset_names

    names = set(preset_names())
    for step in sequence.steps:
        if isinstance(step, PromptStep) and step.simulated_rig in names:
            chamber = load_preset(step.simulated_rig).chamber
            if chamber is not None:
                return chamber
    return ChamberParameters()


def embedded_chamber_station(sequence: Sequence) -> ChamberStation:
    """The ``[chamber]`` of the embedded simulated rig for a sequence."""
    parameters = _chamber_parameters(sequence)
    low, high = EMBEDDED_CHAMBER_LIMITS_C
    return ChamberStation(address="tcp://127.0.0.1:502", low_limit_c=low, high_limit_c=high,
                          safe_set_point_c=EMBEDDED_SAFE_SET_POINT_C, unit=1, specimen_unit=2,
                          decimals=EMBEDDED_DECIMALS,
                          specimen_time_constant_s=parameters.specimen_time_constant_s,
                          heating_rate_k_per_min=parameters.heating_rate_k_per_min,
                          cooling_rate_k_per_min=parameters.cooling_rate_k_per_min)


def chamber_errors() -> tuple[type[BaseException], ...]:
    """The chamber driver's exception types that mean an instrument fault."""
    from eurotherm3200 import ChamberError

    return (ChamberError,)


def open_chamber(chamber: ChamberStation, address: str | None = None,
                 pass_time: Any = None) -> Any:
    """Connect the chamber's controller: a :class:`~viscorig.acquisition.chamber.ChamberMonitor`.

    Raises
    ------
    InstrumentError
        The controller cannot be reached.
    """
    from eurotherm3200 import ChamberError, Eurotherm3200

    try:
        controller = Eurotherm3200.open(
            address or chamber.address, unit=chamber.unit, specimen_unit=chamber.specimen_unit,
            limits_c=(chamber.low_limit_c, chamber.high_limit_c), baudrate=chamber.baudrate,
            decimals=chamber.decimals)
    except (ChamberError, ValueError) as error:
        raise InstrumentError(f"cannot reach the chamber: {single_line(str(error))}") from None
    return ChamberMonitor(controller, chamber, pass_time, (ChamberError,))


def _specimen_geometry(sequence: Sequence) -> SpecimenGeometry | None:
    """The specimens' geometry of the first preset the sequence mounts that gives it all."""
    from rigsim.rigfile import load_preset, preset_names

    names = set(preset_names())
    for step in sequence.steps:
        if isinstance(step, PromptStep) and step.simulated_rig in names:
            specimen = load_preset(step.simulated_rig).specimen
            diameter_m, height_m, count = specimen.diameter_m, specimen.height_m, specimen.count
            if diameter_m is not None and height_m is not None and count is not None:
                return SpecimenGeometry(diameter_m, height_m, count)
    return None


def _first_preset(sequence: Sequence) -> str:
    for step in sequence.steps:
        if isinstance(step, PromptStep) and step.simulated_rig:
            return step.simulated_rig
    return DEFAULT_PRESET


@dataclass(frozen=True)
class _Mounting:
    """A preset mounted by a prompt, and the first run measured on it."""

    preset: str
    prompt: int | None
    """Step index of the prompt that mounted it (None: mounted when the rig started)."""
    rig: Any
    first_run: SweepStep | None = None


def _describe_rig(rig: Any) -> str:
    if rig.device is None:
        return "no specimens"
    specimen = rig.specimen
    hardness = ("" if specimen.hardness_shore_a is None
                else f"{specimen.hardness_shore_a:g} Shore A, ")
    return f"{hardness}preload {specimen.preload_strain or 0.0:g}"


def _describe_step(step: SweepStep) -> str:
    if step.bare_table:
        return "the bare table"
    hardness = "" if math.isnan(step.hardness_shore_a) else f"{step.hardness_shore_a:g} Shore A, "
    return f"specimen {step.specimen!r}, {hardness}preload {step.preload_strain:g}"


def _fits(rig: Any, step: SweepStep) -> bool:
    """Does a preset hold what the sweep step says is mounted?"""
    if step.bare_table or rig.device is None:
        return step.bare_table and rig.device is None
    hardness = rig.specimen.hardness_shore_a
    if not math.isnan(step.hardness_shore_a) and hardness is not None and abs(
            hardness - step.hardness_shore_a) > HARDNESS_MATCH_SHORE_A:
        return False
    return abs((rig.specimen.preload_strain or 0.0) - step.preload_strain) <= PRELOAD_MATCH


def simulated_rig_problems(sequence: Sequence, text: str = "") -> list[Problem]:
    """Every sweep of a sequence that the embedded simulated rig would measure on the wrong rig.

    Walks the steps as the runner mounts presets (a prompt's ``simulated_rig``; the bare table
    before any), and finds: a preset name that is not shipped; a bare-table run on a rig with
    specimens; a specimen run with no specimens mounted (it would measure the bare table under
    its name); a specimen whose hardness or preload differs from the preset's; a run of another
    specimen than the one measured before on the same mounting (a prompt asked the operator to
    change it, but named no preset). Each problem names the preset that fits.

    Parameters
    ----------
    sequence
        A valid sequence.
    text
        Its TOML text, for line numbers.
    """
    from rigsim.rigfile import load_preset, preset_names

    problems = Problems(sequence.source, text)
    presets = {name: load_preset(name) for name in preset_names()}
    mounted: _Mounting | None = _Mounting(DEFAULT_PRESET, None, presets[DEFAULT_PRESET])
    last_prompt: int | None = None
    for index, step in enumerate(sequence.steps):
        if isinstance(step, PromptStep):
            last_prompt = index
            if step.simulated_rig is None:
                continue
            if step.simulated_rig not in presets:
                problems.add(("steps", index, "simulated_rig"),
                             f"{step.simulated_rig!r} is not a simulated rig preset (known: "
                             f"{', '.join(presets)})", did_you_mean(step.simulated_rig, presets))
                mounted = None  # unknown from here on until the next preset
            else:
                mounted = _Mounting(step.simulated_rig, index, presets[step.simulated_rig])
            continue
        if not isinstance(step, SweepStep) or mounted is None:
            continue
        wrong = _wrong_rig(step, mounted, last_prompt)
        if wrong is not None:
            word = step.specimen.lower()
            fitting = sorted((name for name, rig in presets.items() if _fits(rig, step)),
                             key=lambda name: word not in f"{name} {presets[name].description}"
                             .lower())
            problems.add(("steps", index, "run"), wrong, _fix(fitting, last_prompt))
        elif mounted.first_run is None:
            mounted = _Mounting(mounted.preset, mounted.prompt, mounted.rig, step)
    return problems.items


def _wrong_rig(step: SweepStep, mounted: _Mounting, last_prompt: int | None) -> str | None:
    """Why ``step`` cannot be measured on the mounted preset, or None."""
    where = ("mounted when the rig starts" if mounted.prompt is None
             else f"mounted at steps[{mounted.prompt}]")
    rig_text = f"the simulated rig {mounted.preset!r} ({_describe_rig(mounted.rig)}, {where})"
    if not _fits(mounted.rig, step):
        if not step.bare_table and mounted.rig.device is None:
            return (f"run {step.run!r} ({_describe_step(step)}) would measure the bare table "
                    f"under its name: no simulated rig with specimens is mounted before it")
        return f"run {step.run!r} ({_describe_step(step)}) does not match {rig_text}"
    first = mounted.first_run
    changed = first is not None and (
        first.specimen != step.specimen
        or not _same_number(first.hardness_shore_a, step.hardness_shore_a))
    if changed and first is not None and last_prompt is not None and (mounted.prompt is None
                                               or last_prompt > mounted.prompt):
        return (f"run {step.run!r} ({_describe_step(step)}) would be measured on {rig_text}, "
                f"which run {first.run!r} measured as specimen {first.specimen!r}: the prompt "
                f"at steps[{last_prompt}] names no simulated_rig")
    return None


def _same_number(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


def _fix(fitting: list[str], last_prompt: int | None) -> str:
    if not fitting:
        return "no shipped preset holds that specimen: correct the step, or run it with --station"
    names = " or ".join(f'simulated_rig = "{name}"' for name in fitting[:3])
    if last_prompt is None:
        return f"add a prompt step with {names} before it"
    return f"add {names} to the prompt at steps[{last_prompt}]"


def check_presets(sequence: Sequence, text: str = "") -> None:
    """The embedded simulated rig can measure every sweep as written (before anything runs).

    Raises
    ------
    FileCheckError
        Every problem :func:`simulated_rig_problems` finds.
    """
    problems = simulated_rig_problems(sequence, text)
    if problems:
        raise FileCheckError(problems)


@contextlib.contextmanager
def simulated_station(sequence: Sequence, pace: float | None = None,
                      seed: int | None = None) -> Iterator[OpenStation]:
    """The embedded simulated rig: a virtual 35670A on loopback, through the real driver; its
    noise from ``seed`` (None: fresh noise).

    Check the sequence with :func:`check_presets` first. The station's transducers, shaker
    gain and force limit are those of the first preset the sequence mounts (every shipped
    preset has the same ones); the rig starts bare, and prompts mount the presets they name.
    """
    from agilent35670a import Agilent35670A
    from rigsim.rigfile import load_preset
    from rigsim.server import SimulatedAnalyserServer

    rig = load_preset(_first_preset(sequence))
    # the rig starts bare: prompts mount the presets they name (simulated_rig_problems)
    server = SimulatedAnalyserServer(load_preset(DEFAULT_PRESET), pace=pace, seed=seed)
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
            specimen=_specimen_geometry(sequence),
            source="embedded simulated rig",
        )
        with contextlib.ExitStack() as stack:
            chamber = None
            if sequence.soaks:
                chamber = stack.enter_context(_embedded_chamber(sequence, server, pace))
                station = replace(station, chamber=chamber.station)
                errors = (*errors, *chamber_errors())
            try:
                yield OpenStation(station, analyser, True, server.analyser.mount, errors,
                                  chamber, server=server)
            finally:
                with contextlib.suppress(Exception):
                    analyser.close()
    finally:
        server.close()


@contextlib.contextmanager
def _embedded_chamber(sequence: Sequence, server: Any, pace: float | None) -> Iterator[Any]:
    """The simulated chamber around the embedded rig's specimens: its controller served on
    loopback (Modbus TCP) and reached through the real driver; time passes on the rig's clock
    (really only at ``pace``)."""
    from rigsim.chamber import Chamber
    from rigsim.chamber_server import ChamberServer

    chamber = Chamber(_chamber_parameters(sequence))
    analyser = server.analyser
    analyser.simulator.attach_chamber(chamber, advance=True)
    paced_until = [0.0]  # the wall-clock instant the paced simulated time has reached

    def pass_time(seconds: float) -> None:
        with analyser.lock:
            analyser.simulator.idle(seconds)
        if pace is not None:  # against a deadline, so that the polling's own work is absorbed
            now = time.monotonic()
            paced_until[0] = max(paced_until[0], now) + seconds / pace
            time.sleep(max(paced_until[0] - now, 0.0))

    with ChamberServer(chamber, controller_unit=1, specimen_unit=2,
                       decimals=EMBEDDED_DECIMALS) as chamber_server:
        monitor = open_chamber(embedded_chamber_station(sequence), chamber_server.address,
                               pass_time)
        try:
            yield monitor
        finally:
            with contextlib.suppress(Exception):
                monitor.controller.close()


@contextlib.contextmanager
def lab_station(station: Station) -> Iterator[OpenStation]:
    """The analyser a station file names (GPIB, a Prologix adapter, or a socket)."""
    from agilent35670a import Agilent35670A

    errors = instrument_errors()
    try:
        analyser = Agilent35670A.open(station.resource, adapter=station.adapter)
    except errors as error:
        raise InstrumentError(f"cannot reach the analyser: {single_line(str(error))}") from None
    try:
        chamber = None
        if station.chamber is not None:
            chamber = open_chamber(station.chamber)
            errors = (*errors, *chamber_errors())
        try:
            yield OpenStation(station, analyser, False, None, errors, chamber)
        finally:
            if chamber is not None:
                with contextlib.suppress(Exception):
                    chamber.controller.close()
    finally:
        with contextlib.suppress(Exception):
            analyser.close()


@contextlib.contextmanager
def open_station(sequence: Sequence, station, pace: float | None, seed: int | None = None):
    """The station a sequence runs on: the lab's (a station file), else the embedded
    simulated rig (at ``pace`` simulated seconds per second, None: as fast as it can; its noise
    from ``seed``, None: fresh)."""
    if station is None:
        with simulated_station(sequence, pace, seed) as opened:
            yield opened
    else:
        with lab_station(station) as opened:
            yield opened


def runner_options(opened, over_limit: str | None) -> RunnerOptions:
    """How a sequence runs on an open station (the simulated rig's clock is test time)."""
    simulated = opened.simulated
    return RunnerOptions(
        simulated=simulated,
        time_base="test" if simulated else "wall",
        real_time_waits=not simulated,
        over_limit=over_limit,
        poll_interval_s=0.2,
        mount=opened.mount,
        instrument_errors=opened.instrument_errors,
        chamber=opened.chamber,
    )
