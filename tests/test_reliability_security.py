"""Security: loopback-only servers, nothing read is executed, no command injection.

- The simulated analyser (and the scripted test endpoint) bind 127.0.0.1 unless told otherwise;
  checked on the socket itself and, for ``viscorig sim serve``, in the kernel's socket table.
- No file the project reads is executed or unpickled: the source of the three packages is
  parsed and searched for pickle-like modules, ``eval``/``exec``, ``allow_pickle=True``,
  ``yaml.load``, ``shell=True`` and friends (the checker itself is tested on bad code).
- Text sent to the analyser is validated: a ``;``, a newline or ``*RST`` in a label, keyword or
  feed is refused before anything is written (checked on what a recording server received).
"""

from __future__ import annotations

import ast
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import reliability_tally as tally
from agilent35670a import Agilent35670A, SettingOutOfRange
from agilent35670a.scripted import ScriptedSCPIServer
from hypothesis import given, settings
from hypothesis import strategies as st

REPO = Path(__file__).resolve().parents[1]
SOURCE_FOLDERS = ("src/viscorig", "drivers/agilent35670a", "sim/rigsim")
IDN = "HEWLETT-PACKARD,35670A,3416A01234,A.02.01"

# -- loopback only ----------------------------------------------------------------------------


def test_simulated_analyser_binds_loopback_by_default() -> None:
    from rigsim.server import SimulatedAnalyserServer

    with SimulatedAnalyserServer(prologix=True) as server:
        addresses = [listener.getsockname()[0] for listener in server._listeners]
        assert addresses and set(addresses) == {"127.0.0.1"}
        assert server.socket_resource.startswith("TCPIP::127.0.0.1::")
        assert server.prologix_resource.startswith("PRLGX-TCPIP::127.0.0.1::")


def test_scripted_endpoint_binds_loopback() -> None:
    with ScriptedSCPIServer() as server:
        assert server._listener.getsockname()[0] == "127.0.0.1"


def _listening_addresses(port: int) -> set[str]:
    """Local IPv4 addresses listening on ``port``, from the kernel's socket table."""
    found = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        fields = line.split()
        address, port_hex = fields[1].split(":")
        if int(port_hex, 16) == port and fields[3] == "0A":  # 0A: LISTEN
            octets = [str(int(address[i : i + 2], 16)) for i in (6, 4, 2, 0)]
            found.add(".".join(octets))
    return found


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="needs Linux /proc/net/tcp")
def test_sim_serve_command_listens_on_loopback_only() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "viscorig", "sim", "serve", "--prologix"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        lines = []
        assert process.stdout is not None
        for line in process.stdout:
            lines.append(line)
            if line.startswith("Ctrl-C"):
                break
        ports = [int(port) for port in re.findall(r"127\.0\.0\.1::(\d+)::", "".join(lines))]
        assert len(ports) == 2, lines
        for port in ports:
            assert _listening_addresses(port) == {"127.0.0.1"}
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(timeout=10)


# -- nothing read is executed or unpickled ----------------------------------------------------

UNSAFE_MODULES = {"pickle", "cPickle", "_pickle", "dill", "cloudpickle", "marshal", "shelve",
                  "joblib"}
UNSAFE_BUILTINS = {"eval", "exec", "compile", "__import__", "execfile"}
UNSAFE_ATTRIBUTES = {
    ("yaml", "load"), ("yaml", "unsafe_load"), ("yaml", "full_load"), ("os", "system"),
    ("os", "popen"), ("pd", "read_pickle"), ("pandas", "read_pickle"), ("runpy", "run_path"),
}


def unsafe_constructs(source: str, name: str = "<source>") -> list[str]:
    """Every construct in ``source`` that could execute or unpickle what a file holds."""
    found = []
    for node in ast.walk(ast.parse(source, name)):
        where = f"{name}:{getattr(node, 'lineno', '?')}"
        if isinstance(node, ast.Import | ast.ImportFrom):
            modules = [alias.name for alias in node.names] if isinstance(node, ast.Import) else [
                node.module or ""]
            found += [f"{where}: import {m}" for m in modules if m.split(".")[0] in UNSAFE_MODULES]
        elif isinstance(node, ast.Call):
            function = node.func
            if isinstance(function, ast.Name) and function.id in UNSAFE_BUILTINS:
                found.append(f"{where}: {function.id}()")
            if isinstance(function, ast.Attribute) and isinstance(function.value, ast.Name):
                pair = (function.value.id, function.attr)
                if pair in UNSAFE_ATTRIBUTES:
                    found.append(f"{where}: {'.'.join(pair)}()")
                if function.attr == "import_module" and not _constant_prefix(node):
                    found.append(f"{where}: import_module of a computed name")
            for keyword in node.keywords:
                constant = isinstance(keyword.value, ast.Constant) and keyword.value.value is True
                if keyword.arg in ("shell", "allow_pickle") and not (
                    isinstance(keyword.value, ast.Constant) and keyword.value.value is False
                ):
                    found.append(f"{where}: {keyword.arg}={'True' if constant else '<expr>'}")
    return found


def _constant_prefix(call: ast.Call) -> bool:
    """``import_module`` of a literal, or of an f-string starting with a literal package."""
    if not call.args:
        return False
    argument = call.args[0]
    if isinstance(argument, ast.Constant):
        return True
    return (
        isinstance(argument, ast.JoinedStr)
        and bool(argument.values)
        and isinstance(argument.values[0], ast.Constant)
        and str(argument.values[0].value).endswith(".")
    )


def test_the_checker_finds_each_unsafe_construct() -> None:
    bad = """
import pickle
from shelve import open
import numpy as np, yaml, os, subprocess
x = eval(text)
exec(code)
np.load(path, allow_pickle=True)
yaml.load(stream)
os.system(command)
subprocess.run(command, shell=True)
subprocess.run(command, shell=flag)
importlib.import_module(user_text)
"""
    found = unsafe_constructs(bad)
    assert len(found) == 10, found
    good = "np.load(p, allow_pickle=False)\nsubprocess.run(['ls'])\nimport_module(f'a.b.{n}')\n"
    assert unsafe_constructs(good) == []


@pytest.mark.slow
def test_no_source_file_executes_or_unpickles_what_it_reads() -> None:
    files = [path for folder in SOURCE_FOLDERS for path in (REPO / folder).rglob("*.py")]
    assert len(files) > 30
    found = [item for path in files
             for item in unsafe_constructs(path.read_text(encoding="utf-8"), str(path))]
    assert found == []


def test_toml_and_hdf5_are_read_with_data_only_parsers() -> None:
    """Sequence, station and rig files go through tomllib (no code), campaign files through
    h5py (no object references followed into code)."""
    texts = {path: path.read_text(encoding="utf-8")
             for folder in SOURCE_FOLDERS for path in (REPO / folder).rglob("*.py")}
    readers = [path for path, text in texts.items() if "tomllib.load" in text]
    assert readers, "TOML files are read with tomllib"
    assert not any(re.search(r"\btoml\.load|\bjson\.load.*object_hook", text)
                   for text in texts.values())


# -- no command injection through text sent to the analyser -------------------------------------

INJECTIONS = ["N;*RST", "N\n*RST", "N\r\n*RST", "*RST", "N;:OUTP ON", "M/S2 ;SOUR:VOLT 5",
              "N'", 'N"', "N\x1b\n*RST", "ON;*RST", "REAL,64;*RST", "ASC,12\n*RST"]


@pytest.fixture(scope="module")
def recorder():
    with ScriptedSCPIServer({"*IDN?": IDN, "*OPT?": '"1D2,AY6"'}) as server:
        analyser = Agilent35670A.open(server.resource, timeout_s=1.0)
        yield server, analyser
        analyser.close()


def _sent_after(server: ScriptedSCPIServer, count: int) -> list[str]:
    server.commands(0.02)
    return server.received[count:]


@pytest.mark.parametrize("text", INJECTIONS)
def test_labels_and_keywords_with_separators_are_refused_before_sending(recorder, text) -> None:
    server, analyser = recorder
    before = len(server.received)
    attempts = [
        lambda: setattr(analyser.channel(2), "transducer_label", text),
        lambda: analyser.channel(2).set_engineering_units(text, 0.01),
        lambda: setattr(analyser.traces, "data_format", text),
        lambda: setattr(analyser.sweep, "direction", text),
        lambda: setattr(analyser, "instrument_mode", text),
        lambda: setattr(analyser.channel(1), "coupling", text),
        lambda: analyser.read_trace(f"XFR:POW:RAT 2,1{text}"),
        lambda: analyser.read_trace(text),
    ]
    for attempt in attempts:
        with pytest.raises(SettingOutOfRange):
            attempt()
    assert _sent_after(server, before) == []
    tally.add("injections refused", len(attempts))


@pytest.mark.slow
@settings(max_examples=150, deadline=None)
@given(label=st.text(alphabet=st.sampled_from(list("NMGS/2;:*RST\n\r'\" \x1b,")), max_size=12))
def test_any_label_is_sent_clean_or_not_at_all(recorder, label: str) -> None:
    server, analyser = recorder
    before = len(server.received)
    try:
        analyser.channel(2).transducer_label = label
    except SettingOutOfRange:
        assert _sent_after(server, before) == []
        tally.add("injections refused")
    else:
        sent = _sent_after(server, before)
        assert sent[0] == f"VOLT2:RANG:UNIT:XDCR:LAB {label.strip().upper()}"
        assert not re.search(r"[;\n\r'\"*]", sent[0])
    tally.add("inputs fuzzed")


def test_every_valid_feed_is_accepted() -> None:
    feeds = ["XFR:POW:RAT 2,1", "XFR:POW:RAT 4,3", "XFR:POW:LIN 3", "XFR:POW:VAR 4",
             "XFR:POW:CROS 1,2", "XTIM:VOLT 1", "xfr:pow:rat 2,1"]
    from agilent35670a import check_feed

    assert [check_feed(feed) for feed in feeds][:2] == ["XFR:POW:RAT 2,1", "XFR:POW:RAT 4,3"]
    for bad in ("XFR:POW:RAT 5,1", "XFR:POW:COH 2", "XFR:POW:RAT 2,1';*RST;'", ""):
        with pytest.raises(SettingOutOfRange):
            check_feed(bad)

