"""Fault injection for the simulated analyser: what a flaky cable, adapter or instrument does.

Faults are queued on a :class:`FaultInjector` (one per server, ``server.faults``) and fire once,
on the next program message that matches:

``no_reply``
    The message is executed but its response is lost (the client's read times out).
``drop``
    The connection is closed when the message arrives; the message is not executed.
``garble``
    The response is corrupted: cut in the middle and followed by junk, terminator kept (a
    binary block then declares more bytes than it carries).
``error``
    An error ``code,"message"`` is put in the analyser's error queue.
``overload``
    The next points measured flag an input overload on a channel (status bits and event
    register, as when the signal exceeds the range).
``autocal``
    The analyser runs an auto-calibration before its next point (the sweep pauses, status
    ``STAT:OPER`` bit 0 "calibrating" is set meanwhile).

Faults of the wiring between the rig and the analyser's inputs (:class:`FrontEnd`) last until
cleared, like a bad cable does:

``unplug=N``
    Input N reads nothing but the analyser's own noise (a cable off, an ICP supply off).
``swap=A,B``
    Inputs A and B read each other's transducer (two cables swapped).
``gain=N:K``
    Input N reads K times its transducer (a sensitivity off by K in the station file, a
    wrong amplifier gain).
``invert=N``
    Input N reads its transducer with the opposite sign (an accelerometer mounted upside down).
``range=N:DBVRMS``
    Input N's range is stuck at that range whatever the analyser selects (so a normal signal
    overloads it when the stuck range is small).
``hum=N:VPK[:HZ]``
    Input N picks up mains hum (a ground loop in its cable): a sine of VPK volts peak at HZ
    (default 50 Hz), not synchronous with the source. In swept sine a point integrating for
    ``T`` seconds at ``f`` reads it through its integration window, ``sinc((f − HZ) T)``, at a
    phase of its own; the level control watches the transducer, not the hum.

``match`` is a case-insensitive substring of the program message (``"CALC1:DATA?"``). Without
it, ``no_reply`` and ``garble`` fire on the next query, ``drop`` on the next message, and the
others at once.

Command-line form (``viscorig sim serve --fault SPEC``): ``KIND[=ARG][@MATCH]``, for example
``no_reply@*IDN?``, ``drop@INIT``, ``garble@TRAC:DATA?``, ``error=-310,Hardware fault``,
``overload=4`` (channel 4, next sweep) or ``overload=4:10`` (the next 10 points), ``unplug=3``,
``swap=2,4``, ``gain=3:10``, ``invert=4``, ``range=3:-51``, ``hum=1:0.005``, ``autocal``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

__all__ = [
    "FAULT_KINDS",
    "Fault",
    "FaultInjector",
    "FaultSpecError",
    "FaultTarget",
    "FrontEnd",
    "garble",
    "parse_fault_spec",
]

FAULT_KINDS = ("no_reply", "drop", "garble", "error", "overload", "autocal", "unplug", "swap",
               "gain", "invert", "range", "hum")
#: Faults that act on one message's transport; the others act on the instrument.
MESSAGE_FAULTS = ("no_reply", "drop", "garble")
#: Faults of the wiring between rig and inputs (they last).
WIRING_FAULTS = ("unplug", "swap", "gain", "invert", "range", "hum")
#: Mains frequency of a hum without one (Hz).
MAINS_HZ = 50.0
CHANNELS = 4


class FrontEnd:
    """The wiring between the rig's transducers and the analyser's inputs, with its faults.

    Input ``n`` reads ``gain[n] ×`` the signal of transducer ``source[n]`` (``None``: nothing
    is connected, the input reads only the analyser's own noise). ``pinned_range_dbvrms[n]``
    is a range stuck on input ``n``; ``hum[n]`` the mains hum it picks up, ``(volts peak,
    Hz)``. All indices are inputs 1..4. A healthy wiring is the identity.
    """

    def __init__(self) -> None:
        self.source: dict[int, int | None] = {n: n for n in range(1, CHANNELS + 1)}
        self.gain: dict[int, float] = {n: 1.0 for n in range(1, CHANNELS + 1)}
        self.pinned_range_dbvrms: dict[int, float] = {}
        self.hum: dict[int, tuple[float, float]] = {}

    @property
    def healthy(self) -> bool:
        """No fault in the wiring."""
        return (all(self.source[n] == n and self.gain[n] == 1.0 for n in self.source)
                and not self.pinned_range_dbvrms and not self.hum)

    def altered(self, channel: int) -> bool:
        """Input ``channel`` does not simply read its own transducer."""
        return (self.source[channel] != channel or self.gain[channel] != 1.0
                or channel in self.hum)

    def add_hum(self, channel: int, volts_peak: float, frequency_hz: float = MAINS_HZ) -> None:
        """Input ``channel`` picks up a hum of ``volts_peak`` at ``frequency_hz``."""
        self.hum[channel] = (volts_peak, frequency_hz)

    def hum_phasors(self, frequency_hz: np.ndarray, integrate_s: np.ndarray,
                    rng: np.random.Generator) -> np.ndarray:
        """The hum each swept-sine point reads (complex volts peak, points × inputs): through
        the rectangular integration window of ``integrate_s`` seconds at ``frequency_hz``,
        ``sinc((f − f_hum) T)`` of its amplitude, at a phase of its own (the hum is not locked
        to the source)."""
        out = np.zeros((frequency_hz.size, CHANNELS), complex)
        for channel, (volts, mains) in self.hum.items():
            window = np.sinc((frequency_hz - mains) * integrate_s)
            phase = np.exp(2j * np.pi * rng.random(frequency_hz.size))
            out[:, channel - 1] = volts * window * phase
        return out

    def hum_samples(self, times_s: np.ndarray) -> np.ndarray:
        """The hum in the inputs' samples at ``times_s`` (inputs × samples, volts)."""
        out = np.zeros((CHANNELS, times_s.size))
        for channel, (volts, mains) in self.hum.items():
            out[channel - 1] = volts * np.sin(2 * np.pi * mains * times_s)
        return out

    def unplug(self, channel: int) -> None:
        """Input ``channel`` reads nothing."""
        self.source[channel] = None

    def swap(self, a: int, b: int) -> None:
        """Inputs ``a`` and ``b`` read each other's transducer."""
        self.source[a], self.source[b] = self.source[b], self.source[a]
        self.gain[a], self.gain[b] = self.gain[b], self.gain[a]

    def scale(self, channel: int, factor: float) -> None:
        """Input ``channel`` reads ``factor`` times what it read."""
        self.gain[channel] *= factor

    def pin_range(self, channel: int, range_dbvrms: float) -> None:
        """Input ``channel``'s range is stuck at ``range_dbvrms``."""
        self.pinned_range_dbvrms[channel] = range_dbvrms

    def reset(self) -> None:
        """A healthy wiring again."""
        self.__init__()

    def apply(self, values: np.ndarray, scaled: bool = True) -> np.ndarray:
        """What the inputs read, from what the transducers give (last axis: channels 1..4);
        ``scaled=False`` routes without the gains (a normalized variance, which a gain leaves
        as it is).

        An unplugged input reads zero here; the caller adds the analyser's own noise.
        """
        out = np.zeros_like(values)
        for n in range(1, CHANNELS + 1):
            source = self.source[n]
            if source is not None:
                out[..., n - 1] = (self.gain[n] if scaled else 1.0) * values[..., source - 1]
        return out

    def describe(self) -> list[str]:
        """One line per fault, for logs."""
        lines = []
        for n in range(1, CHANNELS + 1):
            source, gain = self.source[n], self.gain[n]
            if source is None:
                lines.append(f"input {n} unplugged")
            elif source != n:
                lines.append(f"input {n} reads transducer {source}")
            if source is not None and gain != 1.0:
                lines.append(f"input {n} reads {gain:g} times its transducer")
        lines += [f"input {n} range stuck at {r:g} dBVrms"
                  for n, r in sorted(self.pinned_range_dbvrms.items())]
        lines += [f"input {n} picks up {volts:g} V peak of {mains:g} Hz hum"
                  for n, (volts, mains) in sorted(self.hum.items())]
        return lines


class FaultTarget(Protocol):
    """What instrument faults act on (the virtual analyser)."""

    front_end: FrontEnd

    def push_error(self, code: int, message: str) -> None:
        """Put an error in the error queue."""

    def force_overload(self, channel: int, points: int | None = None) -> None:
        """Flag an overload on ``channel`` for the next points."""

    def request_calibration(self) -> None:
        """Run an auto-calibration before the next point."""


class FaultSpecError(ValueError):
    """A fault specification cannot be read."""


@dataclass(frozen=True)
class Fault:
    """One fault to inject.

    Attributes
    ----------
    kind
        One of :data:`FAULT_KINDS`.
    match
        Case-insensitive substring of the program message that triggers the fault, or ``None``.
    code, message
        The error for ``error`` faults.
    channel, points
        Input (1..4) of ``overload``, ``unplug``, ``gain``, ``invert``, ``range`` faults, and
        the number of points of an ``overload`` (``None``: the whole next sweep).
    other
        The second input of a ``swap``.
    value
        The factor of a ``gain`` fault, the range (dBVrms) of a ``range`` fault, the volts
        peak of a ``hum``.
    frequency_hz
        The hum's frequency.
    """

    kind: str
    match: str | None = None
    code: int = -310
    message: str = "System error"
    channel: int = 1
    points: int | None = None
    other: int = 2
    value: float = 1.0
    frequency_hz: float = MAINS_HZ

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise FaultSpecError(f"unknown fault {self.kind!r}; faults: {', '.join(FAULT_KINDS)}")
        for number in (self.channel, self.other):
            if not 1 <= number <= CHANNELS:
                raise FaultSpecError(f"{self.kind}: input must be 1..4, got {number}")
        if self.kind == "swap" and self.channel == self.other:
            raise FaultSpecError("swap needs two different inputs")
        if self.kind == "range" and not -51.0 <= self.value <= 27.0:
            raise FaultSpecError(f"range must be -51..27 dBVrms, got {self.value:g}")
        if self.kind == "hum" and not (0.0 < self.value <= 100.0
                                       and 1.0 <= self.frequency_hz <= 1000.0):
            raise FaultSpecError(f"hum needs 0 < VPK <= 100 and 1 <= HZ <= 1000, got "
                                 f"{self.value:g} V at {self.frequency_hz:g} Hz")

    def triggered_by(self, message: str) -> bool:
        if self.match is not None:
            return self.match.upper() in message.upper()
        return "?" in message if self.kind in ("no_reply", "garble") else True


@dataclass
class FaultInjector:
    """Queued faults of one server. Thread-safe; each fault fires once.

    Parameters
    ----------
    analyser
        The instrument that instrument and wiring faults act on.
    """

    analyser: FaultTarget
    _faults: list[Fault] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    fired: list[Fault] = field(default_factory=list)

    def add(self, fault: Fault) -> Fault:
        """Queue a fault (instrument faults without ``match`` act at once)."""
        if fault.match is None and fault.kind not in MESSAGE_FAULTS:
            self._apply(fault)
            return fault
        with self._lock:
            self._faults.append(fault)
        return fault

    def no_reply(self, match: str | None = None) -> Fault:
        """The next query (or message containing ``match``) gets no response."""
        return self.add(Fault("no_reply", match))

    def drop_connection(self, match: str | None = None) -> Fault:
        """Close the connection at the next message (or the one containing ``match``)."""
        return self.add(Fault("drop", match))

    def garble_reply(self, match: str | None = None) -> Fault:
        """Corrupt the response to the next query (or the one containing ``match``)."""
        return self.add(Fault("garble", match))

    def error(self, code: int, message: str, match: str | None = None) -> Fault:
        """Put ``code,"message"`` in the error queue now, or when ``match`` arrives."""
        return self.add(Fault("error", match, code=code, message=message))

    def overload(self, channel: int, points: int | None = None, match: str | None = None) -> Fault:
        """Flag an overload on ``channel`` for the next ``points`` points (whole next sweep)."""
        return self.add(Fault("overload", match, channel=channel, points=points))

    def autocal(self, match: str | None = None) -> Fault:
        """An auto-calibration before the next point (or when ``match`` arrives)."""
        return self.add(Fault("autocal", match))

    @property
    def pending(self) -> list[Fault]:
        """Faults not yet fired."""
        with self._lock:
            return list(self._faults)

    def clear(self) -> None:
        """Forget the faults not yet fired."""
        with self._lock:
            self._faults.clear()

    def take(self, message: str) -> set[str]:
        """Fire the faults that ``message`` triggers; return the message-fault kinds to apply."""
        if not self._faults:  # fast path, read without the lock
            return set()
        fired: list[Fault] = []
        with self._lock:
            seen: set[str] = set()
            for fault in list(self._faults):
                if fault.kind in seen or not fault.triggered_by(message):
                    continue
                seen.add(fault.kind)
                self._faults.remove(fault)
                fired.append(fault)
        kinds: set[str] = set()
        for fault in fired:
            if fault.kind in MESSAGE_FAULTS:
                kinds.add(fault.kind)
            else:
                self._apply(fault)
        self.fired.extend(fired)
        return kinds

    def _apply(self, fault: Fault) -> None:
        target = self.analyser
        wiring = target.front_end
        if fault.kind == "error":
            target.push_error(fault.code, fault.message)
        elif fault.kind == "overload":
            target.force_overload(fault.channel, fault.points)
        elif fault.kind == "autocal":
            target.request_calibration()
        elif fault.kind == "unplug":
            wiring.unplug(fault.channel)
        elif fault.kind == "swap":
            wiring.swap(fault.channel, fault.other)
        elif fault.kind == "gain":
            wiring.scale(fault.channel, fault.value)
        elif fault.kind == "invert":
            wiring.scale(fault.channel, -1.0)
        elif fault.kind == "range":
            wiring.pin_range(fault.channel, fault.value)
        elif fault.kind == "hum":
            wiring.add_hum(fault.channel, fault.value, fault.frequency_hz)


def garble(response: bytes) -> bytes:
    """A corrupted copy of a response: cut in the middle, junk appended, terminator kept."""
    body = response[:-1] if response.endswith(b"\n") else response
    return body[: len(body) // 2] + b"\x7f?#~" + b"\n"


def _numbers(spec: str, arg: str, separator: str, count: int, example: str) -> list[float]:
    parts = arg.split(separator) if arg else []
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != count:
        raise FaultSpecError(f"fault {spec!r}: expected {example}")
    return values


def parse_fault_spec(spec: str) -> Fault:
    """Read ``KIND[=ARG][@MATCH]`` (see the module docstring).

    Raises
    ------
    FaultSpecError
        The specification names no known fault or has a bad argument.
    """
    head, _, match = spec.partition("@")
    kind, _, arg = head.partition("=")
    kind = kind.strip().lower().replace("-", "_")
    arg = arg.strip()
    if kind == "no_response":
        kind = "no_reply"
    if kind == "error":
        code_text, _, message = arg.partition(",")
        try:
            code = int(code_text)
        except ValueError:
            raise FaultSpecError(f"fault {spec!r}: error needs a code, e.g. error=-310") from None
        return Fault("error", match or None, code=code, message=message.strip() or "System error")
    if kind == "overload":
        channel_text, _, points_text = arg.partition(":")
        try:
            channel = int(channel_text)
            points = int(points_text) if points_text else None
        except ValueError:
            raise FaultSpecError(f"fault {spec!r}: overload needs a channel (overload=4)") from None
        return Fault("overload", match or None, channel=channel, points=points)
    if kind in ("unplug", "invert"):
        (channel,) = _numbers(spec, arg, ",", 1, f"{kind}=N (an input 1..4)")
        return Fault(kind, match or None, channel=int(channel))
    if kind == "swap":
        a, b = _numbers(spec, arg, ",", 2, "swap=A,B (two inputs)")
        return Fault("swap", match or None, channel=int(a), other=int(b))
    if kind in ("gain", "range"):
        example = "gain=N:K (input, factor)" if kind == "gain" else "range=N:DBVRMS"
        channel, value = _numbers(spec, arg, ":", 2, example)
        if kind == "gain" and value == 0:
            raise FaultSpecError(f"fault {spec!r}: a gain of 0 is unplug=N")
        return Fault(kind, match or None, channel=int(channel), value=value)
    if kind == "hum":
        numbers = _numbers(spec, arg, ":", 3 if arg.count(":") == 2 else 2,
                           "hum=N:VPK[:HZ] (input, volts peak, Hz)")
        return Fault("hum", match or None, channel=int(numbers[0]), value=numbers[1],
                     frequency_hz=numbers[2] if len(numbers) == 3 else MAINS_HZ)
    if kind not in FAULT_KINDS:
        raise FaultSpecError(f"unknown fault {kind!r}; faults: {', '.join(FAULT_KINDS)}")
    if arg:
        raise FaultSpecError(f"fault {spec!r}: {kind} takes no argument")
    return Fault(kind, match or None)
