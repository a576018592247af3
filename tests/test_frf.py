"""FRF form conversions against hand-worked values."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from viscorig import frf


def test_receptance_of_a_pure_spring_is_real_and_positive() -> None:
    # A 1e5 N/m spring at 10 Hz: X/F = 1e-5 m/N, so accelerance = -(2π·10)² · 1e-5.
    accelerance = -((2 * np.pi * 10.0) ** 2) * 1e-5
    receptance = frf.accelerance_to_receptance(10.0, accelerance)
    assert np.isclose(receptance, 1e-5)
    assert np.isclose(frf.accelerance_to_dynamic_stiffness(10.0, accelerance), 1e5)


@given(
    st.floats(0.5, 5000.0),
    st.complex_numbers(min_magnitude=1e-6, max_magnitude=1e6, allow_nan=False),
)
def test_round_trips(frequency_hz: float, value: complex) -> None:
    receptance = frf.accelerance_to_receptance(frequency_hz, value)
    assert np.isclose(frf.receptance_to_accelerance(frequency_hz, receptance), value, rtol=1e-12)
    stiffness = frf.accelerance_to_dynamic_stiffness(frequency_hz, value)
    assert np.isclose(frf.dynamic_stiffness_to_accelerance(frequency_hz, stiffness), value)
