"""The virtual Agilent 35670A: settings, status, swept-sine and FFT measurements, traces.

:class:`VirtualAnalyser` holds what the instrument holds (modes and their settings, inputs,
source, traces, data registers, status registers, error queue) and measures a rig simulator
(``rigsim.engine.RigSimulator``): swept sine through the simulator's volts-only interface
(:mod:`rigsim.measurement`), FFT by simulating the rig in the time domain. :class:`ScpiSession`
is one controller's connection to it (its own parser path and output), so a socket server and
in-process code can share one instrument.

The authority is the 35670A's programming guide; behaviour it does not give is marked
**(inferred)** where it is implemented. ``docs/virtual-analyser.md`` lists each subsystem as
measured, accepted as state, or not simulated.

In-process control (not SCPI; the instrument has no such command): :meth:`VirtualAnalyser.mount`
swaps the specimens on the simulated rig between sweeps, as a technician does when a sequence
prompt says "mount the soft specimens"; ``front_end`` is the wiring between rig and inputs, where
wiring faults are injected (:mod:`rigsim.faults`).

Modules, each with one job:

============  ================================================================================
instrument    :class:`VirtualAnalyser`, the parts put together; the in-process API
session       :class:`ScpiSession`, one controller's connection (parsing, ``*OPC?``, ``*WAI``)
host          what commands need of the instrument (a protocol: no import cycle)
commands/     the command set, one module per group of subsystems
settings      declarative settings: kinds, units, limits, presets, scopes, modes, options
units         amplitude units (``DBVRMS``, ``VPK``, ``EU`` ...) and their conversions
status        the error queue and the status registers
run           the measurement thread: start, pause, abort, pacing
sine          the swept-sine measurement
fft           the FFT measurement (the rig in the time domain, windows, averaging)
frequency     frequency rounding, swept-sine point lists, FFT spans
inputs        the inputs as the measurements see them (on/off, ranges, units)
traces        feeds, trace data, display formats, data encoding
limits        identity, limits, timings
============  ================================================================================
"""

from rigsim.analyser.instrument import VirtualAnalyser, build_simulator
from rigsim.analyser.limits import DEFAULT_IDN, DEFAULT_OPTIONS, MARKER, MAX_POINTS
from rigsim.analyser.run import Simulator
from rigsim.analyser.session import ScpiSession
from rigsim.analyser.traces import Feed, Register, parse_feed

__all__ = [
    "DEFAULT_IDN",
    "DEFAULT_OPTIONS",
    "MARKER",
    "MAX_POINTS",
    "Feed",
    "Register",
    "ScpiSession",
    "Simulator",
    "VirtualAnalyser",
    "build_simulator",
    "parse_feed",
]
