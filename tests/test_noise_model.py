"""The shared noise model: estimation from the data alone, and what consumers get from it.

The FRFs here are written by a generator of their own (closed-form accelerance of the paper's
table with a Voigt damper, rigid link), times ``1 + ε`` with ``ε`` drawn from known noise:
heteroscedastic white, a Gauss-Markov drift in test time, outliers. Nothing is shared with the
estimator but the definition of ``ε``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from viscorig.fitting import (
    FrfData,
    FrfNoise,
    NoiseModel,
    estimate_frf_noise,
    estimate_noise,
    noise_estimation,
    outliers,
)
from viscorig.fitting.noise import WIDE_COLUMNS, MarkovWhitening, exponential_kernel_apply

FREQUENCY = np.arange(20.0, 120.0 + 1e-9, 0.25)
OMEGA = 2 * np.pi * FREQUENCY
#: Test time at the end of each point of a 100 + 100 period sweep.
TIME = np.cumsum(200.0 / FREQUENCY)
CLEAN = -(OMEGA**2) / (50194.0 + 1.5e5 - OMEGA**2 * 3.65 + 1j * OMEGA * 119.6)
#: White relative noise growing fivefold along the band (complex rms).
WHITE_RMS = 2e-4 * (1 + 4 * (FREQUENCY - 20) / 100)


def ou_path(rng: np.random.Generator, time: np.ndarray, tau: float) -> np.ndarray:
    """Unit-variance Gauss-Markov process sampled at ``time``."""
    path = np.empty(time.size)
    path[0] = rng.normal()
    for i in range(1, time.size):
        a = math.exp(-(time[i] - time[i - 1]) / tau)
        path[i] = a * path[i - 1] + math.sqrt(1 - a * a) * rng.normal()
    return path


def noisy(seed: int, drift_rms: float = 0.0, tau: float = 10.0, phase: bool = False,
          outliers: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    eps = WHITE_RMS / np.sqrt(2) * (rng.normal(size=FREQUENCY.size)
                                    + 1j * rng.normal(size=FREQUENCY.size))
    if drift_rms:
        eps = eps + drift_rms * ou_path(rng, TIME, tau) * (1j if phase else 1.0)
    if outliers:
        where = rng.choice(FREQUENCY.size, outliers, replace=False)
        eps[where] += 100 * WHITE_RMS[where] * np.exp(2j * np.pi * rng.random(outliers))
    return CLEAN * (1 + eps)


def truth_floor(drift_rms: float = 0.0) -> float:
    return float(np.sqrt(np.mean(WHITE_RMS**2) + drift_rms**2))


def test_white_noise_floor_and_no_correlated_part() -> None:
    floors, correlated = [], 0
    for seed in range(8):
        noise = estimate_frf_noise(noisy(seed), FREQUENCY, TIME)
        floors.append(NoiseModel.of(noise).floor / truth_floor())
        correlated += noise.correlated
    assert np.mean(floors) == pytest.approx(1.0, abs=0.06)
    assert max(abs(f - 1) for f in floors) < 0.15
    assert correlated <= 1  # the test for a correlated part has 1 % false alarms


def test_the_same_points_give_the_same_estimate_made_once() -> None:
    data = noisy(21, drift_rms=3e-4, outliers=2)
    first = estimate_frf_noise(data, FREQUENCY, TIME, name="support")
    assert estimate_frf_noise(data.copy(), FREQUENCY.copy(), TIME, name="support") is first
    with pytest.raises(ValueError):
        first.white_power[0] = 1.0  # shared, so read-only
    moved = data.copy()
    moved[200] *= 1.001
    other = estimate_frf_noise(moved, FREQUENCY, TIME, name="support")
    assert other is not first
    assert estimate_frf_noise(data, FREQUENCY, TIME, name="table") is not first
    assert estimate_frf_noise(data, FREQUENCY, None, name="support") is not first


def test_an_estimate_whitened_through_dense_factors_is_not_kept() -> None:
    """Points measured out of frequency order (the band's upper half first, then its lower
    half), with a drift along their time: the whitening needs dense Cholesky factors, n²
    numbers a part, which would stay with a kept estimate; such an estimate is made afresh
    each time."""
    rng = np.random.default_rng(8)
    upper = FREQUENCY >= 70.0
    dwell = np.diff(TIME, prepend=0.0)
    time = np.empty(FREQUENCY.size)
    time[upper] = np.cumsum(dwell[upper])
    time[~upper] = time[upper][-1] + np.cumsum(dwell[~upper])
    order = np.argsort(time)
    drift = np.empty(FREQUENCY.size)
    drift[order] = ou_path(rng, time[order], 20.0)
    eps = WHITE_RMS / np.sqrt(2) * (rng.normal(size=FREQUENCY.size)
                                    + 1j * rng.normal(size=FREQUENCY.size)) + 2e-3 * drift
    data = CLEAN * (1 + eps)
    first = estimate_frf_noise(data, FREQUENCY, time, name="support")
    assert first.correlated and first.dense
    assert estimate_frf_noise(data, FREQUENCY, time, name="support") is not first
    ordered = estimate_frf_noise(noisy(22, drift_rms=2e-3), FREQUENCY, TIME, name="support")
    assert ordered.correlated and not ordered.dense


def test_local_white_power_follows_the_band() -> None:
    noise = estimate_frf_noise(noisy(3), FREQUENCY, TIME)
    ratio = np.sqrt(noise.white_power) / WHITE_RMS
    assert np.median(ratio[:100]) == pytest.approx(1.0, abs=0.15)
    assert np.median(ratio[-100:]) == pytest.approx(1.0, abs=0.15)


@pytest.mark.parametrize("phase", [False, True])
def test_a_drift_in_test_time_is_found_on_its_part(phase: bool) -> None:
    drift = 1e-3
    found, other, floors = [], [], []
    for seed in range(6):
        noise = estimate_frf_noise(noisy(seed, drift, tau=10.0, phase=phase), FREQUENCY, TIME)
        re, im = (math.sqrt(v) for v in noise.correlated_power)
        found.append(im if phase else re)
        other.append(re if phase else im)
        floors.append(NoiseModel.of(noise).floor / truth_floor(drift))
        assert noise.axis_unit == "s"
    assert np.median(found) == pytest.approx(drift, rel=0.3)
    assert np.median(other) < 0.5 * drift
    assert np.median(floors) == pytest.approx(1.0, abs=0.15)
    # Without the drift model the floor would be the white part alone: 1.9 times too low.
    assert truth_floor(drift) / truth_floor() > 1.8


def test_outliers_neither_inflate_nor_collapse_the_noise_elsewhere() -> None:
    """Eight points struck at 100 times the noise: found, given their own error (a perfect
    model's rms includes them, so the floor must), and the noise of every other point is
    estimated as without them."""
    for seed in range(4):
        clean = estimate_frf_noise(noisy(seed), FREQUENCY, TIME)
        measured = noisy(seed, outliers=8)
        spoiled = estimate_frf_noise(measured, FREQUENCY, TIME)
        found = spoiled.outliers
        assert np.count_nonzero(found) >= 7  # two may fall side by side
        assert not spoiled.correlated
        others = ~found
        assert np.median(spoiled.power()[others] / clean.power()[others]) == pytest.approx(
            1.0, abs=0.05)
        error2 = np.abs(measured / CLEAN - 1) ** 2
        assert np.median(spoiled.power()[found] / error2[found]) == pytest.approx(1.0, abs=0.2)
        expected = np.sqrt(np.mean(np.where(found, error2, clean.power())))
        assert NoiseModel.of(spoiled).floor == pytest.approx(expected, rel=0.1)


def test_the_analysers_variance_gives_the_shape_and_the_data_the_scale() -> None:
    variance = WHITE_RMS**2
    scales, halved = [], []
    for seed in range(6):
        noise = estimate_frf_noise(noisy(seed), FREQUENCY, TIME, variance=variance)
        assert noise.source == "analyser variance"
        ratio = noise.white_power / variance
        assert np.ptp(ratio) < 1e-9  # the shape is the variance's, point by point
        scales.append(ratio[0])
        # A variance that misses half the scatter (point-to-point errors) is scaled up.
        noise = estimate_frf_noise(noisy(seed), FREQUENCY, TIME, variance=variance / 2)
        halved.append(noise.white_power[0] / variance[0])
    assert np.mean(scales) == pytest.approx(1.0, abs=0.06)
    assert np.mean(halved) == pytest.approx(1.0, abs=0.06)
    assert max(abs(s - 1) for s in scales) < 0.25


def test_estimate_noise_takes_the_frfs_of_a_run() -> None:
    data = FrfData(FREQUENCY, noisy(1), noisy(2), TIME, name="run")
    model = estimate_noise(data)
    assert model.frfs == ("table", "support")
    assert model.points("support") == FREQUENCY.size
    assert model.floor == pytest.approx(truth_floor(), rel=0.12)


@pytest.mark.parametrize("damage", [1e308, np.inf, -1.0, 0.0, 5e-324])
def test_a_damaged_analyser_variance_is_not_used(damage: float) -> None:
    """A variance dataset of 1e308 (or a denormal 5e-324) at every point, as a damaged file
    holds, overflowed in the whitening: every fit of the run ended in 'residuals are not
    finite'. Such a variance is set aside and
    the noise estimated from the points, as without one."""
    table, support = noisy(1), noisy(2)
    variance = np.full(FREQUENCY.size, 2 * WHITE_RMS**2)
    variance[100] = damage
    damaged = FrfData(FREQUENCY, table, support, TIME, name="run", variance_table=variance,
                      variance_support=np.full_like(variance, damage))
    model = estimate_noise(damaged)
    plain = estimate_noise(FrfData(FREQUENCY, table, support, TIME, name="run"))
    assert [block.source for frf in model.frfs for block in model.blocks[frf]] == [
        "differences", "differences"]
    assert model.floor == plain.floor
    assert np.isfinite(model.whiten({"table": table, "support": support})).all()


# -- what consumers get -----------------------------------------------------------------------

def _model(rng: np.random.Generator, n: int = 60) -> tuple[FrfNoise, np.ndarray]:
    axis = np.cumsum(rng.uniform(0.5, 2.0, n))
    noise = FrfNoise("table", rng.uniform(1e-8, 4e-8, n), (3e-8, 1e-8), 4.0, axis, "s")
    return noise, axis


def test_exponential_kernel_is_applied_exactly_in_any_order_and_span() -> None:
    rng = np.random.default_rng(0)
    for tau, scale in [(3.0, 1.0), (0.01, 1.0), (5.0, 1e3)]:  # 1e3: spans > the block span
        axis = rng.permutation(np.cumsum(rng.uniform(0.5, 2.0, 80)) * scale)
        x = rng.normal(size=(80, 3))
        dense = np.exp(-np.abs(axis[:, None] - axis[None, :]) / tau) @ x
        assert np.allclose(exponential_kernel_apply(axis, tau, x), dense, rtol=1e-9, atol=1e-12)


def test_whitening_gives_the_mahalanobis_norm_and_the_likelihood() -> None:
    rng = np.random.default_rng(1)
    table, _ = _model(rng)
    support = FrfNoise("support", rng.uniform(1e-8, 2e-8, 60))
    model = NoiseModel.of(table, support)
    residuals = {"table": rng.normal(size=60) * 2e-4 + 1j * rng.normal(size=60) * 1e-4,
                 "support": rng.normal(size=60) * 1e-4 + 1j * rng.normal(size=60) * 1e-4}
    stacked = model.stack(residuals)
    blocks = [table.covariance("re"), support.covariance("re"),
              table.covariance("im"), support.covariance("im")]
    sigma = np.zeros((240, 240))
    offset = 0
    for block in blocks:
        sigma[offset:offset + 60, offset:offset + 60] = block
        offset += 60
    assert model.chi2(residuals) == pytest.approx(stacked @ np.linalg.solve(sigma, stacked),
                                                  rel=1e-9)
    expected = multivariate_normal(np.zeros(240), sigma).logpdf(stacked)
    assert model.log_likelihood(residuals) == pytest.approx(expected, rel=1e-9)
    jac = {"table": rng.normal(size=(60, 2)) + 1j * rng.normal(size=(60, 2)),
           "support": rng.normal(size=(60, 2)) + 1j * rng.normal(size=(60, 2))}
    whitened = model.whiten_jacobian(jac)
    full = np.concatenate([np.concatenate([jac["table"].real, jac["support"].real]),
                           np.concatenate([jac["table"].imag, jac["support"].imag])])
    assert np.allclose(whitened.T @ whitened, full.T @ np.linalg.solve(sigma, full), rtol=1e-8)
    assert np.allclose(model.apply_covariance(full, ("table", "support")), sigma @ full)


@pytest.mark.parametrize("order", ["up", "down", "ties", "shuffled"])
def test_whitening_of_a_drift_is_the_inverse_cholesky_factor(order: str) -> None:
    """The O(n) whitening along a monotone time axis gives ``L⁻¹ y`` of the dense covariance
    (``Σ = L Lᵀ`` formed here from the model's definition); points out of time order fall
    back to the dense factor with the same result."""
    rng = np.random.default_rng(7)
    n = 90
    axis = np.cumsum(rng.uniform(0.2, 3.0, n))
    if order == "down":
        axis = axis[::-1]
    elif order == "ties":
        axis[10:14] = axis[10]
    elif order == "shuffled":
        axis = rng.permutation(axis)
    white = rng.uniform(1e-9, 5e-8, n)
    noise = FrfNoise("table", white, (4e-8, 1e-9), 6.0, axis, "s")
    y = rng.normal(size=(n, 4)) * 1e-4
    for part, sigma2 in (("re", 4e-8), ("im", 1e-9)):
        sigma = np.diag(white / 2) + sigma2 * np.exp(-np.abs(axis[:, None] - axis[None, :]) / 6.0)
        expected = np.linalg.solve(np.linalg.cholesky(sigma), y)
        assert np.allclose(noise.whiten_part(part, y), expected, rtol=1e-9, atol=1e-12)
        assert np.allclose(noise.whiten_part(part, y[:, 0]), expected[:, 0], rtol=1e-9,
                           atol=1e-12)
    assert (noise.whitening("re") is None) == (order == "shuffled")


def test_joined_whitening_whitens_each_piece_as_its_own() -> None:
    """Drift pieces and white pieces stacked into one whitening: each piece's rows come out as
    that piece's own whitening makes them (no piece's process reaches into the next)."""
    rng = np.random.default_rng(3)
    pieces, rows = [], []
    for n, drift in ((40, True), (25, False), (1, True), (60, True), (7, False)):
        if drift:
            axis = np.cumsum(rng.uniform(0.2, 3.0, n))
            pieces.append(MarkovWhitening.of(rng.uniform(1e-3, 1.0, n), 0.5, axis, 6.0))
        else:
            pieces.append(1.0 / np.sqrt(rng.uniform(1e-3, 1.0, n)))
        rows.append(rng.normal(size=(n, 3)))
    joined = MarkovWhitening.joined(pieces).apply(np.concatenate(rows))
    alone = [piece.apply(y) if isinstance(piece, MarkovWhitening) else y * piece[:, None]
             for piece, y in zip(pieces, rows, strict=True)]
    np.testing.assert_allclose(joined, np.concatenate(alone), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("columns", [1, WIDE_COLUMNS - 1, WIDE_COLUMNS, 3 * WIDE_COLUMNS])
def test_whitening_of_many_columns_is_the_dense_cholesky_solve(columns: int) -> None:
    """Narrow and wide matrices (solved column by column, or filtered row by row across the
    columns) whiten as ``L⁻¹`` of the dense covariance's Cholesky factor does, piece by piece,
    white pieces and one-point pieces included."""
    rng = np.random.default_rng(columns)
    pieces, factors = [], []
    for n, drift in ((50, True), (9, False), (1, True), (70, True)):
        white = rng.uniform(1e-3, 1.0, n)
        if drift:
            axis = np.cumsum(rng.uniform(0.2, 3.0, n))
            pieces.append(MarkovWhitening.of(white, 0.5, axis, 6.0))
            covariance = np.diag(white) + 0.5 * np.exp(-np.abs(axis[:, None] - axis) / 6.0)
        else:
            pieces.append(1.0 / np.sqrt(white))
            covariance = np.diag(white)
        factors.append(np.linalg.cholesky(covariance))
    y = rng.normal(size=(sum(f.shape[0] for f in factors), columns))
    expected, start = [], 0
    for factor in factors:
        expected.append(np.linalg.solve(factor, y[start:start + factor.shape[0]]))
        start += factor.shape[0]
    whitened = MarkovWhitening.joined(pieces).apply(y)
    np.testing.assert_allclose(whitened, np.concatenate(expected), rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(MarkovWhitening.joined(pieces).apply(y[:, :1])[:, 0],
                                  MarkovWhitening.joined(pieces).apply(y[:, 0]))
    # whitened in place when allowed: the same numbers, in the array given
    given = y.copy()
    in_place = MarkovWhitening.joined(pieces).apply(given, overwrite=True)
    np.testing.assert_array_equal(in_place, whitened)
    assert np.shares_memory(in_place, given)


def test_sandwich_matches_the_scatter_of_least_squares_estimates() -> None:
    """A linear model fitted by unweighted least squares under correlated, heteroscedastic
    noise: the sandwich is the covariance of the estimates over many draws."""
    rng = np.random.default_rng(2)
    table, _axis = _model(rng, 80)
    model = NoiseModel.of(table)
    design = np.stack([np.ones(80), np.linspace(-1, 1, 80)], axis=1)
    jac = np.concatenate([design, 0.5 * design])  # real and imaginary parts
    sigma = np.zeros((160, 160))
    sigma[:80, :80], sigma[80:, 80:] = table.covariance("re"), table.covariance("im")
    draws = rng.multivariate_normal(np.zeros(160), sigma, size=4000)
    estimates = np.linalg.lstsq(jac, draws.T, rcond=None)[0].T
    predicted = model.sandwich(jac, ("table",))
    assert np.allclose(np.diag(np.cov(estimates.T)), np.diag(predicted), rtol=0.1)
    naive = np.linalg.inv(jac.T @ jac) * np.mean(np.diag(sigma))  # points as independent
    assert predicted[0, 0] > 2 * naive[0, 0]  # the correlated part is what counts


def test_effective_points() -> None:
    white = FrfNoise("table", np.full(100, 1e-8))
    assert white.effective_points() == pytest.approx(200.0)
    drifting = FrfNoise("table", np.full(100, 1e-10), (1e-8, 0.0), 10.0)
    assert drifting.effective_points() < 100 + 100 / 5
    joined = NoiseModel.join([NoiseModel.of(white), NoiseModel.of(white)])
    assert joined.points("table") == 200
    assert joined.effective_points() == pytest.approx(400.0)


def test_a_jacobian_with_non_finite_entries_gives_no_errors_rather_than_a_crash() -> None:
    from viscorig.fitting.uncertainty import _inverse

    jac = np.ones((20, 3))
    jac[4, 1] = np.inf
    inverse, full_rank = _inverse(jac)
    assert not full_rank
    assert inverse.shape == (3, 3) and np.all(np.isnan(inverse))


def test_a_constant_changed_at_run_time_gives_a_new_estimate(monkeypatch) -> None:
    data = noisy(23, outliers=2)
    first = estimate_frf_noise(data, FREQUENCY, TIME, name="support")
    monkeypatch.setattr(noise_estimation, "REJECT", 4.0)
    assert estimate_frf_noise(data, FREQUENCY, TIME, name="support") is not first
    monkeypatch.undo()
    monkeypatch.setattr(outliers, "OUTLIER_LEVEL", 10.0)
    assert estimate_frf_noise(data, FREQUENCY, TIME, name="support") is not first
    monkeypatch.undo()
    assert estimate_frf_noise(data, FREQUENCY, TIME, name="support") is first
