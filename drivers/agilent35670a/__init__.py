"""Driver for the Agilent (HP) 35670A dynamic signal analyser in swept-sine mode.

Built on pyvisa; imports nothing of ``viscorig`` or ``rigsim``. Facts about the instrument:
``shared/docs/35670a.md``.

>>> from agilent35670a import Agilent35670A
>>> with Agilent35670A.open("GPIB0::11::INSTR") as analyser:      # doctest: +SKIP
...     analyser.configure_swept_sine(sensitivities_v_per_eu={1: 0.01124, 2: 0.0102,
...                                   3: 0.01124, 4: 0.0102}, level_m_per_s2=2.0,
...                                   source_limit_vpk=1.0)
...     segment = analyser.measure(10.0, 60.0)
"""

from .channel import TRANSDUCER_LABELS, InputChannel
from .connection import IDEMPOTENT_QUERIES, Connection
from .errors import (
    ConnectionLost,
    InstrumentError,
    InstrumentTimeout,
    MalformedReply,
    MeasurementAborted,
    MissingOption,
    SCPIError,
    SettingOutOfRange,
    WrongInstrument,
)
from .instrument import Agilent35670A
from .quirks import Quirks
from .segment import SweepProgress, SweepSegment

__all__ = [
    "IDEMPOTENT_QUERIES",
    "TRANSDUCER_LABELS",
    "Agilent35670A",
    "Connection",
    "ConnectionLost",
    "InputChannel",
    "InstrumentError",
    "InstrumentTimeout",
    "MalformedReply",
    "MeasurementAborted",
    "MissingOption",
    "Quirks",
    "SCPIError",
    "SettingOutOfRange",
    "SweepProgress",
    "SweepSegment",
    "WrongInstrument",
]
