"""The K* terms: bare table, Voigt, generalized Maxwell, fractional Zener.

Each term gives the specimens' complex stiffness ``K*(ω)`` (physics.md, "Models of K*") and a
start of its parameters that needs no user guess: ``D_v = K* − ω² M_v`` is linear in the
stiffness-like parameters and in ``M_v`` once the relaxation times (Maxwell) or ``τ, α``
(fractional) are fixed, so a linear or non-negative least-squares solve gives the start.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares, nnls

from viscorig.errors import InputError
from viscorig.models.base import Context, ModulusTerm, Parameter, Term, register_term

#: Highest Maxwell order the fitter tries when the spec leaves the order open.
MAXWELL_MAX_ORDER = 5


def _stack(columns: NDArray[np.complex128], target: NDArray[np.complex128], weight: NDArray):
    """Real system ``A x ≈ b`` from complex columns, rows weighted, columns scaled to unit norm."""
    a = np.concatenate([columns.real, columns.imag]) * np.concatenate([weight, weight])[:, None]
    b = np.concatenate([target.real, target.imag]) * np.concatenate([weight, weight])
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    return a / scale, b, scale


@register_term
class TableOnly(ModulusTerm):
    """The bare table, no specimen: ``K* = 0`` and no disc (fits ``M_s K_s C_s``)."""

    keyword = "table"
    has_disc = False

    def modulus(self, ctx: Context, p: Mapping[str, float]) -> NDArray[np.complex128]:
        return np.zeros(ctx.omega.shape, dtype=complex)

    def modulus_derivatives(self, ctx: Context, p: Mapping[str, float]) -> dict[str, NDArray]:
        return {}

    def start(self, omega, d_disc, weight) -> dict[str, float]:
        return {}


@register_term
class Voigt(ModulusTerm):
    """Voigt: ``K* = K_v + iω C_v`` (with the disc mass ``M_v``, three parameters)."""

    keyword = "voigt"

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter("K_v", "N/m", 1e-3, 1e10, 1e5, description="specimen stiffness"),
            Parameter("C_v", "N·s/m", 1e-6, 1e6, 100.0, description="specimen damping"),
        )

    def modulus(self, ctx: Context, p: Mapping[str, float]) -> NDArray[np.complex128]:
        return np.asarray(p["K_v"] + 1j * ctx.omega * p["C_v"], dtype=np.complex128)

    def modulus_derivatives(self, ctx: Context, p: Mapping[str, float]) -> dict[str, NDArray]:
        return {"K_v": np.ones(ctx.omega.shape, dtype=complex), "C_v": 1j * ctx.omega}

    def start(self, omega, d_disc, weight) -> dict[str, float]:
        columns = np.stack([np.ones_like(omega), 1j * omega, -(omega**2)], axis=1).astype(complex)
        a, b, scale = _stack(columns, d_disc, weight)
        k_v, c_v, m_v = np.linalg.lstsq(a, b, rcond=None)[0] / scale
        return {"K_v": k_v, "C_v": c_v, "M_v": m_v}


@register_term
class Maxwell(ModulusTerm):
    """Generalized Maxwell, Eq. (10): ``K* = K_0 + Σ iω K_i C_i / (K_i + iω C_i)``.

    ``maxwell(N)`` has ``N`` arms; plain ``maxwell`` leaves the order to the fitter, which tries
    1..:data:`MAXWELL_MAX_ORDER` arms and keeps the lowest BIC. Parameters ``K_0, K_1..K_N,
    C_1..C_N`` and the disc mass ``M_v`` (needed for both FRFs; Eq. (5) uses it too).
    """

    keyword = "maxwell"

    def __init__(self, argument: float | None = None) -> None:
        if argument is not None and not (1 <= argument <= 20 and argument == int(argument)):
            raise InputError(
                f"maxwell(N) needs a whole number of arms 1..20, got {argument}", "model spec"
            )
        self.argument = None if argument is None else int(argument)

    @property
    def order(self) -> int | None:
        """Number of arms, ``None`` while open."""
        return None if self.argument is None else int(self.argument)

    def candidates(self) -> list[Term] | None:
        if self.order is not None:
            return None
        return [Maxwell(n) for n in range(1, MAXWELL_MAX_ORDER + 1)]

    def parameters(self) -> tuple[Parameter, ...]:
        if self.order is None:  # open: the fitter expands it through candidates()
            return ()
        stiffness = [
            Parameter(f"K_{i}", "N/m", 1e-3, 1e11, 1e4, description=f"stiffness of arm {i}")
            for i in range(1, self.order + 1)
        ]
        damping = [
            Parameter(f"C_{i}", "N·s/m", 1e-8, 1e8, 10.0, description=f"damping of arm {i}")
            for i in range(1, self.order + 1)
        ]
        return (
            Parameter("K_0", "N/m", 1e-3, 1e10, 1e5, description="static stiffness"),
            *stiffness,
            *damping,
        )

    def arms(self, p: Mapping[str, float]) -> tuple[NDArray, NDArray]:
        """Arm stiffnesses and damping coefficients as arrays."""
        n = self.order or 0
        k = np.array([p[f"K_{i}"] for i in range(1, n + 1)])
        c = np.array([p[f"C_{i}"] for i in range(1, n + 1)])
        return k, c

    def modulus(self, ctx: Context, p: Mapping[str, float]) -> NDArray[np.complex128]:
        # Arm by arm, so that a parameter may also be an array of one value per point (a
        # Jacobian's parameter sets evaluated at once, viscorig.fitting.jacobian.predict_many).
        # K iωτ/(1 + iωτ) = K (x² + ix)/(1 + x²), x = ωτ: real arithmetic, no complex division
        storage = np.zeros_like(ctx.omega)
        loss = np.zeros_like(ctx.omega)
        for i in range(1, (self.order or 0) + 1):
            k = p[f"K_{i}"]
            x = ctx.omega * (p[f"C_{i}"] / k)
            share = k / (1.0 + x * x)
            storage = storage + share * (x * x)
            loss = loss + share * x
        return (p["K_0"] + storage) + 1j * loss

    def modulus_derivatives(self, ctx: Context, p: Mapping[str, float]) -> dict[str, NDArray]:
        # Arm i: iω k c / (k + iω c); ∂/∂k = (iωc)²/(k + iωc)², ∂/∂c = iω k²/(k + iωc)².
        k, c = self.arms(p)
        iwc = 1j * ctx.omega[:, None] * c[None, :]
        denominator = (k[None, :] + iwc) ** 2
        d_k = iwc**2 / denominator
        d_c = 1j * ctx.omega[:, None] * k[None, :] ** 2 / denominator
        derivatives = {"K_0": np.ones(ctx.omega.shape, dtype=complex)}
        for i in range(k.size):
            derivatives[f"K_{i + 1}"] = d_k[:, i]
            derivatives[f"C_{i + 1}"] = d_c[:, i]
        return derivatives

    def start(self, omega, d_disc, weight) -> dict[str, float]:
        taus, gains, k_0, m_v = _prony_for(omega, d_disc, weight)
        # An arm relaxing far below the band acts as a spring there: fold it into K_0.
        spring = taus > 30.0 / omega.min()
        k_0 += float(gains[spring].sum())
        log_tau = list(np.log(taus[~spring]))
        gain = list(gains[~spring])
        n = self.order or 1
        while len(gain) > n:  # merge the two closest neighbours, keeping total stiffness
            j = int(np.argmin(np.diff(log_tau)))
            total = gain[j] + gain[j + 1]
            log_tau[j] = (gain[j] * log_tau[j] + gain[j + 1] * log_tau[j + 1]) / total
            gain[j] = total
            del log_tau[j + 1], gain[j + 1]
        if not gain:
            centre = -np.log(np.sqrt(omega.min() * omega.max()))
            log_tau, gain = [centre], [max(k_0, 1.0) * 0.05]
        while len(gain) < n:  # split the strongest arm a factor 3 either way
            j = int(np.argmax(gain))
            log_tau[j : j + 1] = [log_tau[j] - np.log(3.0), log_tau[j] + np.log(3.0)]
            gain[j : j + 1] = [gain[j] / 2, gain[j] / 2]
        log_tau_array, k_0, gains_array, m_v = _refine_relaxation_times(
            omega, d_disc, weight, np.sort(np.array(log_tau))
        )
        values = {"K_0": k_0, "M_v": m_v}
        for i, (lt, g) in enumerate(zip(log_tau_array, gains_array, strict=True), start=1):
            g = max(g, 1e-3)  # an idle arm keeps its relaxation time
            values[f"K_{i}"] = g
            values[f"C_{i}"] = g * np.exp(lt)
        return values


def _refine_relaxation_times(
    omega: NDArray[np.float64],
    d_disc: NDArray[np.complex128],
    weight: NDArray[np.float64],
    log_tau: NDArray[np.float64],
) -> tuple[NDArray, float, NDArray, float]:
    """Variable projection: adjust ``log τ_i``, solving ``K_0, K_i, M_v`` linearly at each step.

    The residual is what the columns ``1, iωτ_i/(1+iωτ_i), −ω²`` (weighted, scaled to unit
    norm) leave of the weighted ``D_v`` samples; its Jacobian is Kaufman's,
    ``P⊥ (∂A/∂log τ_i) x_i``. Only products with the tall matrix and solves of the small Gram
    matrix are used, so every evaluation stays cheap on a busy machine. ``log τ`` stays within
    two decades of the band (bounded: an arm with ``τ → 0`` and a huge stiffness is a damper,
    a limit an unbounded search drifts into). Keeps the NNLS/merge result if the refined one
    has a negative stiffness or mass.
    """
    lo, hi = np.log(0.01 / omega.max()), np.log(100.0 / omega.min())
    rows = np.concatenate([weight, weight])
    target = np.concatenate([d_disc.real, d_disc.imag]) * rows
    state: dict[str, NDArray] = {}

    def project(lt: NDArray[np.float64]) -> NDArray[np.float64]:
        iwt = 1j * omega[:, None] * np.exp(lt)[None, :]
        columns = np.concatenate(
            [np.ones((omega.size, 1)), iwt / (1 + iwt), -(omega[:, None] ** 2)], axis=1
        )
        a = np.concatenate([columns.real, columns.imag]) * rows[:, None]
        scale = np.sqrt(np.einsum("ij,ij->j", a, a))
        scale[scale == 0] = 1.0
        a /= scale
        gram_inverse = np.linalg.pinv(a.T @ a, hermitian=True)
        x = gram_inverse @ (a.T @ target)
        state.update(lt=lt.copy(), a=a, gram_inverse=gram_inverse, iwt=iwt, x=x / scale)
        return a @ x - target

    def jacobian(lt: NDArray[np.float64]) -> NDArray[np.float64]:
        if "lt" not in state or not np.array_equal(state["lt"], lt):  # the solver passes a copy
            project(lt)
        a, gram_inverse, iwt = state["a"], state["gram_inverse"], state["iwt"]
        d_columns = iwt / (1 + iwt) ** 2 * state["x"][None, 1:-1]
        d_a = np.concatenate([d_columns.real, d_columns.imag]) * rows[:, None]
        return d_a - a @ (gram_inverse @ (a.T @ d_a))

    def solve(lt: NDArray[np.float64]) -> NDArray[np.float64]:
        project(lt)
        return state["x"]

    start = np.clip(log_tau, lo + 1e-6, hi - 1e-6)
    with np.errstate(all="ignore"):
        refined = least_squares(
            project, start, jac=jacobian, bounds=(lo, hi), ftol=1e-6, xtol=1e-6, max_nfev=20
        ).x
    x = solve(refined)
    if not np.all(np.isfinite(x)) or np.any(x < 0):
        # More arms than the data hold: the best non-negative solution at the refined or at the
        # starting τ (an arm whose gain goes to zero is idle, and the others fit as they can).
        feasible = []
        for lt in (refined, start):
            iwt = 1j * omega[:, None] * np.exp(lt)[None, :]
            columns = np.concatenate(
                [np.ones((omega.size, 1)), iwt / (1 + iwt), -(omega[:, None] ** 2)], axis=1
            )
            a, b, scale = _stack(columns, d_disc, weight)
            solution, norm = nnls(a, b, maxiter=50 * a.shape[1])
            feasible.append((norm, lt, solution / scale))
        _, refined, x = min(feasible, key=lambda item: item[0])
    return refined, float(x[0]), x[1:-1], float(x[-1])


#: The last Prony series and its inputs: an order search starts every order from the same one.
_LAST_PRONY: list[tuple[tuple[NDArray, ...], tuple[NDArray, NDArray, float, float]]] = []


def _prony_for(
    omega: NDArray[np.float64], d_disc: NDArray[np.complex128], weight: NDArray[np.float64]
) -> tuple[NDArray, NDArray, float, float]:
    """:func:`prony_nnls` of these samples, reused when the same samples come again."""
    inputs = (omega, d_disc, weight)
    for seen, series in _LAST_PRONY:
        if all(np.array_equal(a, b) for a, b in zip(seen, inputs, strict=True)):
            return series
    series = prony_nnls(omega, d_disc, weight)
    _LAST_PRONY[:] = [(tuple(np.array(a, copy=True) for a in inputs), series)]
    return series


def prony_nnls(
    omega: NDArray[np.float64],
    d_disc: NDArray[np.complex128],
    weight: NDArray[np.float64],
    per_decade: int = 8,
) -> tuple[NDArray, NDArray, float, float]:
    """Non-negative Prony series of ``D_v = K_0 + Σ g_j iωτ_j/(1+iωτ_j) − ω² M_v``.

    Relaxation times on a log grid two decades beyond the band on each side; ``K_0, g_j, M_v``
    all non-negative (NNLS). Neighbouring active grid points are merged into one arm
    (stiffness-weighted mean of ``log τ``).

    Returns
    -------
    taus, gains, k_0, m_v
        Relaxation times (s) and stiffnesses (N/m) of the merged arms, static stiffness, disc mass.
    """
    lo, hi = 0.01 / omega.max(), 100.0 / omega.min()
    grid = np.logspace(np.log10(lo), np.log10(hi), int(np.log10(hi / lo) * per_decade) + 1)
    iwt = 1j * omega[:, None] * grid[None, :]
    columns = np.concatenate(
        [np.ones((omega.size, 1)), iwt / (1 + iwt), -(omega[:, None] ** 2)], axis=1
    ).astype(complex)
    a, b, scale = _stack(columns, d_disc, weight)
    x = nnls(a, b, maxiter=50 * a.shape[1])[0] / scale
    k_0, gains, m_v = x[0], x[1:-1], x[-1]
    active = gains > 0
    taus, merged = [], []
    j = 0
    while j < grid.size:
        if not active[j]:
            j += 1
            continue
        run = j
        while run < grid.size and active[run]:
            run += 1
        g = gains[j:run]
        merged.append(g.sum())
        taus.append(np.exp(np.sum(g * np.log(grid[j:run])) / g.sum()))
        j = run
    return np.array(taus), np.array(merged), float(k_0), float(m_v)


#: A fractional K* whose transition lies this many decades outside the band is not resolved
#: (:meth:`Fractional.resolved`).
RESOLVED_DECADES = 4.0


@register_term
class Fractional(ModulusTerm):
    """Fractional Zener: ``K* = (K_0 + K_inf (iωτ)^α) / (1 + (iωτ)^α)``, four parameters."""

    keyword = "fractional"

    def parameters(self) -> tuple[Parameter, ...]:
        return (
            Parameter("K_0", "N/m", 1e-3, 1e10, 1e5, description="static (relaxed) stiffness"),
            Parameter("K_inf", "N/m", 1e-3, 1e12, 1e6, description="glassy (unrelaxed) stiffness"),
            Parameter("tau", "s", 1e-9, 1e3, 1e-3, description="relaxation time"),
            Parameter(
                "alpha", "", 0.01, 1.0, 0.5, log=False, description="fractional derivative order"
            ),
        )

    def modulus(self, ctx: Context, p: Mapping[str, float]) -> NDArray[np.complex128]:
        # (iωτ)^α = (ωτ)^α e^{iαπ/2}: a real power and one rotation, several times cheaper
        # than the complex power (ωτ > 0)
        alpha = p["alpha"]
        s = (ctx.omega * p["tau"]) ** alpha * np.exp(0.5j * np.pi * alpha)
        return (p["K_0"] + p["K_inf"] * s) / (1.0 + s)

    def resolved(self, omega: NDArray[np.float64], p: Mapping[str, float]) -> bool:
        """False where the transition ``ωτ = 1`` lies more than :data:`RESOLVED_DECADES`
        decades outside the band: there ``K* ≈ K_0 + (K_inf − K_0)(iωτ)^α`` (or its mirror
        above the transition), and only ``(K_inf − K_0) τ^α`` is determined."""
        reach = 10.0**RESOLVED_DECADES
        return bool(omega.max() * p["tau"] > 1.0 / reach and omega.min() * p["tau"] < reach)

    def modulus_derivatives(self, ctx: Context, p: Mapping[str, float]) -> dict[str, NDArray]:
        # s = (iωτ)^α: ∂s/∂τ = α s/τ, ∂s/∂α = s log(iωτ); ∂K*/∂s = (K_inf − K_0)/(1 + s)².
        log_iwt = np.log(ctx.omega * p["tau"]) + 0.5j * np.pi
        s = np.exp(p["alpha"] * log_iwt)
        d_s = (p["K_inf"] - p["K_0"]) / (1.0 + s) ** 2
        return {
            "K_0": 1.0 / (1.0 + s),
            "K_inf": s / (1.0 + s),
            "tau": d_s * p["alpha"] * s / p["tau"],
            "alpha": d_s * s * log_iwt,
        }

    def start(self, omega, d_disc, weight) -> dict[str, float]:
        """Grid over ``τ, α``; for each, ``(1+s) D_v = K_0 + K_inf s − ω² M_v (1+s)`` is linear.

        The grid only chooses the basin, so its 150 small problems are solved at once on at most
        about 200 of the samples (normal equations of unit-norm columns); the best point with
        positive stiffnesses and mass is then solved exactly on every sample.
        """
        lo, hi = 0.01 / omega.max(), 100.0 / omega.min()
        taus = np.logspace(np.log10(lo), np.log10(hi), 25)
        alphas = np.array([0.15, 0.3, 0.45, 0.6, 0.75, 0.9])
        tau_grid, alpha_grid = (g.ravel() for g in np.meshgrid(taus, alphas, indexing="ij"))

        def system(pick: slice, tau: NDArray, alpha: NDArray) -> tuple[NDArray, NDArray]:
            """Weighted real systems ``a x ≈ b``, one per ``(τ, α)``: grid x rows x 3."""
            w_pick = omega[pick]
            log_iwt = np.log(w_pick[None, :] * tau[:, None]) + 0.5j * np.pi
            s = np.exp(alpha[:, None] * log_iwt)  # (iωτ)^α
            rows = weight[pick][None, :] / np.abs(1.0 + s)
            columns = np.stack([np.ones_like(s), s, -(w_pick**2) * (1.0 + s)], axis=1)
            target = d_disc[pick][None, :] * (1.0 + s)
            a = np.concatenate([columns.real, columns.imag], axis=2) * np.concatenate(
                [rows, rows], axis=1
            )[:, None, :]
            b = np.concatenate([target.real * rows, target.imag * rows], axis=1)
            return a.transpose(0, 2, 1), b

        a, b = system(slice(None, None, max(1, omega.size // 200)), tau_grid, alpha_grid)
        scale = np.sqrt(np.einsum("gpk,gpk->gk", a, a))
        scale[scale == 0] = 1.0
        a = a / scale[:, None, :]
        gram = np.matmul(a.transpose(0, 2, 1), a)
        with np.errstate(all="ignore"):
            x = np.matmul(np.linalg.pinv(gram), np.matmul(a.transpose(0, 2, 1), b[:, :, None]))
            cost = np.sum((np.matmul(a, x)[:, :, 0] - b) ** 2, axis=1)
        feasible = np.all(x[:, :, 0] > 0, axis=1) & np.isfinite(cost)
        if np.any(feasible):
            j = int(np.argmin(np.where(feasible, cost, np.inf)))
            a_all, b_all = system(slice(None), tau_grid[j : j + 1], alpha_grid[j : j + 1])
            k_0, k_inf, m_v = np.linalg.lstsq(a_all[0], b_all[0], rcond=None)[0]
            if min(k_0, k_inf, m_v) > 0:
                return {"K_0": k_0, "K_inf": k_inf, "tau": tau_grid[j], "alpha": alpha_grid[j],
                        "M_v": m_v}  # fmt: skip
        # no grid point with positive stiffnesses: fall back to a Voigt start
        voigt = Voigt().start(omega, d_disc, weight)
        tau = 1.0 / np.sqrt(omega.min() * omega.max())
        return {
            "K_0": voigt["K_v"],
            "K_inf": 10 * abs(voigt["K_v"]),
            "tau": tau,
            "alpha": 0.5,
            "M_v": voigt["M_v"],
        }
