"""The effect terms: what a K* model alone leaves out of the rig's FRFs.

Each term is one physical effect of the design's vocabulary (design.md, "Identification and
diagnosis"), with named parameters, bounds and units, and takes part in one stage of the
evaluation pipeline (:mod:`viscorig.models.base`):

========== =================== ==================================================================
term       stage               what it adds
========== =================== ==================================================================
amplitude  modify_modulus      ``K* · (x/x_ref)^(−β)``, ``x`` the displacement amplitude
kraus      modify_modulus      ``K* + K_f(x)``: the filler network of Kraus's Payne-effect model
drift      modify_modulus      ``K* · (1 + κ t)``, ``t`` the test time ``time_s``
temperature modify_modulus     ``K* · exp(γ (T − T_ref))``, ``T`` the recorded ``temperature_c``
fixture    disc_stiffness      a local mode (mass ``m`` on a spring-damper) attached to the disc
load_cell  couple              the two-DOF coupling of physics.md with a finite ``K_c``
frame      frame               the inertial frame under the table, a mass on its isolators
========== =================== ==================================================================

The measuring chain's effects (``delay``, ``gain``, ``highpass``, ``lowpass`` on one channel) are
in :mod:`viscorig.models.sensors`.

A modifier's covariate (``time_s``, ``reference_amplitude``, ``temperature_c``) is required of
the data a model is fitted to; without it (K* on a plot's grid, at one frequency) each modifier
gives K* at its reference: ``drift`` at ``t = 0``, ``amplitude`` at 10 µm, ``kraus`` at vanishing
amplitude, ``temperature`` at ``T_ref``.

Terms whose start cannot come from defaults (a fixture's frequency, the load cell's stiffness)
also give a start from the measured FRFs (:meth:`start_from_data`), so that
``identify --model voigt+fixture`` needs no guess either.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.frf import accelerance_to_dynamic_stiffness
from viscorig.models.base import (
    Context,
    Model,
    Parameter,
    Term,
    register_term,
    table_dynamic_stiffness,
)

#: Reference displacement amplitude of the ``amplitude`` term (m): K* parameters of a model with
#: that term are the values at this amplitude (10 µm, mid-range of the paper's sweeps).
AMPLITUDE_REFERENCE_M = 1e-5

#: Half-width of the frequency range of ``fixture(F)``, relative to ``F``.
FIXTURE_WINDOW = 0.05


def displacement_amplitude(ctx: Context) -> NDArray[np.float64]:
    """Disc displacement amplitude ``|ẍ_v|/ω²`` (m) from the measured reference acceleration."""
    if ctx.reference_amplitude is None:
        raise InputError("the amplitude term needs reference_amplitude", "model spec")
    return np.maximum(np.abs(ctx.reference_amplitude), 1e-300) / ctx.omega**2


@register_term
class LoadCell(Term):
    """Finite load-cell (linkage) stiffness ``K_c`` between table and disc (physics.md).

    Replaces the rigid link: with ``D_s = D_t + K_c`` and ``D_v' = K_c + D_v``,
    ``X_s/F_e = D_v'/(D_s D_v' − K_c²)`` and ``X_v/F_v = 1/D_v`` (exact whatever ``K_c``).
    """

    keyword = "load_cell"

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter("K_c", "N/m", 1e3, 1e13, 1e9, description="load cell and linkage stiffness"),
        )

    def link_stiffness(self, p):
        return p["K_c"]

    def couple(self, ctx, p, d_table, d_disc):
        k_c = p["K_c"]
        # X_s/F_e = 1/(D_t + K_c D_v/(K_c + D_v)), written to stay exact as K_c grows.
        series = d_disc / (1.0 + d_disc / k_c)
        return {"table": 1.0 / (d_table + series), "support": 1.0 / d_disc}

    def couple_derivatives(self, ctx, p, d_table, d_disc):
        # With q = 1/(1 + D_v/K_c) the series stiffness is D_v q:
        # ∂/∂D_v = q², ∂/∂K_c = (D_v q/K_c)².
        k_c = p["K_c"]
        q = 1.0 / (1.0 + d_disc / k_c)
        table = 1.0 / (d_table + d_disc * q)
        support = 1.0 / d_disc
        return {
            "table": {"d_table": -(table**2), "d_disc": -((table * q) ** 2),
                      "K_c": -((table * d_disc * q / k_c) ** 2)},
            "support": {"d_table": np.zeros_like(support), "d_disc": -(support**2),
                        "K_c": np.zeros_like(support)},
        }

    def start_from_data(
        self,
        model: Model,
        ctx: Context,
        values: Mapping[str, float],
        measured: Mapping[str, NDArray[np.complex128]],
    ) -> dict[str, float]:
        """``1/K_c = 1/(F_e/X_s − D_t) − X_v/F_v`` at every point, when both FRFs are fitted."""
        estimate = compliance_estimate(ctx, values, measured)
        if estimate is None or not np.isfinite(estimate[0]) or estimate[0] <= 0:
            return {}
        return {"K_c": 1.0 / estimate[0]}


def compliance_estimate(
    ctx: Context,
    values: Mapping[str, float],
    measured: Mapping[str, NDArray[np.complex128]],
) -> tuple[float, float] | None:
    """Direct estimate of the load cell's compliance ``1/K_c`` (m/N) and its standard error.

    Eq. (4) gives the series stiffness ``D_eff = F_e/X_s − D_t``, Eq. (5) the disc's own
    ``D_v = F_v/X_v``; a rigid link makes them equal, a finite ``K_c`` makes
    ``1/D_eff − 1/D_v = 1/K_c``. ``None`` without both FRFs or the table's parameters.
    """
    if "table" not in measured or "support" not in measured:
        return None
    if not all(name in values for name in ("M_s", "K_s", "C_s")):
        return None
    with np.errstate(all="ignore"):
        z_table = accelerance_to_dynamic_stiffness(ctx.frequency_hz, measured["table"])
        z_support = accelerance_to_dynamic_stiffness(ctx.frequency_hz, measured["support"])
        d_table = table_dynamic_stiffness(ctx.omega, values)
        compliance = (1.0 / (z_table - d_table) - 1.0 / z_support).real
    compliance = compliance[np.isfinite(compliance)]
    if compliance.size < 8:
        return None
    centre = float(np.median(compliance))
    spread = 1.4826 * float(np.median(np.abs(compliance - centre)))
    return centre, spread / np.sqrt(compliance.size)


@register_term
class Fixture(Term):
    """A local mode attached to the disc: mass ``m`` on a spring-damper tuned to ``f_n``.

    Adds ``−ω² m (k + iωc) / (k + iωc − ω² m)`` to the disc's dynamic stiffness, with
    ``k = m (2π f_n)²`` and ``c = 2 ζ m (2π f_n)``. ``fixture`` lets the fit find the
    frequency (started at the largest narrow residual peak); ``fixture(F)`` keeps ``f_n``
    within ±5 % of ``F`` Hz.
    """

    keyword = "fixture"
    repeatable = True

    def __init__(self, argument: float | None = None) -> None:
        if argument is not None and not (np.isfinite(argument) and 0.1 <= argument <= 1e5):
            raise InputError(f"fixture(F) needs a frequency in Hz, got {argument}", "model spec")
        self.argument = argument

    def frequency_bounds(self) -> tuple[float, float]:
        """Range of ``f_n`` (Hz)."""
        if self.argument is None:
            return 0.1, 1e5
        return self.argument * (1 - FIXTURE_WINDOW), self.argument * (1 + FIXTURE_WINDOW)

    def parameters(self) -> tuple[Parameter, ...]:
        lo, hi = self.frequency_bounds()
        start = self.argument if self.argument is not None else 100.0
        return (
            Parameter("f_n", "Hz", lo, hi, start, description="natural frequency of the mode"),
            Parameter("zeta", "", 1e-4, 0.5, 0.02, description="damping ratio of the mode"),
            Parameter("m", "kg", 1e-8, 10.0, 1e-3, description="modal mass of the mode"),
        )

    def disc_stiffness(self, ctx, p):
        # −c (a + ib)/(a − c + ib) with a = m ω_n², b = 2ζ m ω_n ω, c = m ω², in real arithmetic:
        # (a + ib)/(a − c + ib) = (a (a − c) + b² − i b c)/((a − c)² + b²)
        w_n = 2 * np.pi * p["f_n"]
        a = p["m"] * w_n**2
        b = 2 * p["zeta"] * p["m"] * w_n * ctx.omega
        c = ctx.omega**2 * p["m"]
        detuned = a - c
        scale = -c / (detuned * detuned + b * b)
        return scale * (a * detuned + b * b) - 1j * (scale * b * c)

    def disc_stiffness_derivatives(self, ctx, p):
        # ΔD = −c u/(u − c), u = a + ib: ∂ΔD/∂u = c²/(u − c)², and ΔD is linear in m.
        w_n = 2 * np.pi * p["f_n"]
        m = p["m"]
        w = ctx.omega
        u = m * w_n**2 + 2j * p["zeta"] * m * w_n * w
        c = w**2 * m
        ratio = c / (u - c)
        by_u = ratio**2
        return {
            "f_n": by_u * (2 * np.pi) * (2 * m * w_n + 2j * p["zeta"] * m * w),
            "zeta": by_u * (2j * m * w_n * w),
            "m": -ratio * u / m,
        }

    def start_from_data(self, model, ctx, values, measured) -> dict[str, float]:
        """Put the mode at the largest narrow peak of the residual of the rest of the model."""
        names = model.local_names(self)
        rest = dict(values)
        rest[names["m"]] = 1e-12  # this mode off; every other term at its start
        try:
            predicted = model.predict(ctx, rest)
        except (InputError, FloatingPointError):
            return {}
        lo, hi = self.frequency_bounds()
        peaks = []
        for name, h in measured.items():
            with np.errstate(all="ignore"):
                ratio = np.log(h / predicted[name])
            peak = narrow_peak(ctx.frequency_hz, ratio, (lo, hi))
            if peak is not None:
                peaks.append((peak[1], peak[0], name))
        if not peaks:
            return {}
        height, frequency, name = max(peaks)
        return fixture_start(frequency, height, ctx, measured[name])


def fixture_start(
    frequency_hz: float, height: float, ctx: Context, accelerance: NDArray[np.complex128]
) -> dict[str, float]:
    """Start of a fixture mode from a residual peak of relative ``height`` at ``frequency_hz``.

    At resonance the mode adds ``|ΔD| ≈ ω_n² m / (2ζ)`` to a dynamic stiffness
    ``|D| = ω²/|H|``, so ``m ≈ 2 ζ height / |H(f_n)|`` with ``ζ`` started at 0.02.
    """
    zeta = 0.02
    i = int(np.argmin(np.abs(ctx.frequency_hz - frequency_hz)))
    mass = 2 * zeta * height / max(abs(accelerance[i]), 1e-300)
    return {"f_n": float(frequency_hz), "zeta": zeta, "m": float(np.clip(mass, 1e-7, 1.0))}


def narrow_peak(
    frequency_hz: NDArray[np.float64],
    log_ratio: NDArray[np.complex128],
    band_hz: tuple[float, float],
    width_hz: float = 8.0,
) -> tuple[float, float] | None:
    """The largest narrow feature of a complex log-ratio: ``(frequency_hz, relative height)``.

    The smooth part is a running median over ``width_hz``; what stands above it over a few
    points is a narrow feature. ``None`` if the band holds fewer than 8 points.
    """
    order = np.argsort(frequency_hz)
    f, r = frequency_hz[order], log_ratio[order]
    ok = np.isfinite(r)
    f, r = f[ok], r[ok]
    if f.size < 8:
        return None
    steps = np.diff(f)
    step = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 1.0
    half = int(np.clip(round(width_hz / step / 2), 3, max(f.size // 4, 3)))
    smooth = edge_held_median(r.real, half) + 1j * edge_held_median(r.imag, half)
    excess = np.abs(r - smooth)
    inside = (f >= band_hz[0]) & (f <= band_hz[1])
    if not np.any(inside):
        return None
    i = int(np.flatnonzero(inside)[np.argmax(excess[inside])])
    return float(f[i]), float(excess[i])


def edge_held_median(values: NDArray[np.float64], half: int) -> NDArray[np.float64]:
    """Median over ``±half`` points (shrinking at the ends), vectorised with a sliding window."""
    padded = np.pad(values, half, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    return np.median(windows, axis=1)


#: Masses an inertial frame under a vibration table may have, kg: at least the table's own
#: order (a frame lighter than the moving body is no inertial reference).
FRAME_MASS_KG = (1.0, 1e7)


@register_term
class Frame(Term):
    """The inertial frame under the table: its rigid-body mode on its isolators.

    The frame (mass ``M_f``) carries the shaker body, the table suspension and the specimens,
    and sits on isolators tuned to ``f_g`` with damping ratio ``ζ_g``: ``G = M_f (ω_g² +
    2iζ_g ω_g ω − ω²)`` to ground. On a rigid link the table FRF becomes
    ``X_s/F_e = 1/(A + P (1 + A/G))`` with ``A = −ω²(M_s + M_v)`` (plus what is attached to the
    disc) and ``P = K_s + iωC_s + K*`` (what connects the moving body to the frame); the frame
    moves by ``x_g = −A x/G``. Well above ``f_g``, ``A/G ≈ M/M_f``: every spring and dashpot
    to the frame reads ``M/M_f`` stiffer, which a model without the frame takes into ``K_s``,
    ``C_s`` and ``K*`` (the paper's table, 3.4 kg on a 2000 kg frame: ``K_s`` +0.17 %). Only the
    remainder, ``∝ (f_g/f)²``, tells the frame apart, so its mass is hardly identified from
    the data: ``frame(M)`` takes it as known (kg) and fits ``f_g`` and ``ζ_g``; ``frame`` fits
    all three, with the large, correlated ± that says what the data cannot tell.
    """

    keyword = "frame"

    def __init__(self, argument: float | None = None) -> None:
        low, high = FRAME_MASS_KG
        if argument is not None and not (np.isfinite(argument) and low <= argument <= high):
            raise InputError(f"frame(M) needs the frame's mass in kg, {low:g} to {high:g}, got "
                             f"{argument:g}", "model spec")
        self.argument = argument

    def parameters(self) -> tuple[Parameter, ...]:
        own = (
            Parameter("f_g", "Hz", 0.05, 100.0, 3.0, description="frame's mode on its isolators"),
            Parameter("zeta_g", "", 1e-3, 2.0, 0.1, description="damping of the frame's mode"),
        )
        if self.argument is not None:
            return own
        return (
            Parameter("M_f", "kg", *FRAME_MASS_KG, 1000.0,
                      description="mass of the inertial frame"),
            *own,
        )

    def frame(self, ctx, p):
        mass = self.argument if self.argument is not None else p["M_f"]
        w_g = 2 * np.pi * p["f_g"]
        return mass * (w_g**2 + 2j * p["zeta_g"] * w_g * ctx.omega - ctx.omega**2)


@register_term
class Amplitude(Term):
    """Stiffness against vibration amplitude: ``K* · (x / x_ref)^(−β)``.

    ``x = |ẍ_v|/ω²`` is the disc's displacement amplitude from the measured reference
    acceleration and ``x_ref`` is :data:`AMPLITUDE_REFERENCE_M` (10 µm), so ``β`` is the log-log
    slope of the modulus against amplitude (positive: softening, the Payne effect) and the K*
    parameters are the values at 10 µm. Separable from a frequency-dependent modulus only with
    runs at two or more levels: at constant acceleration ``x ∝ 1/f²``.
    """

    keyword = "amplitude"
    requires = ("reference_amplitude",)

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter(
                "beta", "", -0.5, 0.5, 0.0, log=False,
                description="log-log slope of the modulus against displacement amplitude",
            ),
        )

    def modify_modulus(self, ctx, p, kstar):
        if ctx.reference_amplitude is None:  # K* at the reference amplitude (module text)
            return kstar
        ratio = displacement_amplitude(ctx) / AMPLITUDE_REFERENCE_M
        return kstar * ratio ** (-p["beta"])


def kraus_stiffness(displacement_m: NDArray[np.float64], p: Mapping[str, float]
                    ) -> NDArray[np.complex128]:
    """The filler network's complex stiffness in Kraus's model of the Payne effect, N/m.

    ``K' = ΔK' / (1 + r^(2m))``, ``K'' = 2 ΔK''_m r^m / (1 + r^(2m))``, ``r = x / x_c``: the
    storage part falls from ``ΔK'`` (``K_f``) to zero as the amplitude grows past ``x_c``
    (``x_c``), the loss part peaks at ``ΔK''_m`` (``L_f``) at ``x_c``; ``m`` (``m_k``) sets
    how sharply.
    """
    r = (np.asarray(displacement_m, dtype=float) / p["x_c"]) ** p["m_k"]
    return np.asarray((p["K_f"] + 2j * p["L_f"] * r) / (1.0 + r * r), dtype=np.complex128)


#: The Kraus term's parameters (shared by the term and the strain identification).
KRAUS_PARAMETERS = (
    Parameter("K_f", "N/m", 1.0, 1e8, 1e4,
              description="stiffness of the filler network at small amplitude (ΔK')"),
    Parameter("L_f", "N/m", 1e-2, 1e8, 1e3,
              description="peak loss stiffness of the filler network, at x_c (ΔK''_m)"),
    Parameter("x_c", "m", 1e-8, 1e-2, 1e-4,
              description="displacement amplitude where the filler network breaks down"),
    Parameter("m_k", "", 0.1, 4.0, 0.6,
              description="Kraus exponent: how sharply the network breaks down"),
)


@register_term
class Kraus(Term):
    """The Payne effect of a filled rubber (Kraus): ``K* + K_f(x)``, :func:`kraus_stiffness`.

    ``x = |ẍ_v|/ω²`` as for ``amplitude``; the K* parameters are then the rubber's matrix alone
    (the filler network's stiffness at vanishing amplitude is ``K_f``). Like ``amplitude`` it is
    separable from the modulus' frequency dependence only with runs at several levels
    (:mod:`viscorig.strain` identifies it from the differences between them).
    """

    keyword = "kraus"
    requires = ("reference_amplitude",)

    def parameters(self) -> tuple[Parameter, ...]:
        return KRAUS_PARAMETERS

    def modify_modulus(self, ctx, p, kstar):
        if ctx.reference_amplitude is None:  # at vanishing amplitude (module text)
            return kstar + kraus_stiffness(np.zeros(ctx.omega.shape), p)
        return kstar + kraus_stiffness(displacement_amplitude(ctx), p)


@register_term
class Drift(Term):
    """Thermal drift: ``K* · (1 + κ t)``, ``t`` the test time ``time_s`` (s).

    ``κ`` in 1/s (−5.6e-6 /s is −2 % per hour); K* parameters are the values at ``t = 0``.
    """

    keyword = "drift"
    requires = ("time_s",)

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter(
                "kappa", "1/s", -1e-3, 1e-3, 0.0, log=False,
                description="relative change of the modulus per second of test time",
            ),
        )

    def modify_modulus(self, ctx, p, kstar):
        if ctx.time_s is None:  # K* at t = 0 (module text)
            return kstar
        return kstar * (1.0 + p["kappa"] * ctx.time_s)


@register_term
class Temperature(Term):
    """The specimen's recorded temperature: ``K* · exp(γ (T − T_ref))``.

    ``T`` is the temperature recorded at each point (a chamber run's ``temperature_c``, °C) and
    ``T_ref`` the term's argument (``temperature(0)``: K* parameters are the values at 0 °C; the
    run's set point in a diagnosis). ``γ`` in 1/K is the modulus' relative change per kelvin
    (negative: softening as it warms; a rubber near its transition loses several % per K). It
    explains a thermal drift from what was measured instead of inferring it from the test time,
    as ``drift`` does. Without a recorded temperature (a plot's smooth grid) K* is the value at
    ``T_ref``.
    """

    keyword = "temperature"
    requires = ("temperature_c",)

    def __init__(self, argument: float | None = None) -> None:
        if argument is None or not np.isfinite(argument) or not -273.15 < argument < 1000.0:
            raise InputError("the temperature term needs its reference temperature in °C, "
                             "e.g. temperature(25)", "model spec")
        self.argument = float(argument)

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter(
                "gamma", "1/K", -0.5, 0.5, 0.0, log=False,
                description="relative change of the modulus per kelvin of the recorded "
                            "specimen temperature",
            ),
        )

    def modify_modulus(self, ctx, p, kstar):
        if ctx.temperature_c is None:
            return kstar
        return kstar * np.exp(p["gamma"] * (ctx.temperature_c - self.argument))


#: Effect vocabulary of the design: effect name -> (term keyword, what is missing).
EFFECTS: dict[str, tuple[str, str]] = {
    "frequency_dependent_modulus": (
        "maxwell",
        "the rubber's stiffness and damping change with frequency",
    ),
    "load_cell_compliance": (
        "load_cell",
        "the link between table and device is not rigid (Eq. 1 not reduced)",
    ),
    "fixture_resonance": ("fixture", "a local mode of the linkage or device"),
    "frame_mode": (
        "frame",
        "the inertial frame under the table moves on its isolators (its rigid-body mode)",
    ),
    "sensor_delay": ("delay", "a time delay or low-pass lag on one channel"),
    "sensor_highpass": ("highpass", "a high-pass filter (charge amplifier) on one channel"),
    "sensor_gain": ("gain", "a channel's sensitivity differs from the one its data assume"),
    "amplitude_dependence": ("amplitude", "stiffness depends on vibration amplitude"),
    "thermal_drift": ("drift", "the modulus drifts during the run"),
}


