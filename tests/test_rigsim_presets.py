"""Presets measured in the time domain reproduce the paper's tables as documented in them.

The Voigt fit is the paper's step 2 written here with numpy (no viscorig code): K_v, M_v, C_v of
``F_e/X_s - (K_s - ω² M_s + iω C_s) = K_v - ω² M_v + iω C_v`` by weighted linear least squares,
weights the inverse of the model's dynamic stiffness (relative receptance error).
"""

from __future__ import annotations

import numpy as np
import pytest
from rigsim.engine import RigSimulator
from rigsim.measurement import SourceControl, SweepRequest
from rigsim.rigfile import load_preset

M_S, K_S, C_S = 3.4, 50194.0, 5.05
#: paper Table 1 (K_v, C_v) and Table 2 (f_r, ξ), and this rig's documented f_r miss
PAPER = {
    "soft-0": (149986.61, 114.59, 39.50, 0.074, -0.029),
    "soft-10": (163948.13, 124.91, 40.75, 0.077, -0.025),
    "medium-0": (244605.26, 144.48, 47.39, 0.075, -0.015),
    "medium-10": (268906.82, 150.13, 49.21, 0.075, -0.012),
    "hard-0": (980356.04, 107.37, 79.47, 0.027, 0.096),
    "hard-10": (1104445.91, 102.72, 81.99, 0.027, 0.127),
}
FREQUENCY = np.arange(20.0, 120.001, 0.25)


def paper_sweep(name: str, reference_channel: int):
    rig = load_preset(name)
    control = SourceControl(
        source_vpk=0.05, auto_level=True, reference_channel=reference_channel,
        reference_vpk=1.0 * rig.sensors.acceleration_v_per_m_s2, tolerance_db=1.0,
        source_limit_vpk=2.0,
    )
    request = SweepRequest(FREQUENCY, 100 / FREQUENCY, 100 / FREQUENCY, control)
    record = RigSimulator(rig, seed=7).sweep(request)
    ch = record.channel_v
    scale = rig.sensors.force_v_per_n / rig.sensors.acceleration_v_per_m_s2
    receptance = ch[:, 1] / ch[:, 0] * scale / -((2 * np.pi * FREQUENCY) ** 2)
    return record, receptance


def weighted_fit(w, dynamic_stiffness, offset):
    """(K, M, C) of dynamic_stiffness - offset = K - ω² M + iω C, relative weights."""
    basis = np.stack([np.ones_like(w), -(w**2), 1j * w], axis=1)
    weight = 1 / np.abs(dynamic_stiffness)
    for _ in range(4):
        a = basis * weight[:, None]
        rhs = (dynamic_stiffness - offset) * weight
        p = np.linalg.lstsq(np.concatenate([a.real, a.imag]),
                            np.concatenate([rhs.real, rhs.imag]), rcond=None)[0]
        weight = 1 / np.abs(offset + basis @ p)
    return p


def test_table_preset_gives_the_paper_table() -> None:
    record, receptance = paper_sweep("table", reference_channel=2)
    assert record.level_reached.all()
    k, m, c = weighted_fit(2 * np.pi * FREQUENCY, 1 / receptance, 0.0)
    assert k == pytest.approx(K_S, rel=0.005)
    assert m == pytest.approx(M_S, rel=0.005)
    assert c == pytest.approx(C_S, rel=0.02)


@pytest.mark.parametrize("name", sorted(PAPER))
def test_specimen_preset_voigt_fit_matches_table_1(name: str) -> None:
    k_v_paper, c_v_paper, f_r_paper, xi_paper, f_r_miss = PAPER[name]
    record, receptance = paper_sweep(name, reference_channel=4)
    assert record.level_reached.all() and not record.overload.any()
    w = 2 * np.pi * FREQUENCY
    k_v, m_v, c_v = weighted_fit(w, 1 / receptance, K_S - w**2 * M_S + 1j * w * C_S)
    assert k_v == pytest.approx(k_v_paper, rel=0.01)
    assert c_v == pytest.approx(c_v_paper, rel=0.02)
    f_r = np.sqrt((K_S + k_v) / (M_S + m_v)) / (2 * np.pi)
    xi = (C_S + c_v) / (2 * np.sqrt((K_S + k_v) * (M_S + m_v)))
    assert f_r / f_r_paper - 1 == pytest.approx(f_r_miss, abs=0.005)
    if name.startswith("hard"):
        return
    assert abs(f_r / f_r_paper - 1) < 0.03
    assert xi == pytest.approx(xi_paper, rel=0.03)


def test_hard_rubber_shows_linkage_compliance_and_fixture_peaks() -> None:
    """Eq. (4) (rigid link) reads the hard rubber ~10 % softer than Eq. (5) (exact)."""
    record, receptance = paper_sweep("hard-10", reference_channel=4)
    w = 2 * np.pi * FREQUENCY
    ch = record.channel_v
    accel_support = ch[:, 3] / ch[:, 2] * 0.01124 / 0.0102
    k_eq5 = -(w**2) / accel_support + w**2 * 0.15
    k_eq4 = 1 / receptance - (K_S - w**2 * (M_S + 0.15) + 1j * w * C_S)
    band = (FREQUENCY > 60) & (FREQUENCY < 70)
    assert 0.85 < np.median(k_eq4.real[band] / k_eq5.real[band]) < 0.93
    # local peaks near 58 and 92 Hz in Eq. (5) against a smooth neighbourhood
    soft_record, _ = paper_sweep("soft-0", reference_channel=4)
    ch = soft_record.channel_v
    k5 = -(w**2) / (ch[:, 3] / ch[:, 2] * 0.01124 / 0.0102) + w**2 * 0.15
    for f0 in (38.0, 58.0, 92.0):
        near = np.abs(FREQUENCY - f0) < 1.5
        around = (np.abs(FREQUENCY - f0) > 6) & (np.abs(FREQUENCY - f0) < 9)
        trend = np.polyfit(FREQUENCY[around], k5.imag[around], 1)
        bump = np.max(np.abs(k5.imag[near] - np.polyval(trend, FREQUENCY[near])))
        assert bump > 0.02 * np.abs(k5[near]).mean()
