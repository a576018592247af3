"""The analyser's command set, one module per SCPI subsystem.

Each module holds a mixin of :class:`rigsim.analyser.worker.SweepWorker` with the subsystem's
handlers and a ``_register_*_commands(tree)`` method: its part of the command table, one
``tree.add(header, setter=..., query=...)`` row per command, headers in the manual's long form
(``[SENSe:]FREQuency:STARt``; ``#`` marks a numeric suffix such as ``INP2``).

============  ================================================================================
module        subsystems
============  ================================================================================
common        ``*IDN *OPT *RST *CLS *ESE *ESR *SRE *STB *TST *CAL *OPC *TRG``, ``SYSTem``,
              ``STATus``
sense         ``INSTrument`` (mode), ``[SENSe:]FREQuency``, ``SWEep``, ``REFerence``,
              ``WINDow``, ``AVERage``, ``TRIGger``
inputs        ``INPut#``, ``[SENSe:]VOLTage#`` (ranges, engineering units)
source        ``OUTPut``, ``SOURce:VOLTage`` (level, limits, auto level)
traces        ``CALCulate#``, ``TRACe`` (data registers), ``FORMat``
running       ``ABORt``, ``INITiate``
============  ================================================================================
"""

from rigsim.analyser.commands.common import CommonCommands
from rigsim.analyser.commands.inputs import InputCommands
from rigsim.analyser.commands.running import RunCommands
from rigsim.analyser.commands.sense import SenseCommands
from rigsim.analyser.commands.source import SourceCommands
from rigsim.analyser.commands.traces import TraceCommands

__all__ = [
    "CommonCommands",
    "InputCommands",
    "RunCommands",
    "SenseCommands",
    "SourceCommands",
    "TraceCommands",
]
