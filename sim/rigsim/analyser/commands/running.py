"""``ABORt`` and ``INITiate``: start, pause, resume and stop the measurement."""

from __future__ import annotations

from rigsim.analyser.params import Params, one
from rigsim.analyser.worker import SweepWorker
from rigsim.scpi import CommandTree, format_bool, parse_bool

__all__ = ["RunCommands"]


class RunCommands(SweepWorker):
    """Handlers of ``ABORt`` and ``INITiate`` (a base of the analyser)."""

    def _register_run_commands(self, t: CommandTree) -> None:
        t.add("ABORt", setter=lambda p, s: self._abort())
        t.add("INITiate[:IMMediate]", setter=lambda p, s: self._initiate())
        t.add("INITiate:CONTinuous", setter=self._continuous,
              query=lambda p, s: format_bool(self.continuous))

    def _continuous(self, params: Params, suffix: int | None) -> None:
        # In swept sine, INIT:CONT OFF pauses and ON resumes a sweep in progress; a finished
        # sweep is not restarted (inferred).
        on = parse_bool(one(params))
        self.continuous = on
        if on:
            self._resume()
        else:
            self._pause()
