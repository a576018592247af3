"""Acquisition layer: flags, limits, force estimates, the analyser protocol, segment handling."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from viscorig.acquisition import (
    Analyser,
    ProbeReading,
    RigEstimate,
    SweepHooks,
    SweepMeasurement,
    SweepSettings,
    Wiring,
    configure,
    estimate_force,
    estimate_force_from_probe,
    motion_ratio,
    point_flags,
    source_limit_v,
    specimen_from_accelerance,
)
from viscorig.acquisition.console import format_duration
from viscorig.errors import InstrumentError
from viscorig.sequences import parse_sequence
from viscorig.storage import (
    FORCE_ABOVE_SHAKER_LIMIT,
    INPUT_OVERLOAD,
    LEVEL_NOT_REACHED,
    SOURCE_AT_LIMIT,
    CampaignFile,
    RunSettings,
)

TABLE = RigEstimate(3.4, 50194.0, 5.05)


def flags_of(reference, force, overloaded=False):
    return point_flags(reference, force, level_m_per_s2=1.4, tolerance_db=1.0,
                       force_limit_n=100.0, overloaded=overloaded)


def test_point_flags_bits() -> None:
    reference = np.array([1.4, 1.3, 1.0, 1.0, 1.9, 1.4, np.nan])
    force = np.array([10.0, 10.0, 20.0, 99.0, 5.0, 130.0, 10.0])
    flags = flags_of(reference, force)
    # within 1 dB: nothing; -0.64 dB: nothing
    assert flags[0] == 0 and flags[1] == 0
    # -2.9 dB with the force far below the limit: the source limit was binding
    assert flags[2] == LEVEL_NOT_REACHED | SOURCE_AT_LIMIT
    # -2.9 dB with the force at the limit (within 0.5 dB): the shaker limit held it
    assert flags[3] == LEVEL_NOT_REACHED
    # +2.7 dB: too much motion is a missed level, but not a source limit
    assert flags[4] == LEVEL_NOT_REACHED
    # force 30 % over the limit
    assert flags[5] == FORCE_ABOVE_SHAKER_LIMIT
    # no reading at all is never a reached level
    assert flags[6] & LEVEL_NOT_REACHED
    assert np.all(flags_of(reference, force, overloaded=True) & INPUT_OVERLOAD)
    assert flags.dtype == np.uint16


def test_force_at_the_limit_within_noise_is_not_flagged_above_it() -> None:
    flags = flags_of([1.0, 1.0], [100.4, 101.5])
    assert not flags[0] & FORCE_ABOVE_SHAKER_LIMIT
    assert flags[1] & FORCE_ABOVE_SHAKER_LIMIT


def test_source_limit_comes_from_the_shaker_when_its_gain_is_known() -> None:
    assert source_limit_v(5.0, 100.0, 50.0) == pytest.approx(2.0)
    assert source_limit_v(1.5, 100.0, 50.0) == pytest.approx(1.5)
    assert source_limit_v(4.0, 100.0, None) == pytest.approx(4.0)
    assert source_limit_v(9.0, 1e4, 1.0) == pytest.approx(5.0)  # the analyser's maximum


def test_force_estimate_of_the_paper_rig_matches_the_sequence_comment() -> None:
    # paper.toml: hard-10 (K_v 1 104 446 N/m) needs about 97 N at 20 Hz and 1.4 m/s^2
    rig = RigEstimate(3.4, 50194.0, 5.05, 1_104_445.91, 102.72, 0.0)
    estimate = estimate_force(np.arange(20.0, 120.25, 0.25), 1.4, rig)
    assert estimate.peak_frequency_hz == 20.0
    assert estimate.peak_n == pytest.approx(97.3, abs=1.0)
    reduced = estimate.level_for(80.0, 1.4)
    again = estimate_force(estimate.frequency_hz, reduced, rig)
    assert again.peak_n == pytest.approx(0.9 * 80.0, rel=1e-9)


def test_specimen_stiffness_is_recovered_from_a_table_accelerance() -> None:
    frequency = np.arange(20.0, 120.0, 0.5)
    truth = RigEstimate(3.4, 50194.0, 5.05, 244_605.0, 144.5, 0.2)
    omega = 2 * np.pi * frequency
    accelerance = -(omega**2) / truth.dynamic_stiffness(frequency)
    rng = np.random.default_rng(1)
    accelerance *= 1 + 1e-3 * (rng.standard_normal(frequency.size)
                               + 1j * rng.standard_normal(frequency.size))
    stiffness, damping, mass = specimen_from_accelerance(frequency, accelerance, TABLE)
    assert stiffness == pytest.approx(244_605.0, rel=0.01)
    assert damping == pytest.approx(144.5, rel=0.05)
    assert mass == pytest.approx(0.2, abs=0.02)
    assert specimen_from_accelerance(frequency[:2], accelerance[:2], TABLE) is None


def test_durations_read_as_clock_times() -> None:
    assert format_duration(59.6) == "1:00"
    assert format_duration(3 * 3600 + 61) == "3:01:01"


def test_the_35670a_driver_satisfies_the_analyser_protocol_structurally() -> None:
    from agilent35670a import Agilent35670A

    for name in ("resource", "identify", "configure_swept_sine", "measure", "measure_point",
                 "abort", "close"):
        assert hasattr(Agilent35670A, name), name
    server_module = pytest.importorskip("rigsim.server")
    with server_module.SimulatedAnalyserServer("table", seed=1) as server:
        analyser = Agilent35670A.open(server.resource, timeout_s=2.0)
        try:
            assert isinstance(analyser, Analyser)
        finally:
            analyser.close()


# -- a protocol-level analyser double: the flag and segment logic without a transport --------


@dataclass
class FakeSegment:
    frequency_hz: np.ndarray
    frf_21: np.ndarray
    frf_43: np.ndarray | None
    amplitude_eu: dict
    variance: dict
    overload_channels: tuple[int, ...] = ()
    started_at_s: float = 0.0
    finished_at_s: float = 1.0


@dataclass
class FakeAnalyser:
    """Returns what a script says; records what it was asked."""

    force_n: float = 10.0
    reference: float = 1.4
    overloads: list[tuple[int, ...]] = field(default_factory=list)
    axis_shift_hz: float = 0.0
    calls: list[tuple[float, float]] = field(default_factory=list)
    resource: str = "FAKE::1::INSTR"

    def identify(self) -> str:
        return "FAKE,35670A,0,0"

    def configure_swept_sine(self, **settings) -> None:
        self.settings = settings

    def _segment(self, frequency: np.ndarray) -> FakeSegment:
        n = frequency.size
        overload = self.overloads.pop(0) if self.overloads else ()
        return FakeSegment(
            frequency + self.axis_shift_hz, np.full(n, 0.1 + 0.01j), np.full(n, 0.2 + 0.02j),
            {1: np.full(n, self.force_n), 2: np.full(n, 1.0), 3: np.full(n, 5.0),
             4: np.full(n, self.reference)},
            {ch: np.full(n, 1e-6) for ch in (1, 2, 3, 4)}, overload,
        )

    def measure(self, start_hz, stop_hz, *, progress=None, poll_interval_s=0.2):
        self.calls.append((start_hz, stop_hz))
        return self._segment(np.arange(start_hz, stop_hz + 1e-9, 0.25))

    def measure_point(self, frequency_hz, *, progress=None, poll_interval_s=0.2):
        self.calls.append((frequency_hz, frequency_hz))
        return self._segment(np.array([frequency_hz]))

    def abort(self) -> None:
        pass

    def close(self) -> None:
        pass


SEQUENCE = """
name = "t"
[[steps]]
type = "sweep"
run = "r"
specimen = "soft"
band_hz = [20.0, 25.0]
resolution_hz = 0.25
settle_cycles = 10
integrate_cycles = 10
level = "1.4 m/s^2"
segment_s = 3
"""

WIRING = Wiring(1, 2, 3, 4, {1: 0.01, 2: 0.01, 3: 0.01, 4: 0.01})


def measure_fake(tmp_path, analyser: FakeAnalyser, sequence: str = SEQUENCE):
    step = parse_sequence(sequence).sweeps[0]
    campaign = CampaignFile.create(tmp_path / "c.h5", sequence_text=sequence, durable=False)
    campaign.start_run(step.run, RunSettings(
        specimen=step.specimen, level_m_per_s2=step.level_m_per_s2, direction="up",
        settle_cycles=10, integrate_cycles=10, resolution_hz=0.25))
    settings = SweepSettings(step=step, level_m_per_s2=1.4, force_limit_n=100.0,
                             source_limit_v=2.0, time_base="test")
    done = []
    SweepMeasurement(campaign, analyser, WIRING, settings,
                     SweepHooks(on_segment=done.append)).run()
    return campaign.run("r"), done


def test_a_sweep_is_committed_segment_by_segment_with_the_plan(tmp_path) -> None:
    analyser = FakeAnalyser()
    run, done = measure_fake(tmp_path, analyser)
    assert run.points == 21
    np.testing.assert_allclose(run.frequency_hz, 20.0 + 0.25 * np.arange(21))
    assert len(done) == len(analyser.calls) > 3  # 3 s of test time per segment
    assert [d.points_done for d in done][-1] == 21
    assert np.all(np.diff(run.time_s) > 0)
    # time_s on the test clock is the sum of settle and integration periods
    assert run.time_s[-1] == pytest.approx(np.sum(20 / run.frequency_hz))
    np.testing.assert_allclose(run.accelerance_table, 0.1 + 0.01j)
    np.testing.assert_allclose(run.accelerance_support, 0.2 + 0.02j)
    assert np.all(np.isnan(run.source_amplitude))
    np.testing.assert_allclose(run.variance_table, 2e-6)
    assert not run.flags.any()


def test_force_above_the_shaker_limit_is_flagged(tmp_path) -> None:
    run, _ = measure_fake(tmp_path, FakeAnalyser(force_n=130.0))
    assert np.all(run.flags == FORCE_ABOVE_SHAKER_LIMIT)


def test_an_overloaded_segment_is_measured_again_once(tmp_path) -> None:
    analyser = FakeAnalyser(overloads=[(4,), (), (2,), (2,)])
    run, done = measure_fake(tmp_path, analyser)
    assert done[0].remeasured and not (run.flags[: done[0].points_done] & INPUT_OVERLOAD).any()
    second = slice(done[0].points_done, done[1].points_done)
    assert done[1].remeasured and np.all(run.flags[second] & INPUT_OVERLOAD)
    assert len(analyser.calls) == len(done) + 2
    assert run.points == 21  # no duplicated point from the measurement thrown away


def test_an_axis_off_the_plan_is_an_instrument_fault_and_nothing_is_written(tmp_path) -> None:
    with pytest.raises(InstrumentError, match=r"FAKE::1::INSTR.*returned"):
        measure_fake(tmp_path, FakeAnalyser(axis_shift_hz=0.125))
    assert CampaignFile.open(tmp_path / "c.h5").run("r").points == 0


def test_the_wiring_decides_the_analysers_inputs_and_reference() -> None:
    """Excitation force on input 3: the labels, sensitivities and reference follow the wiring
    (the driver is told them, it decides none)."""
    wiring = Wiring(3, 4, 1, 2, {1: 0.011, 2: 0.0102, 3: 0.012, 4: 0.0105})
    assert wiring.inputs() == [(1, "N", 0.011), (2, "M/S2", 0.0102), (3, "N", 0.012),
                               (4, "M/S2", 0.0105)]
    assert wiring.reference_channel(bare_table=True) == 4
    assert wiring.reference_channel(bare_table=False) == 2
    with pytest.raises(ValueError, match=r"input\(s\) \[4\]"):
        Wiring(1, 2, 3, 4, {1: 0.01, 2: 0.01, 3: 0.01}).inputs()
    analyser = FakeAnalyser()
    step = parse_sequence(SEQUENCE).sweeps[0]
    configure(analyser, wiring, SweepSettings(step=step, level_m_per_s2=1.4, force_limit_n=100.0,
                                              source_limit_v=2.0))
    assert analyser.settings["inputs"] == wiring.inputs()
    assert analyser.settings["reference_channel"] == 2  # the device's accelerometer
    assert analyser.settings["reference_level_eu"] == 1.4
    assert analyser.settings["pairing"] == "PAIR"
    assert analyser.settings["input_limit_eu"] == 100.0


def test_a_bare_table_run_stores_nan_support(tmp_path) -> None:
    sequence = SEQUENCE.replace('specimen = "soft"', 'specimen = "none"')
    run, _ = measure_fake(tmp_path, FakeAnalyser(reference=1.0), sequence)
    assert np.all(np.isnan(run.accelerance_support))
    # the reference of a bare table is the table acceleration (input 2), 1.0 here
    np.testing.assert_allclose(run.reference_amplitude, 1.0)
    assert math.isnan(run.variance_support[0])


# -- force prediction from a low-level probe --------------------------------------------------


def rig_dynamic_stiffness(frequency_hz, specimen_stiffness, specimen_damping, disc_mass_kg,
                          link_stiffness=None):
    """F_e/X_s and X_s/X_v of the two-DOF rig (physics.md), table of TABLE, a Voigt specimen."""
    omega = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    table = TABLE.dynamic_stiffness(frequency_hz)
    device = specimen_stiffness + 1j * omega * specimen_damping - omega**2 * disc_mass_kg
    if link_stiffness is None:
        return table + device, np.ones_like(omega)
    link = link_stiffness
    dynamic = table + link * device / (link + device)  # D_s − K_c² / D_v, D_s with K_c in it
    return dynamic, np.abs((link + device) / link)


def probe_at(frequency_hz, level, **rig) -> ProbeReading:
    """What a probe at ``level`` of the disc's acceleration reads on the closed-form rig."""
    dynamic, motion = rig_dynamic_stiffness(np.array([frequency_hz]), **rig)
    omega2 = (2 * np.pi * frequency_hz) ** 2
    force = float(np.abs(dynamic[0]) * motion[0] * level / omega2)
    return ProbeReading(frequency_hz, complex(dynamic[0]), level, level, force, 0, 10.0)


def needed_force(frequency_hz, level, **rig):
    dynamic, motion = rig_dynamic_stiffness(frequency_hz, **rig)
    return np.abs(dynamic) * motion * level / (2 * np.pi * np.asarray(frequency_hz)) ** 2


HARD = {"specimen_stiffness": 1.07e6, "specimen_damping": 306.0, "disc_mass_kg": 0.15,
        "link_stiffness": 1e7}
GRID = np.arange(20.0, 120.25, 0.25)


def test_a_probe_predicts_a_hard_specimen_that_the_previous_soft_one_underestimates() -> None:
    truth = needed_force(GRID, 1.4, **HARD)
    # the old way: the previous (soft) run's specimen, fitted from its table accelerance
    soft = {"specimen_stiffness": 1.5e5, "specimen_damping": 115.0, "disc_mass_kg": 0.15}
    dynamic, _ = rig_dynamic_stiffness(GRID, **soft)
    accelerance = -((2 * np.pi * GRID) ** 2) / dynamic
    stiffness, damping, mass = specimen_from_accelerance(GRID, accelerance, TABLE)
    carried = estimate_force(GRID, 1.4, RigEstimate(3.4, 50194.0, 5.05, stiffness, damping, mass))
    assert carried.peak_n < 0.2 * truth.max()
    # the probe: the band's edges at a tenth of the level
    probes = (probe_at(20.0, 0.14, **HARD), probe_at(120.0, 0.14, **HARD))
    estimate = estimate_force_from_probe(GRID, 1.4, probes, TABLE, "probe")
    assert estimate.peak_frequency_hz == 20.0 == GRID[np.argmax(truth)]
    # measured there (up to the other point's larger motion ratio or damping), not modelled
    assert estimate.peak_n == pytest.approx(truth.max(), rel=1e-3)
    # conservative over the band (the disc's mass ignored, viscous damping), never far off
    assert np.all(estimate.force_n >= truth * (1 - 1e-9))
    assert np.all(estimate.force_n <= 1.2 * truth)
    # a rigid-link reading of the same probe misses the 10 % the table moves beyond the disc
    assert probes[0].motion_ratio == pytest.approx(1.107, abs=0.01)
    assert estimate.probes == probes and estimate.basis == "probe"


def test_a_band_above_the_resonance_is_covered_by_the_second_probe_point() -> None:
    """Mass-dominated: the force is largest at the high edge, which a spring through the low
    probe point alone would underestimate."""
    soft = {"specimen_stiffness": 1.5e5, "specimen_damping": 115.0, "disc_mass_kg": 0.6}
    grid = np.arange(60.0, 400.5, 0.5)
    truth = needed_force(grid, 10.0, **soft)
    low_only = estimate_force_from_probe(grid, 10.0, (probe_at(60.0, 1.0, **soft),), TABLE, "")
    assert low_only.force_n[-1] < 0.9 * truth[-1]
    both = estimate_force_from_probe(grid, 10.0, (probe_at(60.0, 1.0, **soft),
                                                  probe_at(400.0, 1.0, **soft)), TABLE, "")
    assert np.all(both.force_n >= truth * (1 - 1e-9))
    assert both.peak_n == pytest.approx(truth.max(), rel=0.02)


def test_a_probe_without_known_table_predicts_the_bare_table() -> None:
    grid = np.arange(12.0, 28.125, 0.125)
    bare = {"specimen_stiffness": 0.0, "specimen_damping": 0.0, "disc_mass_kg": 0.0}
    truth = needed_force(grid, 1.4, **bare)
    probes = (probe_at(12.0, 0.14, **bare), probe_at(28.0, 0.14, **bare))
    estimate = estimate_force_from_probe(grid, 1.4, probes, None, "")
    assert estimate.peak_n == pytest.approx(truth.max(), rel=1e-9)
    assert np.all(estimate.force_n >= truth * (1 - 1e-9))


def test_an_unusable_probe_reading_is_not_used() -> None:
    good = probe_at(20.0, 0.14, **HARD)
    assert good.usable
    assert not replace(good, dynamic_stiffness_n_per_m=complex(math.nan, 0.0)).usable
    assert not replace(good, force_n=0.0).usable
    assert not replace(good, flags=int(INPUT_OVERLOAD)).usable
    with pytest.raises(ValueError, match="no usable probe"):
        estimate_force_from_probe(GRID, 1.4, (replace(good, force_n=math.nan),), TABLE, "")
    # the unusable high point is left out; the low one still predicts the peak
    estimate = estimate_force_from_probe(
        GRID, 1.4, (good, replace(probe_at(120.0, 0.14, **HARD), flags=int(INPUT_OVERLOAD))),
        TABLE, "")
    assert estimate.peak_n == pytest.approx(needed_force(GRID, 1.4, **HARD).max(), rel=1e-3)


def test_motion_ratio_of_a_measured_run() -> None:
    assert motion_ratio([0.5, 0.4, np.nan], [2.0, 2.0, 1.0], [1.0, 1.0, 1.0]) == 1.0
    assert motion_ratio([np.nan], [1.0], [1.0]) == 1.0  # nothing measured: a rigid link
