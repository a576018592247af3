"""The virtual Agilent 35670A: instrument state, command set, status registers, measurement.

:class:`VirtualAnalyser` holds what the instrument holds (modes and their settings, inputs,
source, traces, data registers, status registers, error queue) and runs swept-sine
measurements on a rig simulator (``rigsim.engine.RigSimulator``) in a background worker, through
the volts-only interface of :mod:`rigsim.measurement`. It converts volts to engineering units
per channel and forms the traces. :class:`ScpiSession` is one controller's connection to it
(its own parser path and output), so a socket server and in-process code can share one
instrument.

The command set follows ``shared/docs/35670a.md``. Behaviour marked **(inferred)** in comments
and docstrings is our reading where that page and the manual are silent; keep it easy to change.

Not simulated, on purpose and visibly: FFT, octave, order and histogram measurements (``INIT``
outside swept sine answers -221); the swept sine's automatic resolution (``FREQ:RES:AUTO ON``
still measures the fixed ``FREQ:RES`` grid, so always read the X axis); the source slew rate
(stored only). What the traces hold: :mod:`rigsim.analyser.traces`.

In-process control (not SCPI; the instrument has no such command): :meth:`VirtualAnalyser.mount`
swaps the specimens on the simulated rig between sweeps, as a technician does when a sequence
prompt says "mount the soft specimens".

Modules, each with one job:

============  ================================================================================
instrument    :class:`VirtualAnalyser`, the parts put together; the in-process API
session       :class:`ScpiSession`, one controller's connection (parsing, ``*OPC?``, ``*WAI``)
commands/     the command table and its handlers, one module per SCPI subsystem
worker        the swept-sine measurement thread: plan, pacing, pause, abort
state         settings per mode, inputs, source, registers, measured points; ``*RST`` presets
status        the error queue and the status registers
traces        feeds, traces in engineering units, display formats, ASCII and REAL blocks
params        parameter checks shared by the handlers (count, range, keywords, ``? UNIT``)
limits        the instrument's identity and setting ranges
============  ================================================================================
"""

from rigsim.analyser.instrument import VirtualAnalyser, build_simulator
from rigsim.analyser.limits import DEFAULT_IDN, DEFAULT_OPTIONS, MAX_POINTS
from rigsim.analyser.session import ScpiSession
from rigsim.analyser.state import Register
from rigsim.analyser.traces import Feed, parse_feed
from rigsim.analyser.worker import Simulator

__all__ = [
    "DEFAULT_IDN",
    "DEFAULT_OPTIONS",
    "MAX_POINTS",
    "Feed",
    "Register",
    "ScpiSession",
    "Simulator",
    "VirtualAnalyser",
    "build_simulator",
    "parse_feed",
]
