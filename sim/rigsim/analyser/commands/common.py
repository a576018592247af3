"""Common ``*`` commands, ``SYSTem`` and ``STATus``: identity, resets, errors, status registers.

``*OPC?`` and ``*WAI`` wait outside the instrument lock, so the controller's connection handles
them (:class:`rigsim.analyser.session.ScpiSession`); ``*OPC`` is here.
"""

from __future__ import annotations

from collections.abc import Callable

from rigsim.analyser.params import Params, integer
from rigsim.analyser.state import MeasuredPoints
from rigsim.analyser.worker import SweepWorker
from rigsim.scpi import CommandTree, format_int

__all__ = ["CommonCommands"]


class CommonCommands(SweepWorker):
    """Handlers of the common commands, ``SYSTem`` and ``STATus`` (a base of the analyser)."""

    idn: str

    def _register_common_commands(self, t: CommandTree) -> None:
        t.add("*IDN", query=lambda p, s: self.idn)
        t.add("*OPT", query=lambda p, s: ",".join(self.options) or "0")
        t.add("*RST", setter=lambda p, s: self._reset(preset=False))
        t.add("*CLS", setter=lambda p, s: self.status.clear())
        t.add("*ESE", setter=lambda p, s: setattr(self.status, "ese", integer(p, 0, 255)),
              query=lambda p, s: format_int(self.status.ese))
        t.add("*ESR", query=lambda p, s: format_int(self.status.read_esr()))
        t.add("*SRE", setter=lambda p, s: setattr(self.status, "sre", integer(p, 0, 255) & ~64),
              query=lambda p, s: format_int(self.status.sre))
        t.add("*STB", query=lambda p, s: format_int(self.status.status_byte()))
        t.add("*TST", query=lambda p, s: format_int(0))
        t.add("*CAL", query=lambda p, s: format_int(0))
        t.add("*OPC", setter=lambda p, s: self.status.operation_complete(idle=self.state == "IDLE"))
        t.add("*TRG", setter=lambda p, s: self._forbid_in_sine("*TRG"))
        t.add("SYSTem:ERRor[:NEXT]", query=lambda p, s: self.status.next_error())
        t.add("SYSTem:PRESet", setter=lambda p, s: self._reset(preset=True))
        t.add("SYSTem:VERSion", query=lambda p, s: "1992.0")

    def _register_status_commands(self, t: CommandTree) -> None:
        t.add("STATus:OPERation:CONDition", query=lambda p, s: format_int(self.oper_condition()))
        t.add("STATus:OPERation[:EVENt]", query=self._read_event("oper_event"))
        t.add("STATus:OPERation:ENABle", setter=self._enable("oper_enable"),
              query=lambda p, s: format_int(self.status.oper_enable))
        t.add("STATus:QUEStionable:CONDition", query=lambda p, s: format_int(
            1 if self._volt_condition() & self.status.volt_enable else 0))
        t.add("STATus:QUEStionable[:EVENt]", query=self._read_event("ques_event"))
        t.add("STATus:QUEStionable:ENABle", setter=self._enable("ques_enable"),
              query=lambda p, s: format_int(self.status.ques_enable))
        t.add("STATus:QUEStionable:VOLTage:CONDition", query=lambda p, s: format_int(
            self._volt_condition()))
        t.add("STATus:QUEStionable:VOLTage[:EVENt]", query=self._read_event("volt_event"))
        t.add("STATus:QUEStionable:VOLTage:ENABle", setter=self._enable("volt_enable"),
              query=lambda p, s: format_int(self.status.volt_enable))
        t.add("STATus:PRESet", setter=lambda p, s: self.status.preset())

    def _reset(self, preset: bool) -> None:
        """``*RST`` (preset False) or ``SYST:PRES`` (preset True): any sweep stops."""
        self._abort()
        self._reset_settings(preset)
        self._measured = MeasuredPoints(0)

    def _read_event(self, name: str) -> Callable[..., str]:
        return lambda p, s: format_int(self.status.read_event(name))

    def _enable(self, name: str) -> Callable[..., None]:
        def setter(params: Params, suffix: int | None) -> None:
            setattr(self.status, name, integer(params, 0, 65535))
        return setter
