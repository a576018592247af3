"""Held-out cases for diagnosis, measured on the time-domain rig simulator.

Every case is a rig with one planted effect (or none), swept as the paper does (20-120 Hz in
0.25 Hz steps, 100 settle and 100 integration cycles, the disc held at 1 m/s²) by ``rigsim``,
which integrates the equations of motion and correlates each channel like the analyser. This
module imports ``rigsim`` and numpy only: nothing of the identification core makes or touches
the data, so a diagnosis that names the planted effect found it in data it did not make.

Effects and their strengths (the planted size, in steps of about √10; each on every channel
where it applies):

============= ============================= ======================================================
effect        strengths                     planted as
============= ============================= ======================================================
delay         0.1 to 30 µs                  ``[delays]`` of one channel
lowpass       lag 0.1 to 30 µs              ``[sensors.<channel>] lowpass_hz = 1/(2π lag)``
highpass      0.001 to 0.3 Hz               ``[sensors.<channel>] highpass_hz``
gain          0.01 to 3 %                   ``[sensors.<channel>] gain = 1 + strength``
fixture       0.01 to 1 g                   a local mode at 47 or 83 Hz, ζ = 0.02
load_cell     K*/K_c 0.003 to 1 %           ``[load_cell]`` with ``K_c = 1.5e5 N/m / strength``
modulus       0.03 to 10 %                  a fractional rubber whose K' rises by it over the band
amplitude     0.03 to 10 %                  Payne softening of K* at 10 µm (about the disc's
                                            displacement at 49 Hz); a second run at twice the level
drift         0.01 to 3 % per hour          a down sweep after the up sweep, on one clock
clean         none                          the base rig alone
============= ============================= ======================================================

The base rig is the paper's table with a Voigt specimen (1.5·10⁵ N/m, 114.59 N·s/m, disc
0.25 kg) on a rigid link, diagnosed from ``voigt``; the paper-like clean cases are the rig
presets, diagnosed from the model each preset is made of.

Noise (``noise_level`` is the rms relative error of the FRFs, the noise floor of the design):

- ``white``: the simulator's sensor noise, its densities scaled so that the FRFs' rms relative
  error is the level;
- ``correlated``: half of that variance white, half the simulator's drift of every
  transducer's sensitivity (``[noise] sensitivity_drift_rms``, Gauss-Markov in test time with a
  correlation time of 60 s, so neighbouring points err alike: amplifiers warming, a charge
  amplifier drifting);
- ``heavy``: the white noise, plus the simulator's interference bursts: a point is disturbed
  with probability 2 %, its noise ten times larger on every channel (outlier points).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import Rig, load_preset, parse_rig

#: Spec names of the channels and the rig-file names of them.
CHANNELS = {"F_e": "excitation_force", "x_s": "table_acceleration",
            "F_v": "device_force", "x_v": "disc_acceleration"}
FORCE_V_PER_N = 0.01124
ACCELERATION_V_PER_M_S2 = 0.0102
TABLE = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}
BASE_STIFFNESS = 1.5e5
BASE_DEVICE = f"""
[device]
mass_kg = 0.25
model = "voigt"
stiffness_n_per_m = {BASE_STIFFNESS}
damping_ns_per_m = 114.59
"""
TABLE_TEXT = """
[table]
mass_kg = 3.4
stiffness_n_per_m = 50194.0
damping_ns_per_m = 5.05
"""
#: Relative noise densities of the four channels (forces ten times the accelerations, in SI).
NOISE_PATTERN = (2e-3, 2e-4, 2e-3, 2e-4)
NOISE_TYPES = ("white", "correlated", "heavy")
NOISE_LEVELS = (0.003, 0.01)
#: Correlation time of the sensitivity drift of correlated noise (s).
DRIFT_TIME_S = 60.0
#: Probability of an interference burst per point, and its noise factor (heavy-tailed noise).
BURST_PROBABILITY, BURST_FACTOR = 0.02, 10.0

#: effect -> (vocabulary name, channels it applies to, strengths, unit of the strengths)
EFFECTS: dict[str, tuple[str, tuple[str | None, ...], tuple[float, ...], str]] = {
    "delay": ("sensor_delay", tuple(CHANNELS), (1e-7, 3e-7, 1e-6, 3e-6, 1e-5, 3e-5), "s"),
    "lowpass": ("sensor_delay", tuple(CHANNELS), (1e-7, 3e-7, 1e-6, 3e-6, 1e-5, 3e-5), "s lag"),
    "highpass": ("sensor_highpass", tuple(CHANNELS), (1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3), "Hz"),
    "gain": ("sensor_gain", tuple(CHANNELS), (1e-4, 3e-4, 1e-3, 3e-3, 0.01, 0.03), "relative"),
    "fixture": ("fixture_resonance", (None,), (1e-5, 3e-5, 1e-4, 3e-4, 1e-3), "kg"),
    "load_cell": ("load_cell_compliance", (None,), (3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2),
                  "K*/K_c"),
    "modulus": ("frequency_dependent_modulus", (None,), (3e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1),
                "relative"),
    "amplitude": ("amplitude_dependence", (None,), (3e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1),
                  "relative"),
    "drift": ("thermal_drift", (None,), (1e-4, 3e-4, 1e-3, 3e-3, 0.01, 0.03), "per hour"),
}
#: The paper-like presets, and the model each is made of (diagnosed from it when clean): a
#: fractional rubber, the load cell, three local modes, and the 2000 kg frame under the table.
PRESET_MODELS = {
    name: "fractional+load_cell+fixture(38)+fixture(58)+fixture(92)+frame(2000)"
    for name in ("soft-0", "soft-10", "medium-0", "medium-10", "hard-0", "hard-10")
}


@dataclass(frozen=True)
class Run:
    """One measured run, in the units of a campaign file."""

    name: str
    frequency_hz: np.ndarray
    time_s: np.ndarray
    table: np.ndarray
    support: np.ndarray
    reference_amplitude: np.ndarray
    level_m_per_s2: float
    direction: str
    true_noise: float
    """rms over both FRFs of ``H_measured/H_noiseless − 1``: the noise this run really has."""
    variance_table: np.ndarray | None = None
    """The analyser's normalized variance of each FRF (both channels' summed), as the 35670A
    reports it with every point."""
    variance_support: np.ndarray | None = None


@dataclass(frozen=True)
class Case:
    """A held-out case: what is planted, the noise, and the model to diagnose from."""

    effect: str
    channel: str | None
    strength: float
    noise_type: str
    noise_level: float
    seed: int
    base: str = "voigt"
    fixture_hz: float = 47.0
    extra_effects: tuple[tuple[str, str | None, float], ...] = field(default=())

    @property
    def name(self) -> str:
        where = f"-{self.channel}" if self.channel else ""
        size = "" if self.effect == "clean" else f"-{self.strength:g}"
        return (f"{self.base}-{self.effect}{where}{size}-{self.noise_type}-"
                f"{self.noise_level * 100:g}%-s{self.seed}")

    @property
    def vocabulary(self) -> str | None:
        """The effect diagnosis should name (``None`` for a clean case)."""
        return EFFECTS[self.effect][0] if self.effect in EFFECTS else None

    @property
    def model(self) -> str:
        """Spec of the model the base rig is made of (what diagnosis starts from)."""
        return "voigt" if self.base == "voigt" else PRESET_MODELS[self.base]


def _fractional_device(rise: float) -> str:
    """A fractional rubber whose K' rises by ``rise`` from 20 to 120 Hz, K'(49 Hz) = 1.5e5."""
    tau, alpha = 1.0 / (2 * math.pi * 2000.0), 0.5

    def storage(k_0: float, k_inf: float, f: float) -> float:
        s = (2j * math.pi * f * tau) ** alpha
        return float(((k_0 + k_inf * s) / (1 + s)).real)

    lo, hi = 1.0, 1e4
    for _ in range(100):  # bisection on K_inf/K_0 for the rise
        ratio = math.sqrt(lo * hi)
        change = storage(1.0, ratio, 120.0) / storage(1.0, ratio, 20.0) - 1
        lo, hi = (ratio, hi) if change < rise else (lo, ratio)
    k_0 = BASE_STIFFNESS / storage(1.0, ratio, 49.0)
    return f"""
[device]
mass_kg = 0.25
model = "fractional"
static_stiffness_n_per_m = {k_0:.6g}
high_stiffness_n_per_m = {k_0 * ratio:.6g}
tau_s = {tau:.6g}
alpha = {alpha}
"""


def _effect_lines(effect: str, channel: str | None, strength: float, case: Case) -> str:
    key = CHANNELS.get(channel or "", "")
    if effect == "delay":
        return f"[delays]\n{key}_s = {strength!r}\n"
    if effect == "lowpass":
        return f"[sensors.{key}]\nlowpass_hz = {1 / (2 * math.pi * strength)!r}\n"
    if effect == "highpass":
        return f"[sensors.{key}]\nhighpass_hz = {strength!r}\n"
    if effect == "gain":
        return f"[sensors.{key}]\ngain = {1 + strength!r}\n"
    if effect == "fixture":
        return (f"[[fixture]]\nfrequency_hz = {case.fixture_hz!r}\ndamping_ratio = 0.02\n"
                f"mass_kg = {strength!r}\n")
    if effect == "load_cell":
        return f"[load_cell]\nstiffness_n_per_m = {BASE_STIFFNESS / strength!r}\n"
    if effect == "amplitude":
        # softening `strength` at the displacement of 1 m/s² at 49 Hz (about 10 µm)
        return (f"[amplitude]\nsoftening_fraction = {2 * strength!r}\n"
                "reference_displacement_m = 1.05e-5\n")
    if effect == "drift":
        return f"[drift]\nmodulus_change_per_hour = {-strength!r}\n"
    return ""


def rig_text(case: Case) -> str:
    """The rig file of a case (the base rig with its effects planted)."""
    if case.base != "voigt":
        return ""
    planted = [(case.effect, case.channel, case.strength), *case.extra_effects]
    device = BASE_DEVICE
    lines = []
    sensors: dict[str, list[str]] = {}
    for effect, channel, strength in planted:
        if effect == "modulus":
            device = _fractional_device(strength)
            continue
        text = _effect_lines(effect, channel, strength, case)
        if text.startswith("[sensors."):  # merge several settings of one channel
            head, _, body = text.partition("\n")
            sensors.setdefault(head, []).append(body)
        else:
            lines.append(text)
    lines += [head + "\n" + "".join(bodies) for head, bodies in sensors.items()]
    return TABLE_TEXT + device + "".join(lines)


def _rig(case: Case, noise_scale: float, extra_noise: bool = True) -> Rig:
    rig = parse_rig(rig_text(case), case.name) if case.base == "voigt" else load_preset(case.base)
    densities = [noise_scale * p for p in NOISE_PATTERN]
    noise = f"""
[noise]
excitation_force_n_per_sqrt_hz = {densities[0]!r}
table_acceleration_m_per_s2_per_sqrt_hz = {densities[1]!r}
device_force_n_per_sqrt_hz = {densities[2]!r}
disc_acceleration_m_per_s2_per_sqrt_hz = {densities[3]!r}
adc_noise_db_re_range_per_sqrt_hz = -200.0
"""
    if extra_noise and case.noise_type == "correlated":
        # two channels per FRF: each drifting by level/2 gives the FRF half the level's variance
        noise += (f"sensitivity_drift_rms = {case.noise_level / 2!r}\n"
                  f"sensitivity_drift_time_s = {DRIFT_TIME_S!r}\n")
    elif extra_noise and case.noise_type == "heavy":
        noise += (f"burst_probability = {BURST_PROBABILITY!r}\n"
                  f"burst_factor = {BURST_FACTOR!r}\n")
    if noise_scale == 0:
        return replace(rig, noise=None)
    return replace(rig, noise=parse_rig(TABLE_TEXT + noise).noise)


def _sweep(simulator: RigSimulator, level: float, direction: str):
    frequency = np.arange(20.0, 120.0 + 0.125, 0.25)
    if direction == "down":
        frequency = frequency[::-1]
    rig = simulator.rig
    control = SourceControl(
        source_vpk=0.05, auto_level=True, reference_channel=4,
        reference_vpk=level * ACCELERATION_V_PER_M_S2, tolerance_db=0.5,
        source_limit_vpk=rig.shaker.force_limit_n / rig.shaker.force_n_per_v,
    )
    return simulator.sweep(SweepRequest(frequency, 100 / frequency, 100 / frequency, control))


def _frfs(volts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    force_e = volts[:, 0] / FORCE_V_PER_N
    accel_s = volts[:, 1] / ACCELERATION_V_PER_M_S2
    force_v = volts[:, 2] / FORCE_V_PER_N
    accel_v = volts[:, 3] / ACCELERATION_V_PER_M_S2
    return accel_s / force_e, accel_v / force_v


def _plan(case: Case) -> list[tuple[str, float, str]]:
    """Runs of a case: (name, level, direction), the main run first, on one clock."""
    runs = [("run", 1.0, "up")]
    effects = {case.effect, *(e for e, _, _ in case.extra_effects)}
    if "amplitude" in effects:
        runs.append(("run-level2", 2.0, "up"))
    if "drift" in effects:
        runs.append(("run-down", 1.0, "down"))
    return runs


def _noise_scale(case: Case, white_share: float) -> float:
    """Density scale that makes the white noise's rms relative FRF error ``white_share`` of
    the level, read from the analyser's own normalized variance of a unit-scale sweep."""
    return case.noise_level * math.sqrt(white_share) / _unit_floor(
        replace(case, seed=0, noise_type="white", noise_level=1.0))


@lru_cache(maxsize=256)
def _unit_floor(case: Case) -> float:
    """rms relative FRF error of a sweep at unit noise scale (the same for every seed)."""
    probe = RigSimulator(_rig(case, 1.0, extra_noise=False), seed=0)
    v = _sweep(probe, 1.0, "up").variance
    return float(np.sqrt(np.mean(np.concatenate([v[:, 0] + v[:, 1], v[:, 2] + v[:, 3]]))))


def measure(case: Case) -> list[Run]:
    """Sweep a case's runs (main run first) and return them as a campaign would hold them."""
    white_share = 0.5 if case.noise_type == "correlated" else 1.0
    scale = _noise_scale(case, white_share)
    simulator = RigSimulator(_rig(case, scale), seed=case.seed)
    quiet = RigSimulator(_rig(case, 0.0))
    runs = []
    for name, level, direction in _plan(case):
        record = _sweep(simulator, level, direction)
        clean = _sweep(quiet, level, direction)
        volts = record.channel_v
        table, support = _frfs(volts)
        clean_table, clean_support = _frfs(clean.channel_v)
        error = np.concatenate([table / clean_table - 1, support / clean_support - 1])
        v = record.variance
        runs.append(Run(
            name, record.frequency_hz, record.end_time_s, table, support,
            np.abs(volts[:, 3] / ACCELERATION_V_PER_M_S2), level, direction,
            float(np.sqrt(np.mean(np.abs(error) ** 2))), v[:, 0] + v[:, 1], v[:, 2] + v[:, 3],
        ))
    return runs


def detection_cases(
    noise_types: Sequence[str] = NOISE_TYPES,
    noise_levels: Sequence[float] = NOISE_LEVELS,
    seeds: Sequence[int] = range(10),
    effects: Sequence[str] = tuple(EFFECTS),
) -> Iterator[Case]:
    """Every effect at every strength on every channel where it applies."""
    for effect in effects:
        _, channels, strengths, _ = EFFECTS[effect]
        for channel in channels:
            for strength in strengths:
                for noise_type in noise_types:
                    for level in noise_levels:
                        for seed in seeds:
                            fixture_hz = 47.0 if seed % 2 == 0 else 83.0
                            yield Case(effect, channel, strength, noise_type, level, seed,
                                       fixture_hz=fixture_hz)


def clean_cases(
    noise_types: Sequence[str] = NOISE_TYPES,
    noise_levels: Sequence[float] = NOISE_LEVELS,
    seeds: Sequence[int] = range(50),
    bases: Sequence[str] = ("voigt",),
) -> Iterator[Case]:
    """Cases with nothing planted."""
    for base in bases:
        for noise_type in noise_types:
            for level in noise_levels:
                for seed in seeds:
                    yield Case("clean", None, 0.0, noise_type, level, seed, base=base)
