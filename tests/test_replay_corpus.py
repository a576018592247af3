"""Replay of what real 35670A programs send, over a plain socket to ``viscorig sim serve``.

The corpus (``tests/data/35670a_corpus.jsonl``) holds the programming guide's example
statements, with their chapter, and the command strings of four real programs (a Prologix FFT
driver, a remote-lab GPIB driver, a noise-spectroscopy application's driver and a qudi hardware
module). Each entry is sent after ``*RST`` in its instrument mode
(and the setup it needs); then the error queue is read. An entry the instrument accepts must
leave the queue empty and, for a query, answer in the manual's form (NR1, NR3, quoted string,
keyword, ``ON|OFF``, definite block or comma-separated numbers). Where the manual says the
instrument answers with an error (its own misprints, options not installed, a trigger not
awaited, a program's bug), the entry names that error and must get exactly it.
"""

from __future__ import annotations

import json
import re
import socket
from pathlib import Path

import pytest
from simserve import sim_serve

CORPUS = Path(__file__).parent / "data" / "35670a_corpus.jsonl"
NR3 = r"[+-]\d\.\d+E[+-]\d{3}"
FORMS = {
    "int": r"[+-]\d+", "real": NR3, "string": r'"(?:[^"]|"")*"', "word": r"[A-Z][A-Z0-9/]*",
    "onoff": r"ON|OFF", "idn": r"[^,]+,35670A,[^,]+,[^,]+", "error": r'[+-]\d+,"(?:[^"]|"")*"',
    "fmt": r"(ASC|REAL),[+-]\d+", "reals": rf"{NR3}(,{NR3})*", "ints": r"[+-]\d+(,[+-]\d+)*",
}


def load_corpus() -> list[dict]:
    lines = CORPUS.read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines if line and not line.startswith("#")]


class Client:
    """A plain socket client: one line out, one line (or one block) back."""

    def __init__(self, host: str, port: int) -> None:
        self.sock = socket.create_connection((host, port), timeout=20)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buffer = b""

    def send(self, message: str) -> None:
        self.sock.sendall(message.encode("latin-1") + b"\n")

    def _fill(self) -> None:
        chunk = self.sock.recv(1 << 16)
        if not chunk:
            raise ConnectionError("closed")
        self.buffer += chunk

    def reply(self) -> bytes:
        while not self.buffer:
            self._fill()
        if self.buffer.startswith(b"#"):
            while len(self.buffer) < 2:
                self._fill()
            width = int(self.buffer[1:2])
            while len(self.buffer) < 2 + width:
                self._fill()
            end = 2 + width + int(self.buffer[2:2 + width] or 0) + 1
            while len(self.buffer) < end:
                self._fill()
        else:
            while b"\n" not in self.buffer:
                self._fill()
            end = self.buffer.index(b"\n") + 1
        reply, self.buffer = self.buffer[:end], self.buffer[end:]
        return reply

    def query(self, message: str) -> str:
        self.send(message)
        return self.reply().decode("latin-1").rstrip("\n")

    def errors(self) -> list[str]:
        found = []
        while (entry := self.query("SYST:ERR?")) != '+0,"No error"':
            found.append(entry)
            assert len(found) < 8, found
        return found


def answers_in_form(form: str, reply: bytes) -> bool:
    if form in ("data", "block"):
        if reply.startswith(b"#"):
            width = int(reply[1:2])
            return len(reply) == 2 + width + int(reply[2:2 + width]) + 1
        text = reply.decode("latin-1").strip()
        return form == "data" and (text == "" or re.fullmatch(FORMS["reals"], text) is not None)
    return re.fullmatch(FORMS[form], reply.decode("latin-1").rstrip("\n")) is not None


def replay(client: Client, entry: dict) -> str | None:
    """Send one entry; ``None`` if the analyser behaved as the manual says, else why not."""
    client.send("ABOR;*RST;*CLS")
    if entry["mode"] != "FFT":
        client.send(f"INST:SEL {entry['mode']}")
    for message in entry["setup"]:
        client.send(message)
        if "?" in message:
            client.reply()
    setup_errors = client.errors()
    if setup_errors:
        return f"setup failed: {setup_errors}"
    expect = entry["expect"]
    client.send(entry["command"])
    reply = None
    if expect.startswith("err:") or expect == "ok":
        if "?" in entry["command"]:  # a query that fails may still answer, or may not
            client.send("*IDN?")
            while ",35670A," not in (line := client.reply().decode("latin-1")):
                reply = line.encode("latin-1")
    else:
        reply = client.reply()
    errors = client.errors()
    if expect.startswith("err:"):
        code = expect[4:]
        if len(errors) == 1 and errors[0].startswith(code + ","):
            return None
        return f"expected error {code}, got {errors}"
    if errors:
        return f"errors {errors}"
    if expect != "ok" and (reply is None or not answers_in_form(expect, reply)):
        return f"answer {reply!r} is not {expect}"
    return None


@pytest.mark.slow
def test_the_corpus_is_accepted_as_the_manual_says() -> None:
    corpus = load_corpus()
    accepted_by_manual = [e for e in corpus if not e["expect"].startswith("err:")]
    with sim_serve("--preset", "table", "--seed", "1") as (_, host, _, port):
        client = Client(host, port)
        failures = [(entry["command"], entry["chapter"] or entry["source"], why)
                    for entry in corpus if (why := replay(client, entry)) is not None]
        client.sock.close()
    failed = {command for command, _, _ in failures}
    accepted = [e for e in accepted_by_manual if e["command"] not in failed]
    share = len(accepted) / len(accepted_by_manual)
    print(f"\ncorpus: {len(corpus)} program messages; {len(accepted)} of "
          f"{len(accepted_by_manual)} accepted ({100 * share:.1f} %); "
          f"{len(corpus) - len(accepted_by_manual)} answered with the manual's error")
    assert share >= 0.95, failures[:20]
    assert not failures, failures[:20]


def test_the_corpus_covers_the_manual_and_real_programs() -> None:
    corpus = load_corpus()
    chapters = {e["chapter"].split()[0] for e in corpus if e["chapter"][:1].isdigit()}
    assert {"3", "4", "5", "6", "7", "8", "9", "11", "12", "13", "16", "18", "19", "20", "21",
            "23", "24"} <= chapters
    programs = {e["source"] for e in corpus if e["source"].startswith("program:")}
    assert len(programs) == 4
    assert sum(e["source"].startswith("program:") for e in corpus) > 190
    assert all(e["mode"] in ("FFT", "SINE", "HIST", "CORR") for e in corpus)


@pytest.mark.parametrize("entry", [e for e in load_corpus() if e["expect"].startswith("err:")
                                   and e["source"].startswith("manual")][:3],
                         ids=lambda e: e["command"])
def test_an_expected_error_is_named_with_its_reason(entry: dict) -> None:
    """Entries expected to fail say why in the data (a comment is not enough)."""
    assert re.fullmatch(r"err:-\d{3}", entry["expect"])
