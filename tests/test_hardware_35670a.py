"""A real 35670A: identity, options, byte order and a short sweep.

Skipped unless a resource is given: ``pytest --resource GPIB0::11::INSTR`` or the environment
variable ``VISCORIG_RESOURCE`` (a Prologix interface ``PRLGX-...::INTFC`` means the analyser at
GPIB address 11 behind it). The sweep drives the source at 0.1 Vpk with a 0.5 Vpk limit: connect
the source to a dummy load or a shaker that may run.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from agilent35670a import Agilent35670A

pytestmark = pytest.mark.hardware


@pytest.fixture(scope="module")
def analyser(request: pytest.FixtureRequest):
    resource = request.config.getoption("--resource") or os.environ.get("VISCORIG_RESOURCE")
    if not resource:
        pytest.skip("no 35670A given (--resource or VISCORIG_RESOURCE)")
    with Agilent35670A.open(resource, timeout_s=10.0) as instrument:
        yield instrument


def test_identity_and_options(analyser: Agilent35670A) -> None:
    assert "35670A" in analyser.identify().upper()
    analyser.require_options(four_channels=False)  # 1D2 at least


def test_real64_is_big_endian_and_agrees_with_ascii(analyser: Agilent35670A) -> None:
    """Checks the inferred byte order against an ASCII read of the same axis."""
    analyser.instrument_mode = "SINE"
    analyser.set_data_format("ASC,12")
    analyser.configure("TRAC:DATA D1,TRAC1")
    from_ascii = analyser.read_values("TRAC:X? D1")
    analyser.set_data_format("REAL,64")
    from_block = analyser.read_values("TRAC:X? D1")
    np.testing.assert_allclose(from_block, from_ascii, rtol=1e-9)


def test_short_sweep(analyser: Agilent35670A) -> None:
    four = "AY6" in analyser.options
    channels = (1, 2, 3, 4) if four else (1, 2)
    analyser.configure_swept_sine(
        inputs=[(ch, "N" if ch % 2 else "M/S2", 1.0) for ch in channels],
        reference_channel=2,
        reference_level_eu=0.05,
        source_limit_vpk=0.5,
        pairing="PAIR" if four else None,
        settle_cycles=5,
        integrate_cycles=5,
    )
    segment = analyser.measure(100.0, 101.0, timeout_s=120.0)
    assert len(segment) == 5
    np.testing.assert_allclose(segment.frequency_hz, np.linspace(100.0, 101.0, 5), atol=0.02)
    assert np.all(np.isfinite(segment.frf_21))
    assert set(segment.amplitude_eu) == set(channels)


def test_a_sweep_ended_at_a_point_keeps_the_points_measured(analyser: Agilent35670A) -> None:
    """Checks the inferred behaviour a pause at a point relies on: the settling bit rises as a
    new point starts, and after ``ABOR`` the traces keep the points measured (the rest hold the
    no-data marker)."""
    four = "AY6" in analyser.options
    channels = (1, 2, 3, 4) if four else (1, 2)
    analyser.configure_swept_sine(
        inputs=[(ch, "N" if ch % 2 else "M/S2", 1.0) for ch in channels],
        reference_channel=2,
        reference_level_eu=0.05,
        source_limit_vpk=0.5,
        pairing="PAIR" if four else None,
        settle_cycles=20,
        integrate_cycles=20,
    )

    def progress(report) -> None:
        if report.elapsed_s > 0.3 * report.expected_s:
            analyser.end_after_point()

    segment = analyser.measure(20.0, 30.0, progress=progress, timeout_s=300.0)
    assert segment.ended_early and 0 < len(segment) < 41
    np.testing.assert_allclose(segment.frequency_hz, 20.0 + 0.25 * np.arange(len(segment)),
                               atol=0.02)
    assert np.all(np.isfinite(segment.frf_21))
