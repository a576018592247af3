"""The analyser's command set, one module per group of subsystems.

Each module has ``register(tree, analyser)``: its part of the command table, headers written in
the manual's long form (``[SENSe:]FREQuency:STARt``; ``#`` marks a numeric suffix such as
``CALC3``). Plain settings are declared in tables (:mod:`rigsim.analyser.commands.table`);
settings that round, couple or act have their own handlers.

==========  ==================================================================================
module      subsystems (programming guide chapter)
==========  ==================================================================================
common      common commands (3), ``SYSTem`` (21), ``STATus`` (20)
running     ``ABORt`` (4), ``INITiate`` (11), ``CALibration`` (7)
sense       ``INSTrument`` (13), ``[SENSe:]`` (18), ``ARM`` (5), ``TRIGger`` (24)
inputs      ``INPut`` (12), ``[SENSe:]VOLTage`` (18)
source      ``OUTPut`` (16), ``SOURce`` (19)
calculate   ``CALCulate`` (6)
display     ``DISPlay`` (8)
traces      ``TRACe`` (23), ``FORMat`` (9)
==========  ==================================================================================
"""

from rigsim.analyser.commands import (
    calculate,
    common,
    display,
    inputs,
    running,
    sense,
    source,
    traces,
)
from rigsim.analyser.host import Host
from rigsim.scpi import CommandTree

__all__ = ["register_all"]


def register_all(tree: CommandTree, analyser: Host) -> None:
    """The whole command set of the virtual 35670A."""
    for module in (common, running, sense, inputs, source, traces, calculate, display):
        module.register(tree, analyser)
