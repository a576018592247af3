"""``DISPlay`` (chapter 8): the screen's state. Nothing here changes a measurement; the
settings are kept and answered as the manual gives them (scales per trace and per mode)."""

from __future__ import annotations

from rigsim.analyser.commands.table import action, boolean, choice, declare, integer, real, text
from rigsim.analyser.host import Host
from rigsim.analyser.settings import Spec, check_option, one
from rigsim.scpi import Call, CommandTree, ScpiError, unquote

__all__ = ["register"]

_X_UNITS = ("HZ", "S", "ORD", "COUNT", "AVG", "V", "VPK", "RPM", "EU", "REV")
_Y_UNITS = ("DBVRMS", "VRMS", "VPK", "DBVPK", "V", "DBV", "EU", "DBEU")
_NO_WATERFALL = "No WATERFALL display with SWEPT SINE Instrument Mode."
_WATERFALL_MODES = frozenset({"FFT", "OCT", "ORD"})


def _x_preset(edge: str):
    def preset(mode: str, index: tuple[int, ...]) -> float:
        if edge == "LEFT":
            return 51.2 if mode == "SINE" else 0.0
        if mode == "SINE" or index[0] <= 2:
            return 51200.0
        return 7.805e-3
    return preset


_WINDOW = "DISPlay[:WINDow#]"


def register(tree: CommandTree, a: Host) -> None:
    """Register the ``DISPlay`` commands."""
    _display_settings(tree, a)
    _autoscale(tree, a)
    _actions(tree, a)


def _display_settings(tree: CommandTree, a: Host) -> None:
    """The stored display settings: format, view, each trace's scales and waterfall."""
    window = _WINDOW
    trace = {"scope": ("trace",)}
    scale = {"scope": ("trace", "mode")}
    wat = {"scope": ("trace",), "modes": _WATERFALL_MODES, "conflict": _NO_WATERFALL}
    declare(tree, a.store, [
        ("DISPlay:ANNotation[:ALL]", "disp.ann", boolean(True)),
        ("DISPlay:BRIGhtness", "disp.brig", real(1.0, 0.5, 1.0)),
        ("DISPlay:EXTernal[:STATe]", "disp.ext", boolean(False)),
        ("DISPlay:FORMat", "disp.form",
         choice("SING", "SINGle", "ULOWer", "FBACk", "SUBLower", "ULFB", "QUAD")),
        ("DISPlay:GPIB:ECHO", "disp.echo", boolean(False)),
        ("DISPlay:RPM[:STATe]", "disp.rpm", boolean(False)),
        ("DISPlay:SHOWall[:STATe]", "disp.show", boolean(False)),
        ("DISPlay:STATe", "disp.stat", boolean(True)),
        ("DISPlay:TCAPture:ENVelope[:STATe]", "disp.tcap.env", boolean(True)),
        ("DISPlay:VIEW", "disp.view",
         choice("TRAC", "TRACe", "MSTate", "MMEMory", "STABle", "CTABle", "FTABle", "TTABle",
                "MEMory", "OPTions", "CAPTure", "ISTate", "MESSage")),
        ("DISPlay:PROGram[:MODE]", "disp.prog",
         choice("OFF", "OFF", "FULL", "UPPer", "LOWer", option="1C2")),
        ("DISPlay:PROGram:VECTor:BUFFer[:STATe]", "disp.prog.buff",
         boolean(False, option="1C2")),
        (f"{window}:DTABle:MARKer[:STATe]", "disp.dtab.mark", boolean(False, **trace)),
        (f"{window}:DTABle[:STATe]", "disp.dtab", boolean(False, **trace)),
        (f"{window}:LIMit:STATe", "disp.lim", boolean(False, **trace)),
        (f"{window}:POLar:CLOCkwise", "disp.pol.cloc", boolean(False, **trace)),
        (f"{window}:POLar:ROTation", "disp.pol.rot", integer(0, -360, 360, **trace)),
        (f"{window}:TRACe:APOWer[:STATe]", "disp.apow", boolean(False, option="1D1", **trace)),
        (f"{window}:TRACe:BPOWer[:STATe]", "disp.bpow", boolean(False, option="1D1", **trace)),
        (f"{window}:TRACe:GRATicule:GRID[:STATe]", "disp.grid", boolean(True, **trace)),
        (f"{window}:TRACe:LABel", "disp.lab", text("", 13, **trace)),
        (f"{window}:TRACe:LABel:DEFault[:STATe]", "disp.lab.def", boolean(True, **trace)),
        (f"{window}:TRACe:X[:SCALe]:LEFT", "disp.x.left",
         real(_x_preset("LEFT"), -9.9e37, 9.9e37, _X_UNITS, **scale)),
        (f"{window}:TRACe:X[:SCALe]:RIGHt", "disp.x.right",
         real(_x_preset("RIGHT"), -9.9e37, 9.9e37, _X_UNITS, **scale)),
        (f"{window}:TRACe:X:SPACing", "disp.x.spac",
         choice("LIN", "LINear", "LOGarithmic", **scale)),
        (f"{window}:TRACe:Y[:SCALe]:BOTTom", "disp.y.bott",
         real(-100.0, -9.9e37, 9.9e37, _Y_UNITS, **scale)),
        (f"{window}:TRACe:Y[:SCALe]:CENTer", "disp.y.cent",
         real(-50.0, -9.9e37, 9.9e37, _Y_UNITS, **scale)),
        (f"{window}:TRACe:Y[:SCALe]:TOP", "disp.y.top",
         real(0.0, -9.9e37, 9.9e37, _Y_UNITS, **scale)),
        (f"{window}:TRACe:Y[:SCALe]:PDIVision", "disp.y.pdiv",
         real(10.0, 0.0, 9.9e37, ("DB", "VRMS", "VPK", "V"), **scale)),
        (f"{window}:TRACe:Y[:SCALe]:REFerence", "disp.y.ref",
         choice("RANG", "TOP", "CENTer", "BOTTom", "RANGe", **scale)),
        (f"{window}:TRACe:Y:SPACing", "disp.y.spac",
         choice("LIN", "LINear", "LOGarithmic", **scale)),
        (f"{window}:WATerfall:BASeline", "disp.wat.bas", integer(0, 0, 100, **wat)),
        (f"{window}:WATerfall:BOTTom", "disp.wat.bott", real(0.0, -9.9e37, 9.9e37, **wat)),
        (f"{window}:WATerfall:COUNt", "disp.wat.coun",
         real(15.0, 1.0, 9999.0, ("COUNT", "RPM", "S"), **wat)),
        (f"{window}:WATerfall:HEIGht", "disp.wat.heig", integer(20, 0, 100, **wat)),
        (f"{window}:WATerfall:HIDDen", "disp.wat.hidd", boolean(True, **wat)),
        (f"{window}:WATerfall:SKEW", "disp.wat.skew", boolean(False, **wat)),
        (f"{window}:WATerfall:SKEW:ANGLe", "disp.wat.angl", integer(0, -75, 75, **wat)),
        (f"{window}:WATerfall[:STATe]", "disp.wat", boolean(False, **wat)),
        (f"{window}:WATerfall:TOP", "disp.wat.top", real(0.0, -9.9e37, 9.9e37, **wat)),
    ])


def _autoscale(tree: CommandTree, a: Host) -> None:
    """X and Y autoscale: ``ONCE`` scales to the data and leaves the setting as it was."""
    window = _WINDOW
    store = a.store
    store.define("disp.x.auto", Spec("choice", "OFF", choices=("OFF", "ONCE"),
                                     scope=("trace",)))
    store.define("disp.y.auto", Spec("bool", True, scope=("trace",)))

    def auto_setter(name: str, allow_on: bool):
        def setter(call: Call) -> None:
            word = one(call).strip().upper()
            index = store.index(store.specs[name], call)
            if word in ("OFF", "0"):
                store.set(name, False if allow_on else "OFF", index)
            elif word == "ONCE":
                pass  # scales once to the data; the setting is unchanged
            elif allow_on and word in ("ON", "1"):
                store.set(name, True, index)
            else:
                raise ScpiError(-141, f"{word[:20]}")
        return setter

    def auto_query(name: str):
        def query(call: Call) -> str:
            value = store.get(name, store.index(store.specs[name], call))
            if isinstance(value, bool):
                return "ON" if value else "OFF"  # the manual gives ON|OFF for this query
            return str(value)
        return query

    tree.add(f"{window}:TRACe:X[:SCALe]:AUTO", setter=auto_setter("disp.x.auto", False),
             query=auto_query("disp.x.auto"))
    tree.add(f"{window}:TRACe:Y[:SCALe]:AUTO", setter=auto_setter("disp.y.auto", True),
             query=auto_query("disp.y.auto"))


def _actions(tree: CommandTree, a: Host) -> None:
    """Display actions that change nothing stored, and the 1C2 program display keys."""
    window = _WINDOW
    action(tree, "DISPlay:BODE")
    action(tree, f"{window}:TRACe:X:MATCh#")
    action(tree, f"{window}:TRACe:Y:MATCh#")

    def error_message(call: Call) -> None:
        unquote(one(call))

    tree.add("DISPlay:ERRor", setter=error_message)
    for node in ("DISPlay:PROGram:KEY:BOX", "DISPlay:PROGram:KEY:BRACket"):
        def needs_1c2(call: Call) -> None:
            check_option("1C2", a.options)
        tree.add(node, setter=needs_1c2, query=needs_1c2)
