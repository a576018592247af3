"""Sensor terms: what one channel's transducer and conditioning do to the measured FRFs.

The rig measures four channels (physics.md): the excitation force ``F_e``, the table
acceleration ``ẍ_s``, the force into the device ``F_v`` and the disc acceleration ``ẍ_v``; the
FRFs are ``ẍ_s/F_e`` (table) and ``ẍ_v/F_v`` (support). A sensor effect belongs to one channel:
a transfer ``s(ω)`` multiplies the channel's reading, so it multiplies its FRF when the channel
is the response (``ẍ_s``, ``ẍ_v``) and divides it when the channel is the force (``F_e``,
``F_v``). In spec strings a channel is written ``F_e``, ``x_s``, ``F_v`` or ``x_v``:

=================== ======================================= ======================================
term                ``s(ω)`` of the channel                  physical cause
=================== ======================================= ======================================
``delay(CH)``       ``e^{−iωτ}``                             conditioning, cable, a digital filter
``lowpass(CH)``     ``ω_l/(iω + ω_l)``, ``ω_l = 2π f_lp``     an anti-alias filter, a long cable
``highpass(CH)``    ``iω/(iω + ω_h)``, ``ω_h = 2π f_hp``      a charge amplifier's high-pass
``gain(CH)``        ``g`` (true over nominal sensitivity)    a calibration error
``delay``           ``e^{−iωτ_d}`` on both accelerometers    both share one conditioning delay
=================== ======================================= ======================================

What one FRF can tell: a channel effect and the inverse effect on the other channel of the same
FRF give the same data (``gain(x_v)`` = ``1/gain(F_v)``; ``delay(x_v)`` with ``τ < 0`` is
``delay(F_v)``), so a delay's sign names the channel that lags, a gain error names the FRF whose
two channels disagree, and a high-pass is a phase lead on a response channel or a lag on a force
channel. Two FRFs, with the table known, separate a sensor effect from the specimen's K*.

Parameters are named after the channel (``tau_x_v``, ``f_lp_F_e``, ``f_hp_F_v``, ``gain_x_s``);
the shared ``delay`` keeps ``tau_d``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.models.base import Parameter, Term, register_term


class Channel:
    """One of the rig's four measured channels: its spec name, FRF, role and a person's name."""

    def __init__(self, name: str, frf: str, power: int, label: str, quantity: str) -> None:
        self.name = name
        self.frf = frf
        self.power = power
        """+1 when the channel is the FRF's response (numerator), −1 when it is the force."""
        self.label = label
        self.quantity = quantity

    def __repr__(self) -> str:
        return f"<Channel {self.name}>"

    def __reduce__(self) -> tuple[object, tuple[str]]:
        # one object per channel, in a worker process too: terms compare channels by identity
        return _channel, (self.name,)


def _channel(name: str) -> Channel:
    return CHANNELS[name]


#: The channels, in channel order 1..4 of the analyser (physics.md).
CHANNELS: dict[str, Channel] = {
    channel.name: channel
    for channel in (
        Channel("F_e", "table", -1, "excitation force transducer", "F_e"),
        Channel("x_s", "table", +1, "table accelerometer", "ẍ_s"),
        Channel("F_v", "support", -1, "device load cell", "F_v"),
        Channel("x_v", "support", +1, "disc accelerometer", "ẍ_v"),
    )
}
_ORDER = {name: index for index, name in enumerate(CHANNELS)}


def channel(name: str) -> Channel:
    """The channel written ``name`` (``F_e``, ``x_s``, ``F_v``, ``x_v``; case-insensitive)."""
    key = name.strip().lower()
    for known, value in CHANNELS.items():
        if known.lower() == key:
            return value
    raise InputError(
        f"unknown channel '{name}' (one of {', '.join(CHANNELS)})", "model spec"
    )


def response_channel(frf: str) -> Channel:
    """The response (acceleration) channel of an FRF."""
    return next(c for c in CHANNELS.values() if c.frf == frf and c.power > 0)


def force_channel(frf: str) -> Channel:
    """The force channel of an FRF."""
    return next(c for c in CHANNELS.values() if c.frf == frf and c.power < 0)


class ChannelTerm(Term):
    """Base of a term that acts on one channel: ``keyword(CH)``.

    A subclass sets :attr:`keyword`, :attr:`prefix` (its parameter's name before the channel),
    declares its parameter with :meth:`parameter` and gives the channel's transfer ``s(ω)`` in
    :meth:`transfer`.
    """

    prefix: ClassVar[str] = ""

    def __init__(self, argument: str | Channel | None = None) -> None:
        if argument is None:
            raise InputError(
                f"term '{self.keyword}' needs a channel: {self.keyword}(CH), CH one of "
                f"{', '.join(CHANNELS)}",
                "model spec",
            )
        self.channel = argument if isinstance(argument, Channel) else channel(argument)
        self.argument = self.channel.name  # type: ignore[assignment]

    @classmethod
    def from_argument(cls, text: str | None) -> Term:
        return cls(text)

    @property
    def spec(self) -> str:
        return f"{self.keyword}({self.channel.name})"

    def sort_key(self) -> tuple[int]:
        return (_ORDER[self.channel.name],)

    @property
    def name(self) -> str:
        """Local name of the term's parameter (``tau_x_v``)."""
        return f"{self.prefix}_{self.channel.name}"

    def parameter(self) -> Parameter:
        """The term's one parameter."""
        raise NotImplementedError

    def parameters(self) -> tuple[Parameter, ...]:
        return (self.parameter(),)

    def transfer(self, omega: NDArray[np.float64], value: float) -> NDArray[np.complex128]:
        """``s(ω)`` of the channel for a parameter value."""
        raise NotImplementedError

    def transfer_derivative(
        self, omega: NDArray[np.float64], value: float
    ) -> NDArray[np.complex128] | None:
        """``∂s/∂value``; ``None`` (the default): unknown."""
        return None

    #: ``s`` has one shape on every channel (a gain, a delay): see :meth:`Term.frf_weights`.
    same_shape: ClassVar[bool] = False

    def frf_weights(self, frfs: Sequence[str]) -> dict[str, float] | None:
        if not self.same_shape:
            return None
        return {self.channel.frf: 1.0 if self.channel.power > 0 else -1.0}

    def factors(self, omega: NDArray[np.float64], value: float, frfs: Iterable[str],
                derivative: bool = False
                ) -> dict[str, tuple[NDArray[np.complex128], NDArray[np.complex128] | None]]:
        """Per FRF of ``frfs`` the channel enters: the factor it multiplies the FRF by (``s``
        for a response channel, ``1/s`` for a force channel) and, with ``derivative``, that
        factor's derivative by the parameter (``None`` if unknown or not asked for)."""
        if self.channel.frf not in frfs:
            return {}
        s = self.transfer(omega, value)
        ds = self.transfer_derivative(omega, value) if derivative else None
        if self.channel.power > 0:
            return {self.channel.frf: (s, ds)}
        return {self.channel.frf: (1.0 / s, None if ds is None else -ds / s**2)}

    def measure(self, ctx, p, frfs):
        changed = dict(frfs)
        for frf, (factor, _) in self.factors(ctx.omega, p[self.name], frfs).items():
            changed[frf] = frfs[frf] * factor
        return changed

    def measure_derivatives(self, ctx, p, frfs):
        out = {}
        for frf, (factor, derivative) in self.factors(ctx.omega, p[self.name], frfs,
                                                       derivative=True).items():
            if derivative is None:
                return None
            out[frf] = (factor, {self.name: frfs[frf] * derivative})
        return out


@register_term
class Delay(ChannelTerm):
    """A time delay: ``delay(CH)`` delays one channel by ``τ`` (``tau_CH``, negative when the
    channel leads); ``delay`` alone delays both accelerometers by one ``τ_d`` behind the force
    channels (both use the same conditioning), ``H · e^{−iωτ_d}`` on every FRF."""

    keyword = "delay"
    prefix = "tau"

    def __init__(self, argument: str | Channel | None = None) -> None:
        if argument is None:
            self.channel = None  # type: ignore[assignment]
            self.argument = None
            return
        super().__init__(argument)

    @property
    def spec(self) -> str:
        return self.keyword if self.channel is None else super().spec

    def sort_key(self) -> tuple[int]:
        return (-1,) if self.channel is None else super().sort_key()

    @property
    def name(self) -> str:
        return "tau_d" if self.channel is None else super().name

    def parameter(self) -> Parameter:
        what = "both accelerometers' delay" if self.channel is None else (
            f"delay of the {self.channel.label}"
        )
        return Parameter(self.name, "s", -2e-3, 2e-3, 0.0, log=False, description=what)

    def transfer(self, omega, value):
        return np.exp(-1j * omega * value)

    same_shape = True

    def transfer_derivative(self, omega, value):
        return -1j * omega * np.exp(-1j * omega * value)

    def frf_weights(self, frfs):
        if self.channel is not None:
            return super().frf_weights(frfs)
        return dict.fromkeys(frfs, 1.0)

    def factors(self, omega, value, frfs, derivative=False):
        if self.channel is not None:
            return super().factors(omega, value, frfs, derivative)
        shift = self.transfer(omega, value)
        slope = -1j * omega * shift if derivative else None
        return {name: (shift, slope) for name in frfs}


@register_term
class Gain(ChannelTerm):
    """``gain(CH)``: the channel's true sensitivity is ``g`` times the one its volts are converted
    with (``gain_CH``; 1.02 reads 2 % high)."""

    keyword = "gain"
    prefix = "gain"

    def parameter(self) -> Parameter:
        return Parameter(
            self.name, "", 0.5, 2.0, 1.0,
            description=f"true over nominal sensitivity of the {self.channel.label}",
        )

    def transfer(self, omega, value):
        return np.ones(omega.shape, dtype=complex) * value

    same_shape = True

    def transfer_derivative(self, omega, value):
        return np.ones(omega.shape, dtype=complex)


@register_term
class Highpass(ChannelTerm):
    """``highpass(CH)``: a first-order high-pass ``iω/(iω + ω_h)`` on the channel, corner
    ``f_hp_CH`` (Hz): a charge amplifier's, a phase lead of about ``f_hp/f`` rad."""

    keyword = "highpass"
    prefix = "f_hp"

    def parameter(self) -> Parameter:
        return Parameter(
            self.name, "Hz", 1e-3, 100.0, 0.5,
            description=f"high-pass corner of the {self.channel.label}'s conditioning",
        )

    def transfer(self, omega, value):
        s = 1j * omega
        return s / (s + 2 * np.pi * value)

    def transfer_derivative(self, omega, value):
        s = 1j * omega
        return -2 * np.pi * s / (s + 2 * np.pi * value) ** 2


@register_term
class Lowpass(ChannelTerm):
    """``lowpass(CH)``: a first-order low-pass ``ω_l/(iω + ω_l)`` on the channel, corner
    ``f_lp_CH`` (Hz): an anti-alias filter or a long cable, a lag of about ``f/f_lp`` rad that
    also lowers the magnitude by ``(f/f_lp)²/2``."""

    keyword = "lowpass"
    prefix = "f_lp"

    def parameter(self) -> Parameter:
        return Parameter(
            self.name, "Hz", 20.0, 1e6, 1e4,
            description=f"low-pass corner of the {self.channel.label}'s conditioning",
        )

    def transfer(self, omega, value):
        corner = 2 * np.pi * value
        return corner / (1j * omega + corner)

    def transfer_derivative(self, omega, value):
        s = 1j * omega
        return 2 * np.pi * s / (s + 2 * np.pi * value) ** 2

