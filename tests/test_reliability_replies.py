"""Malformed analyser replies, fuzzed with hypothesis through a loopback SCPI server.

A scripted 35670A answers a whole segment measurement (``Agilent35670A.measure``) over
pyvisa-py's real socket code, with one reply damaged the way a bad cable, a confused adapter or
a firmware oddity damages it: a block whose header lies about its length, NaN or SCPI's 9.91E37
among the values, too few or too many points, an odd count of (real, imag) values, the wrong
byte order, a shifted frequency axis, ASCII where a block was expected, random bytes, or a
garbled status reply.

Property: ``measure`` returns exactly the true segment (when the damage hit a reply that is
retried, or did not matter) or raises an :class:`agilent35670a.InstrumentError` with a message;
never another exception, never a segment that differs from the truth. Whatever happens, the
sweep (which drives the source) ends stopped.
"""

from __future__ import annotations

import numpy as np
import pytest
import reliability_tally as tally
from agilent35670a import Agilent35670A, InstrumentError, MalformedReply
from agilent35670a.scripted import ScriptedSCPIServer
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scpi_blocks import canned_trace, definite_block

IDN = "HEWLETT-PACKARD,35670A,3416A01234,A.02.01"
#: The paper's station: forces (N) on inputs 1 and 3, accelerations (m/s²) on 2 and 4.
INPUTS = [(1, "N", 0.01124), (2, "M/S2", 0.0102), (3, "N", 0.01124), (4, "M/S2", 0.0102)]
START_HZ, STOP_HZ, RESOLUTION_HZ = 20.0, 21.0, 0.25
FREQUENCIES = START_HZ + RESOLUTION_HZ * np.arange(5)
FRF_21 = np.array([1 + 2j, -0.5 + 0.25j, 3e-3 - 1e2j, 0.1 + 0.1j, -7.0 + 0j])


def true_trace(feed: str) -> np.ndarray:
    return canned_trace(feed, FRF_21)


# -- damage ---------------------------------------------------------------------------------------

BLOCK_DAMAGE = ("short", "long", "nan", "scpi_nan", "inf", "fewer", "more", "odd", "garbage",
                "ascii", "empty", "little_endian", "shifted", "no_terminator_junk")
#: Damage that leaves finite values of the right count: detectable on the frequency axis (it
#: must be the requested grid), not on trace data, which carries no checksum.
AXIS_ONLY_DAMAGE = ("little_endian", "shifted")
TEXT_DAMAGE = ("garbage", "nan", "scpi_nan", "empty", "fraction", "words", "binary")
#: Replies that can be damaged: the frequency axis, each trace read (by feed), status replies.
TARGETS = ("TRAC:X? D1", "XFR:POW:RAT 2,1", "XFR:POW:RAT 4,3", "XFR:POW:LIN 1", "XFR:POW:LIN 4",
           "XFR:POW:VAR 2", "STAT:QUES:VOLT:EVEN?", "*ESR?", "SYST:ERR?")


def damage_block(values: np.ndarray, how: str, junk: bytes) -> bytes:
    if how == "short":  # header declares more bytes than follow: the read waits, then times out
        good = definite_block(values)
        return good[:-9] + b"\n"
    if how == "long":
        return definite_block(values)[:-1] + junk[:8] + b"\n"
    if how in ("nan", "scpi_nan", "inf"):
        bad = values.copy()
        bad[len(bad) // 2] = {"nan": np.nan, "scpi_nan": 9.91e37, "inf": -np.inf}[how]
        return definite_block(bad)
    if how == "fewer":
        return definite_block(values[:-2])
    if how == "more":
        return definite_block(np.concatenate([values, values[:2]]))
    if how == "odd":
        return definite_block(values[:-1])
    if how == "garbage":
        return junk.replace(b"\n", b"") + b"\n"
    if how == "ascii":
        return ",".join(f"{v:+.6E}" for v in values).encode() + b"\n"
    if how == "empty":
        return b"\n"
    if how == "little_endian":
        return definite_block(values, "<f8")
    if how == "shifted":
        return definite_block(values + 7.0)
    return definite_block(values) + junk[:4].replace(b"\n", b"") + b"\n"


def damage_text(good: str, how: str, junk: bytes) -> bytes:
    return {
        "garbage": junk.replace(b"\n", b"")[:20] + b"\n",
        "nan": b"NAN\n",
        "scpi_nan": b"+9.91E+37\n",
        "empty": b"\n",
        "fraction": b"+1.5\n",
        "words": b'"No error"\n',
        "binary": b"#13\x00\x01\x02\n",
    }[how]


class DamagedAnalyser(ScriptedSCPIServer):
    """A scripted 35670A answering one segment measurement, with one reply damaged.

    ``target`` names a query (or a feed, for ``TRAC:DATA? D1`` after that feed); the damage is
    applied ``times`` times (1: a retry gets the good reply; 9: it never does).
    """

    def __init__(self, target: str, how: str, junk: bytes, times: int) -> None:
        self.target, self.how, self.junk, self.times = target, how, junk, times
        self.damaged = 0
        self.feed = ""
        self.measuring = False
        super().__init__({
            "*IDN?": IDN,
            "*OPT?": '"1D2,AY6"',
            "*STB?": "+32",
            "STAT:OPER:COND?": "+0",
            "*ESR?": lambda m: self.text("*ESR?", "+1"),
            "STAT:QUES:VOLT:EVEN?": lambda m: self.text("STAT:QUES:VOLT:EVEN?", "+0"),
            "SYST:ERR?": lambda m: self.text("SYST:ERR?", '+0,"No error"'),
            "TRAC:X? D1": lambda m: self.data("TRAC:X? D1", FREQUENCIES),
            "TRAC:DATA? D1": lambda m: self.data(self.feed, true_trace(self.feed)),
        }, defaults={"FREQ:STOP?": "+1.00000000E+002"})

    def _reply_to(self, message: str) -> bytes | None:
        if message.upper().startswith("CALC1:FEED"):
            self.feed = message.split("'")[1].upper()
        if ":INIT:IMM" in message.upper():
            self.measuring = True
        return super()._reply_to(message)

    def _hit(self, what: str) -> bool:
        if self.measuring and what == self.target and self.damaged < self.times:
            self.damaged += 1
            return True
        return False

    def text(self, what: str, good: str) -> bytes | str:
        return damage_text(good, self.how, self.junk) if self._hit(what) else good

    def data(self, what: str, values: np.ndarray) -> bytes:
        if self._hit(what):
            return damage_block(values, self.how, self.junk)
        return definite_block(values)


def measure_with(server: DamagedAnalyser):
    analyser = Agilent35670A.open(server.resource, timeout_s=0.25)
    try:
        analyser.configure_swept_sine(
            inputs=INPUTS, reference_channel=4, reference_level_eu=2.0, source_limit_vpk=1.5,
            input_limit_eu=40.0, start_hz=START_HZ, stop_hz=STOP_HZ,
            resolution_hz=RESOLUTION_HZ,
        )
        return analyser.measure(START_HZ, STOP_HZ, poll_interval_s=0.005)
    finally:
        analyser.close()


def assert_true_segment(segment) -> None:
    np.testing.assert_array_equal(segment.frequency_hz, FREQUENCIES)
    np.testing.assert_array_equal(segment.frf_21, FRF_21)
    np.testing.assert_array_equal(segment.frf_43, 2 * FRF_21)
    for channel in (1, 2, 3, 4):
        np.testing.assert_array_equal(segment.amplitude_eu[channel], 5.0 * channel)
        np.testing.assert_array_equal(segment.variance[channel], 1e-4 * channel)


def check_one(target: str, how: str, junk: bytes, times: int) -> str:
    """Measure with one damaged reply; return "data" or "error"; fail on anything else."""
    block_target = target not in ("STAT:QUES:VOLT:EVEN?", "*ESR?", "SYST:ERR?")
    if block_target:
        assert how in BLOCK_DAMAGE
    with DamagedAnalyser(target, how, junk, times) as server:
        try:
            segment = measure_with(server)
        except InstrumentError as error:
            outcome = "error"
            assert str(error).strip(), "an error with no message"
        else:
            outcome = "data"
            assert_true_segment(segment)
        # in swept sine the sweep drives the source: it ends stopped
        commands = server.commands(0.01)
        assert ":INIT:IMM" not in commands or commands[-1] == "ABOR", "the source was left on"
    tally.add("replies fuzzed")
    return outcome


junk_bytes = st.binary(min_size=1, max_size=40)


@pytest.mark.slow
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(target=st.sampled_from(TARGETS[:6]), how=st.sampled_from(BLOCK_DAMAGE), junk=junk_bytes,
       times=st.sampled_from([1, 9]))
def test_a_damaged_data_block_is_an_instrument_error_or_retried_to_the_truth(
    target: str, how: str, junk: bytes, times: int
) -> None:
    assume(target == "TRAC:X? D1" or how not in AXIS_ONLY_DAMAGE)
    check_one(target, how, junk, times)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(target=st.sampled_from(TARGETS[6:]), how=st.sampled_from(TEXT_DAMAGE), junk=junk_bytes)
def test_a_damaged_status_reply_is_an_instrument_error_or_harmless(
    target: str, how: str, junk: bytes
) -> None:
    # random bytes may happen to read as a valid status ("0": not complete yet, poll again)
    outcome = check_one(target, how, junk, 1)
    assert outcome == "error" or how == "garbage"


@pytest.mark.parametrize("how", ["little_endian", "shifted"])
def test_a_frequency_axis_off_the_requested_grid_is_refused(how: str) -> None:
    """Finite but wrong X values (byte order, a stale reply) must not become frequencies."""
    with DamagedAnalyser("TRAC:X? D1", how, b"", 9) as server, pytest.raises(
        MalformedReply, match="frequency axis"
    ):
        measure_with(server)
    tally.add("replies fuzzed")


@pytest.mark.parametrize("how", BLOCK_DAMAGE)
def test_every_kind_of_block_damage_on_the_axis_is_an_error(how: str) -> None:
    assert check_one("TRAC:X? D1", how, b"\x00junk\xff", 9) == "error"
