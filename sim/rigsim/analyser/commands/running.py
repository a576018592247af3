"""``ABORt`` (chapter 4), ``INITiate`` (11) and ``CALibration`` (7)."""

from __future__ import annotations

from rigsim.analyser.commands.table import boolean, declare
from rigsim.analyser.host import Host
from rigsim.analyser.settings import Spec, one
from rigsim.scpi import Call, CommandTree, ScpiError, format_int, parse_bool

__all__ = ["register"]


def register(tree: CommandTree, a: Host) -> None:
    """Register ``ABOR``, ``INIT`` and ``CAL``."""
    tree.add("ABORt", setter=lambda c: a.abort())
    tree.add("INITiate[:IMMediate]", setter=lambda c: a.initiate())
    declare(tree, a.store, [
        ("INITiate:CONTinuous", "init.cont", boolean(True, rst=False)),
    ], after=lambda name, value, index: a.set_continuous(bool(value)))
    tree.add("CALibration[:ALL]", query=lambda c: (a.calibrate_now(), format_int(0))[1])
    a.store.define("cal.auto", Spec("bool", True, rst=False))

    def set_auto(call: Call) -> None:
        word = one(call).strip().upper()
        if word == "ONCE":
            a.calibrate_now()
            return
        try:
            value = parse_bool(word)
        except ScpiError:
            raise ScpiError(-141, f"{word[:20]} is not one of OFF|0|ON|1|ONCE") from None
        a.store.set("cal.auto", value)
        a.settings_changed("cal.auto")

    tree.add("CALibration:AUTO", setter=set_auto,
             query=lambda c: format_int(int(bool(a.store.get("cal.auto")))))
