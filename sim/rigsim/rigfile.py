"""Rig description files: what the simulated rig is made of.

A rig file is TOML. The sections ``[table]``, ``[device]``, ``[load_cell]``, ``[[fixture]]`` and
``[sensors]`` are fixed by the shared design; the others are the simulator's own:

``[shaker]``
    ``force_n_per_v`` (shaker and amplifier gain), ``force_limit_n`` (peak force the shaker can
    deliver; the fundamental of the force saturates there).
``[noise]``
    Sensor noise densities (one-sided amplitude spectral density, white over the band):
    ``excitation_force_n_per_sqrt_hz``, ``table_acceleration_m_per_s2_per_sqrt_hz``,
    ``device_force_n_per_sqrt_hz``, ``disc_acceleration_m_per_s2_per_sqrt_hz``; the analyser's
    ADC floor ``adc_noise_db_re_range_per_sqrt_hz`` (noise density relative to the input range
    in use, default -100 dB per sqrt(Hz)); ``seed`` (integer) for reproducible noise.
    Two sources of noise that is not white and Gaussian, both off unless given:
    ``sensitivity_drift_rms`` (relative rms, e.g. 5e-4) and ``sensitivity_drift_time_s``
    (correlation time, default 30 s): each transducer's sensitivity wanders as it warms and
    cools, a Gauss-Markov process in test time, independent per channel, so the FRFs (channel
    ratios) carry a gain error correlated from point to point along the sweep;
    ``burst_probability`` (per point, e.g. 0.01) and ``burst_factor`` (default 30): at a point
    so struck, interference (a relay, a knock on the bench) multiplies every channel's noise by
    the factor for that point's integration, which makes the errors heavy-tailed.
    Without a ``[noise]`` section the rig is noiseless.
``[delays]``
    Per-channel sensor (conditioning) delays in seconds: ``excitation_force_s``,
    ``table_acceleration_s``, ``device_force_s``, ``disc_acceleration_s``.
``[sensors.<channel>]``
    How one channel's transducer and conditioning differ from the nominal chain, for
    ``<channel>`` one of ``excitation_force``, ``table_acceleration``, ``device_force``,
    ``disc_acceleration``: ``gain`` (true sensitivity over the nominal one of ``[sensors]``,
    which the analyser's engineering units assume; 1.02 is a transducer reading 2 % high),
    ``highpass_hz`` (corner of a first-order high-pass, as a charge amplifier's), ``lowpass_hz``
    (corner of a first-order low-pass, as an anti-alias filter or a long cable's). The filters
    are states of the simulated rig, so they have transients like the structure.
``[amplitude]``
    Payne-like softening of the rubber with the displacement amplitude ``x`` across the
    specimens: the whole K* is scaled by ``1 - softening_fraction * r / (1 + r)`` with
    ``r = (x / reference_displacement_m) ** exponent`` (Kraus form; ``exponent`` defaults to 1).
``[drift]``
    ``modulus_change_per_hour``: fractional change of K* per hour of test time (linear in the
    simulator clock; -0.02 means the modulus falls 2 % per hour as the rubber warms).
``[temperature]``
    Time-temperature superposition of the rubber on the specimens' own temperature (WLF):
    ``reference_temperature_c``, ``c1``, ``c2_k``. At temperature ``T`` every relaxation time
    of the device's material (its dashpot and Maxwell arms) is multiplied by ``a_T`` with
    ``log10 a_T = -c1 (T - T_ref) / (c2_k + T - T_ref)``, i.e. ``K*(f, T) = K*(f a_T, T_ref)``
    (no vertical shift). The temperature is the simulated chamber's specimen temperature.
``[chamber]``
    The temperature chamber around the specimens (:mod:`rigsim.chamber`):
    ``heating_rate_k_per_min``, ``cooling_rate_k_per_min``, ``air_time_constant_s``,
    ``specimen_time_constant_s``, ``start_temperature_c``.
``[payne]``
    Strain-amplitude dependence of a filled rubber (Payne effect, Kraus's model) on the
    displacement amplitude ``x`` across the specimens, added to the material's K*:
    ``K' += storage_drop_n_per_m / (1 + r^(2m))`` and
    ``K'' += 2 loss_peak_n_per_m r^m / (1 + r^(2m))`` with ``r = x / critical_displacement_m``
    and ``m = exponent``. In the time-domain rig it is a spring and a dashpot (``K''/ω`` at the
    point's frequency) between disc and frame, set at each point for the amplitude reached there.
``[frame]``
    The inertial frame that carries the shaker body, the table suspension and the device, on its
    own isolators: ``mass_kg``, ``frequency_hz``, ``damping_ratio``. Leave out for a rigid frame.
``[specimen]``
    Metadata only (not used by the physics): ``hardness_shore_a``, ``preload_strain``,
    ``count``, ``diameter_m``, ``height_m``.

Top-level keys: ``name`` and ``description`` (strings, optional).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # read only when a rig file has a [chamber]
    from rigsim.chamber import ChamberParameters

__all__ = [
    "CHANNEL_KEYS",
    "AmplitudeDependence",
    "Conditioning",
    "Delays",
    "Device",
    "Drift",
    "FixtureMode",
    "FractionalMaterial",
    "Frame",
    "LoadCell",
    "MaxwellMaterial",
    "Noise",
    "Payne",
    "Rig",
    "RigFileError",
    "Sensors",
    "Shaker",
    "Specimen",
    "Table",
    "TemperatureShift",
    "VoigtMaterial",
    "load_preset",
    "load_rig",
    "parse_rig",
    "preset_names",
]


class RigFileError(ValueError):
    """A rig file cannot be read: the message names the file and the key path."""


@dataclass(frozen=True)
class Table:
    """Vibratory table: mass, suspension stiffness and damping (to the frame)."""

    mass_kg: float
    stiffness_n_per_m: float
    damping_ns_per_m: float


@dataclass(frozen=True)
class VoigtMaterial:
    """Spring and dashpot in parallel: ``K* = K + i ω C``."""

    stiffness_n_per_m: float
    damping_ns_per_m: float


@dataclass(frozen=True)
class MaxwellMaterial:
    """Generalized Maxwell: ``K* = K_0 + Σ i ω K_i C_i / (K_i + i ω C_i)``.

    ``arms`` holds ``(K_i [N/m], C_i [N s/m])`` pairs.
    """

    static_stiffness_n_per_m: float
    arms: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class FractionalMaterial:
    """Fractional Zener: ``K* = (K_0 + K_∞ (i ω τ)^α) / (1 + (i ω τ)^α)``."""

    static_stiffness_n_per_m: float
    high_stiffness_n_per_m: float
    tau_s: float
    alpha: float


Material = VoigtMaterial | MaxwellMaterial | FractionalMaterial


@dataclass(frozen=True)
class Device:
    """The damper device: the moving disc (``mass_kg``) held by the specimens (``material``)."""

    mass_kg: float
    material: Material


@dataclass(frozen=True)
class LoadCell:
    """Link between table and disc (load cell and linkage), as a spring."""

    stiffness_n_per_m: float


@dataclass(frozen=True)
class FixtureMode:
    """A local mode attached to the disc: a mass on a spring-damper."""

    frequency_hz: float
    damping_ratio: float
    mass_kg: float


#: Channel names in channel order 1..4 (the keys of ``[delays]`` without ``_s``).
CHANNEL_KEYS = ("excitation_force", "table_acceleration", "device_force", "disc_acceleration")


@dataclass(frozen=True)
class Conditioning:
    """How one channel's transducer and conditioning differ from the nominal chain.

    Attributes
    ----------
    gain
        True sensitivity over the nominal one (the analyser converts volts with the nominal).
    highpass_hz
        Corner of a first-order high-pass ``iω/(iω + ω_h)`` (a charge amplifier), or ``None``.
    lowpass_hz
        Corner of a first-order low-pass ``ω_l/(iω + ω_l)`` (anti-alias filter, cable), or
        ``None``.
    """

    gain: float = 1.0
    highpass_hz: float | None = None
    lowpass_hz: float | None = None

    @property
    def filtered(self) -> bool:
        """The channel has a filter (extra states in the rig's state space)."""
        return self.highpass_hz is not None or self.lowpass_hz is not None


@dataclass(frozen=True)
class Sensors:
    """Transducer sensitivities of the simulated channels (nominal), and per channel how the
    real chain differs from them (``conditioning``, channel order 1..4)."""

    force_v_per_n: float = 0.01124
    acceleration_v_per_m_s2: float = 0.0102
    conditioning: tuple[Conditioning, ...] = (Conditioning(),) * 4

    def gains(self) -> tuple[float, ...]:
        """True over nominal sensitivity of each channel, in channel order."""
        return tuple(channel.gain for channel in self.conditioning)


@dataclass(frozen=True)
class Shaker:
    """Electrodynamic shaker with its amplifier."""

    force_n_per_v: float = 50.0
    force_limit_n: float = 100.0


@dataclass(frozen=True)
class Noise:
    """Sensor noise densities and the analyser's ADC floor."""

    excitation_force_n_per_sqrt_hz: float = 0.0
    table_acceleration_m_per_s2_per_sqrt_hz: float = 0.0
    device_force_n_per_sqrt_hz: float = 0.0
    disc_acceleration_m_per_s2_per_sqrt_hz: float = 0.0
    adc_noise_db_re_range_per_sqrt_hz: float = -100.0
    seed: int | None = None
    sensitivity_drift_rms: float = 0.0
    sensitivity_drift_time_s: float = 30.0
    burst_probability: float = 0.0
    burst_factor: float = 30.0


@dataclass(frozen=True)
class Delays:
    """Per-channel sensor delays (seconds)."""

    excitation_force_s: float = 0.0
    table_acceleration_s: float = 0.0
    device_force_s: float = 0.0
    disc_acceleration_s: float = 0.0

    def as_tuple(self) -> tuple[float, float, float, float]:
        """Delays in channel order 1..4."""
        return (
            self.excitation_force_s,
            self.table_acceleration_s,
            self.device_force_s,
            self.disc_acceleration_s,
        )


@dataclass(frozen=True)
class TemperatureShift:
    """WLF time-temperature shift of the rubber (``[temperature]``)."""

    reference_temperature_c: float
    c1: float
    c2_k: float

    def log10_shift(self, temperature_c: float) -> float:
        """``log10 a_T`` at a temperature (°C): positive below the reference."""
        dt = temperature_c - self.reference_temperature_c
        return -self.c1 * dt / (self.c2_k + dt)


@dataclass(frozen=True)
class Payne:
    """Kraus model of the filler network's stiffness and loss (``[payne]``)."""

    storage_drop_n_per_m: float
    loss_peak_n_per_m: float
    critical_displacement_m: float
    exponent: float

    def stiffness(self, displacement_m: float) -> tuple[float, float]:
        """(K', K'') the filler network adds at a displacement amplitude, N/m."""
        r = (abs(displacement_m) / self.critical_displacement_m) ** self.exponent
        return (self.storage_drop_n_per_m / (1.0 + r * r),
                2.0 * self.loss_peak_n_per_m * r / (1.0 + r * r))


@dataclass(frozen=True)
class AmplitudeDependence:
    """Payne-like softening with the displacement amplitude across the specimens."""

    softening_fraction: float
    reference_displacement_m: float
    exponent: float = 1.0

    def scale(self, displacement_m: float) -> float:
        """Factor on K* at a displacement amplitude (peak metres)."""
        r = (abs(displacement_m) / self.reference_displacement_m) ** self.exponent
        return 1.0 - self.softening_fraction * r / (1.0 + r)


@dataclass(frozen=True)
class Drift:
    """Thermal drift of the modulus, linear in test time."""

    modulus_change_per_hour: float

    def scale(self, time_s: float) -> float:
        """Factor on K* at a simulator time (seconds since mounting)."""
        return 1.0 + self.modulus_change_per_hour * time_s / 3600.0


@dataclass(frozen=True)
class Frame:
    """Inertial frame on isolators, carrying shaker body, table suspension and device."""

    mass_kg: float
    frequency_hz: float
    damping_ratio: float


@dataclass(frozen=True)
class Specimen:
    """Descriptive data of the specimens (not used by the physics)."""

    hardness_shore_a: float | None = None
    preload_strain: float | None = None
    count: int | None = None
    diameter_m: float | None = None
    height_m: float | None = None


@dataclass(frozen=True)
class Rig:
    """A complete simulated rig. ``device`` is ``None`` for the bare table, ``load_cell``
    ``None`` for a rigid link, ``noise`` ``None`` for a noiseless rig."""

    table: Table
    device: Device | None = None
    load_cell: LoadCell | None = None
    fixtures: tuple[FixtureMode, ...] = ()
    sensors: Sensors = field(default_factory=Sensors)
    shaker: Shaker = field(default_factory=Shaker)
    noise: Noise | None = None
    delays: Delays = field(default_factory=Delays)
    amplitude: AmplitudeDependence | None = None
    drift: Drift | None = None
    temperature: TemperatureShift | None = None
    chamber: Any = None
    """``rigsim.chamber.ChamberParameters`` of ``[chamber]``, or None."""
    payne: Payne | None = None
    frame: Frame | None = None
    specimen: Specimen = field(default_factory=Specimen)
    name: str = ""
    description: str = ""
    source: str = "<memory>"

    def noiseless(self) -> Rig:
        """The same rig without sensor noise or ADC floor."""
        return replace(self, noise=None)


# --------------------------------------------------------------------------------------------
# parsing


class _Section:
    """One TOML table being read: typed getters that name the key path in every error."""

    def __init__(self, data: Any, path: str, source: str) -> None:
        self.path = path
        self.source = source
        if not isinstance(data, dict):
            raise self.error(f"must be a table, not {type(data).__name__}", key=None)
        self.data = data
        self.used: set[str] = set()

    def where(self, key: str | None) -> str:
        if key is None:
            return self.path or "<top level>"
        return f"{self.path}.{key}" if self.path else key

    def error(self, message: str, key: str | None) -> RigFileError:
        return RigFileError(f"{self.source}: {self.where(key)}: {message}")

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str) -> Any:
        self.used.add(key)
        return self.data[key]

    def number(
        self,
        key: str,
        default: float | None = None,
        *,
        required: bool = True,
        minimum: float | None = None,
        maximum: float | None = None,
        exclusive_minimum: bool = False,
        exclusive_maximum: bool = False,
    ) -> float:
        if key not in self.data:
            if default is not None or not required:
                return default  # type: ignore[return-value]
            raise self.error("missing value (a number is required)", key)
        value = self.raw(key)
        return self.check_number(
            value, key, minimum, maximum, exclusive_minimum, exclusive_maximum
        )

    def check_number(
        self,
        value: Any,
        key: str,
        minimum: float | None = None,
        maximum: float | None = None,
        exclusive_minimum: bool = False,
        exclusive_maximum: bool = False,
    ) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(f"must be a number, not {type(value).__name__} {value!r}", key)
        try:
            number = float(value)
        except OverflowError:
            raise self.error(f"number {value} is too large", key) from None
        if not math.isfinite(number):
            raise self.error(f"must be finite, not {number}", key)
        if minimum is not None:
            if exclusive_minimum and number <= minimum:
                raise self.error(f"must be > {minimum:g}, not {number:g}", key)
            if not exclusive_minimum and number < minimum:
                raise self.error(f"must be >= {minimum:g}, not {number:g}", key)
        if maximum is not None:
            if exclusive_maximum and number >= maximum:
                raise self.error(f"must be < {maximum:g}, not {number:g}", key)
            if not exclusive_maximum and number > maximum:
                raise self.error(f"must be <= {maximum:g}, not {number:g}", key)
        return number

    def positive(self, key: str, default: float | None = None) -> float:
        return self.number(key, default, minimum=0.0, exclusive_minimum=True)

    def non_negative(self, key: str, default: float | None = None) -> float:
        return self.number(key, default, minimum=0.0)

    def optional_positive(self, key: str) -> float | None:
        if key not in self.data:
            return None
        return self.positive(key)

    def string(self, key: str, default: str) -> str:
        if key not in self.data:
            return default
        value = self.raw(key)
        if not isinstance(value, str):
            raise self.error(f"must be a string, not {type(value).__name__}", key)
        return value

    def integer(self, key: str, *, minimum: int | None = None) -> int | None:
        if key not in self.data:
            return None
        value = self.raw(key)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(f"must be an integer, not {type(value).__name__} {value!r}", key)
        if minimum is not None and value < minimum:
            raise self.error(f"must be >= {minimum}, not {value}", key)
        return value

    def section(self, key: str) -> _Section | None:
        if key not in self.data:
            return None
        return _Section(self.raw(key), self.where(key), self.source)

    def finish(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            where = [self.where(key) for key in unknown]
            raise RigFileError(f"{self.source}: unknown key {', '.join(where)}")


def _read_material(sec: _Section) -> Material:
    if not sec.has("model"):
        raise sec.error("missing value (one of 'voigt', 'maxwell', 'fractional')", "model")
    model = sec.raw("model")
    if model == "voigt":
        return VoigtMaterial(
            stiffness_n_per_m=sec.positive("stiffness_n_per_m"),
            damping_ns_per_m=sec.non_negative("damping_ns_per_m"),
        )
    if model == "maxwell":
        static = sec.non_negative("static_stiffness_n_per_m")
        if not sec.has("arms"):
            raise sec.error("missing value (a list of [K_i, C_i] pairs)", "arms")
        raw_arms = sec.raw("arms")
        if not isinstance(raw_arms, list):
            raise sec.error("must be a list of [K_i, C_i] pairs", "arms")
        arms = []
        for index, arm in enumerate(raw_arms):
            key = f"arms[{index}]"
            if not isinstance(arm, list) or len(arm) != 2:
                raise sec.error("must be a pair [K_i in N/m, C_i in N s/m]", key)
            k_i = sec.check_number(arm[0], f"{key}[0]", 0.0, exclusive_minimum=True)
            c_i = sec.check_number(arm[1], f"{key}[1]", 0.0, exclusive_minimum=True)
            arms.append((k_i, c_i))
        if static == 0.0 and not arms:
            raise sec.error("a Maxwell material needs a static stiffness or an arm", "arms")
        return MaxwellMaterial(static_stiffness_n_per_m=static, arms=tuple(arms))
    if model == "fractional":
        static = sec.non_negative("static_stiffness_n_per_m")
        high = sec.positive("high_stiffness_n_per_m")
        if high <= static:
            raise sec.error(
                f"must exceed static_stiffness_n_per_m ({static:g}), not {high:g}",
                "high_stiffness_n_per_m",
            )
        return FractionalMaterial(
            static_stiffness_n_per_m=static,
            high_stiffness_n_per_m=high,
            tau_s=sec.positive("tau_s"),
            alpha=sec.number(
                "alpha", minimum=0.0, maximum=1.0, exclusive_minimum=True, exclusive_maximum=True
            ),
        )
    raise sec.error(f"must be 'voigt', 'maxwell' or 'fractional', not {model!r}", "model")


def _read_damping_ratio(sec: _Section, key: str) -> float:
    # Critical damping (ratio 1) makes the mode defective for the modal solution.
    return sec.number(key, minimum=0.0, maximum=1.0, exclusive_maximum=True)


def _read_section(top: _Section, key: str, read: Callable[[_Section], Any],
                  default: Any = None) -> Any:
    """``read`` of section ``[key]`` with every key of it used, or ``default`` without it."""
    sec = top.section(key)
    if sec is None:
        return default
    value = read(sec)
    sec.finish()
    return value


def _read_table(sec: _Section) -> Table:
    return Table(
        mass_kg=sec.positive("mass_kg"),
        stiffness_n_per_m=sec.positive("stiffness_n_per_m"),
        damping_ns_per_m=sec.non_negative("damping_ns_per_m"),
    )


def _read_device(sec: _Section) -> Device:
    return Device(mass_kg=sec.positive("mass_kg"), material=_read_material(sec))


def _read_load_cell(sec: _Section) -> LoadCell:
    return LoadCell(stiffness_n_per_m=sec.positive("stiffness_n_per_m"))


def _read_fixtures(top: _Section, has_device: bool) -> tuple[FixtureMode, ...]:
    """The ``[[fixture]]`` modes (they attach to the disc: a device is needed)."""
    if not top.has("fixture"):
        return ()
    raw = top.raw("fixture")
    if not isinstance(raw, list):
        raise top.error("must be an array of tables ([[fixture]])", "fixture")
    if raw and not has_device:
        raise top.error("fixture modes attach to the disc: they need a [device]", "fixture")
    fixtures = []
    for index, item in enumerate(raw):
        sec = _Section(item, f"fixture[{index}]", top.source)
        fixtures.append(
            FixtureMode(
                frequency_hz=sec.positive("frequency_hz"),
                damping_ratio=_read_damping_ratio(sec, "damping_ratio"),
                mass_kg=sec.positive("mass_kg"),
            )
        )
        sec.finish()
    return tuple(fixtures)


def _read_conditioning(sec: _Section, key: str) -> Conditioning:
    channel = sec.section(key)
    if channel is None:
        return Conditioning()
    conditioning = Conditioning(
        gain=channel.number("gain", 1.0, minimum=0.1, maximum=10.0),
        highpass_hz=channel.number("highpass_hz", required=False, minimum=1e-3, maximum=1e3),
        lowpass_hz=channel.number("lowpass_hz", required=False, minimum=1.0, maximum=1e9),
    )
    channel.finish()
    return conditioning


def _read_sensors(sec: _Section) -> Sensors:
    conditioning = tuple(_read_conditioning(sec, key) for key in CHANNEL_KEYS)
    return Sensors(
        force_v_per_n=sec.positive("force_v_per_n", Sensors.force_v_per_n),
        acceleration_v_per_m_s2=sec.positive(
            "acceleration_v_per_m_s2", Sensors.acceleration_v_per_m_s2
        ),
        conditioning=conditioning,
    )


def _read_shaker(sec: _Section) -> Shaker:
    return Shaker(
        force_n_per_v=sec.positive("force_n_per_v"),
        force_limit_n=sec.positive("force_limit_n"),
    )


def _read_noise(sec: _Section) -> Noise:
    defaults = Noise()
    return Noise(
        excitation_force_n_per_sqrt_hz=sec.non_negative("excitation_force_n_per_sqrt_hz", 0.0),
        table_acceleration_m_per_s2_per_sqrt_hz=sec.non_negative(
            "table_acceleration_m_per_s2_per_sqrt_hz", 0.0
        ),
        device_force_n_per_sqrt_hz=sec.non_negative("device_force_n_per_sqrt_hz", 0.0),
        disc_acceleration_m_per_s2_per_sqrt_hz=sec.non_negative(
            "disc_acceleration_m_per_s2_per_sqrt_hz", 0.0
        ),
        adc_noise_db_re_range_per_sqrt_hz=sec.number(
            "adc_noise_db_re_range_per_sqrt_hz",
            defaults.adc_noise_db_re_range_per_sqrt_hz,
            maximum=0.0,
        ),
        seed=sec.integer("seed", minimum=0),
        sensitivity_drift_rms=sec.number(
            "sensitivity_drift_rms", 0.0, minimum=0.0, maximum=0.1
        ),
        sensitivity_drift_time_s=sec.number(
            "sensitivity_drift_time_s", 30.0, minimum=0.0, exclusive_minimum=True,
            maximum=1e6,
        ),
        burst_probability=sec.number("burst_probability", 0.0, minimum=0.0, maximum=1.0),
        burst_factor=sec.number("burst_factor", 30.0, minimum=1.0, maximum=1e4),
    )


def _read_delays(sec: _Section) -> Delays:
    return Delays(
        *(
            sec.number(key, 0.0, minimum=0.0, maximum=1.0)
            for key in (
                "excitation_force_s",
                "table_acceleration_s",
                "device_force_s",
                "disc_acceleration_s",
            )
        )
    )


def _read_amplitude(sec: _Section) -> AmplitudeDependence:
    return AmplitudeDependence(
        softening_fraction=sec.number(
            "softening_fraction", minimum=0.0, maximum=1.0, exclusive_maximum=True
        ),
        reference_displacement_m=sec.positive("reference_displacement_m"),
        exponent=sec.number("exponent", 1.0, minimum=0.0, exclusive_minimum=True, maximum=4),
    )


def _read_drift(sec: _Section) -> Drift:
    return Drift(
        modulus_change_per_hour=sec.number(
            "modulus_change_per_hour", minimum=-0.5, maximum=0.5
        )
    )


def _read_temperature(sec: _Section) -> TemperatureShift:
    return TemperatureShift(
        reference_temperature_c=sec.number("reference_temperature_c", minimum=-100.0,
                                           maximum=300.0),
        c1=sec.number("c1", minimum=0.0, maximum=100.0),
        c2_k=sec.number("c2_k", minimum=0.0, exclusive_minimum=True, maximum=1000.0),
    )


def _read_payne(sec: _Section) -> Payne:
    return Payne(
        storage_drop_n_per_m=sec.non_negative("storage_drop_n_per_m"),
        loss_peak_n_per_m=sec.non_negative("loss_peak_n_per_m"),
        critical_displacement_m=sec.positive("critical_displacement_m"),
        exponent=sec.number("exponent", 0.6, minimum=0.0, exclusive_minimum=True,
                            maximum=4.0),
    )


def _read_frame(sec: _Section) -> Frame:
    return Frame(
        mass_kg=sec.positive("mass_kg"),
        frequency_hz=sec.positive("frequency_hz"),
        damping_ratio=_read_damping_ratio(sec, "damping_ratio"),
    )


def _read_specimen(sec: _Section) -> Specimen:
    return Specimen(
        hardness_shore_a=sec.number("hardness_shore_a", required=False, minimum=0.0,
                                    maximum=100.0),
        preload_strain=sec.number("preload_strain", required=False, minimum=0.0,
                                  maximum=1.0, exclusive_maximum=True),
        count=sec.integer("count", minimum=1),
        diameter_m=sec.optional_positive("diameter_m"),
        height_m=sec.optional_positive("height_m"),
    )


def _read_chamber(sec: _Section) -> ChamberParameters:
    from rigsim.chamber import ChamberParameters

    return ChamberParameters(
        heating_rate_k_per_min=sec.positive("heating_rate_k_per_min", 5.0),
        cooling_rate_k_per_min=sec.positive("cooling_rate_k_per_min", 3.0),
        air_time_constant_s=sec.positive("air_time_constant_s", 60.0),
        specimen_time_constant_s=sec.positive("specimen_time_constant_s", 420.0),
        start_temperature_c=sec.number("start_temperature_c", 25.0, minimum=-70.0,
                                       maximum=180.0),
    )


def parse_rig(text: str, source: str = "<string>") -> Rig:
    """Read a rig description from TOML text.

    Parameters
    ----------
    text
        The TOML document.
    source
        Name used in error messages (a file name).

    Returns
    -------
    Rig

    Raises
    ------
    RigFileError
        Syntax errors, unknown keys, missing or mistyped values, non-physical values; the
        message names ``source`` and the key path.
    """
    try:
        data = tomllib.loads(text.removeprefix("\ufeff"))  # a BOM (Notepad's UTF-8) is no text
    except tomllib.TOMLDecodeError as exc:
        raise RigFileError(f"{source}: not valid TOML: {exc}") from None
    top = _Section(data, "", source)
    name = top.string("name", "")
    description = top.string("description", "")
    table = _read_section(top, "table", _read_table)
    if table is None:
        raise top.error("missing section [table]", "table")
    device = _read_section(top, "device", _read_device)
    load_cell = _read_section(top, "load_cell", _read_load_cell)
    if load_cell is not None and device is None:
        raise top.error("a load cell needs a [device] to link to the table", "load_cell")
    fixtures = _read_fixtures(top, device is not None)
    parts = dict(
        sensors=_read_section(top, "sensors", _read_sensors, Sensors()),
        shaker=_read_section(top, "shaker", _read_shaker, Shaker()),
        noise=_read_section(top, "noise", _read_noise),
        delays=_read_section(top, "delays", _read_delays, Delays()),
        amplitude=_read_section(top, "amplitude", _read_amplitude),
        drift=_read_section(top, "drift", _read_drift),
        temperature=_read_section(top, "temperature", _read_temperature),
        chamber=_read_section(top, "chamber", _read_chamber),
        payne=_read_section(top, "payne", _read_payne),
        frame=_read_section(top, "frame", _read_frame),
        specimen=_read_section(top, "specimen", _read_specimen, Specimen()),
    )
    top.finish()
    return Rig(table=table, device=device, load_cell=load_cell, fixtures=fixtures, **parts,
               name=name, description=description, source=source)


def load_rig(path: str | Path) -> Rig:
    """Read a rig file.

    Raises
    ------
    RigFileError
        The file cannot be read or is not a valid rig description (see :func:`parse_rig`).
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise RigFileError(f"{path}: cannot read rig file: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise RigFileError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    return parse_rig(text, source=str(path))


def preset_names() -> list[str]:
    """Names of the shipped rig presets (``table``, ``soft-0``, ...), sorted."""
    folder = resources.files("rigsim.rigs")
    return sorted(
        entry.name.removesuffix(".toml")
        for entry in folder.iterdir()
        if entry.name.endswith(".toml")
    )


def load_preset(name: str) -> Rig:
    """Read a shipped preset by name (see :func:`preset_names`).

    Raises
    ------
    RigFileError
        No preset of that name.
    """
    names = preset_names()
    if name not in names:
        raise RigFileError(f"no rig preset {name!r}; presets: {', '.join(names)}")
    entry = resources.files("rigsim.rigs").joinpath(f"{name}.toml")
    return parse_rig(entry.read_text(encoding="utf-8"), source=f"preset {name} ({name}.toml)")
