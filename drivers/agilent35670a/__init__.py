"""Driver for the Agilent (HP) 35670A dynamic signal analyser: swept sine and FFT.

Built on pyvisa; imports nothing of ``viscorig`` or ``rigsim``. The authority is the 35670A's
programming guide; what it leaves open is in :class:`Quirks`.

The driver knows no rig: which transducer is on which input (labels, sensitivities), which
input the auto level holds, the ``REF`` pairing and which ratio is which accelerance are the
caller's, passed as arguments. viscorig keeps that wiring in
:class:`viscorig.acquisition.sweep.Wiring`.

>>> from agilent35670a import Agilent35670A
>>> with Agilent35670A.open("GPIB0::11::INSTR") as analyser:      # doctest: +SKIP
...     analyser.configure_swept_sine(
...         inputs=[(1, "N", 0.01124), (2, "M/S2", 0.0102), (3, "N", 0.01124),
...                 (4, "M/S2", 0.0102)],
...         reference_channel=4, reference_level_eu=2.0, source_limit_vpk=1.0)
...     segment = analyser.measure(10.0, 60.0)
...     points = analyser.measure_points([12.5, 19.3, 40.0], settle_cycles=20,
...                                      integrate_cycles=50)

Modules, each with one job:

============  ================================================================================
instrument    :class:`Agilent35670A`: its parts put together, one call per measurement
channels      :class:`InputChannel`: coupling, range, engineering units of one input
swept_sine    the swept sine's band, grid, manual frequency, settle and integration
source        source level, limits and auto level; the FFT source
fft           FFT span, lines, window, averaging
traces        data format, feeds, reading traces (the no-data marker becomes NaN)
status        error queue, status registers
running       start a measurement and wait for it (polling, deadline, pause, abort)
properties    declarative settings (validated, written, read back) and the part base class
connection    pyvisa resources: GPIB, Prologix adapters, sockets; time-outs, one safe retry
blocks        decoding and checking of data replies
segment       what a measurement returns
errors        the driver's exceptions
quirks        what the manual leaves open
scripted      a recording SCPI test server (for protocol tests and benchmarks)
============  ================================================================================
"""

from .channels import TRANSDUCER_LABELS, InputChannel, InputSetting
from .connection import IDEMPOTENT_QUERIES, Connection
from .errors import (
    ConnectionLost,
    InstrumentError,
    InstrumentTimeout,
    MalformedReply,
    MeasurementAborted,
    MissingOption,
    SCPIError,
    SettingNotApplied,
    SettingOutOfRange,
    WrongInstrument,
)
from .instrument import Agilent35670A
from .quirks import Quirks
from .segment import Spectra, SweepProgress, SweepSegment
from .traces import check_feed

__all__ = [
    "IDEMPOTENT_QUERIES",
    "TRANSDUCER_LABELS",
    "Agilent35670A",
    "Connection",
    "ConnectionLost",
    "InputChannel",
    "InputSetting",
    "InstrumentError",
    "InstrumentTimeout",
    "MalformedReply",
    "MeasurementAborted",
    "MissingOption",
    "Quirks",
    "SCPIError",
    "SettingNotApplied",
    "SettingOutOfRange",
    "Spectra",
    "SweepProgress",
    "SweepSegment",
    "WrongInstrument",
    "check_feed",
]
