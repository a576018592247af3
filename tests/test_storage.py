"""The campaign file: exact layout, round trip, files of other writers, damaged files."""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from viscorig import __version__, frf
from viscorig.errors import InputError
from viscorig.numbers import Estimate
from viscorig.storage import (
    FORCE_ABOVE_SHAKER_LIMIT,
    INPUT_OVERLOAD,
    LEVEL_NOT_REACHED,
    SOURCE_AT_LIMIT,
    CampaignFile,
    PointFlag,
    RunSettings,
    Segment,
    count_flags,
)
from viscorig.storage.atomic import staging_path

SETTINGS = RunSettings(
    specimen="soft 25 Shore A",
    hardness_shore_a=25.0,
    preload_strain=0.104,
    temperature_c=25.0,
    level_m_per_s2=1.4,
    direction="up",
    settle_cycles=100,
    integrate_cycles=100,
    resolution_hz=0.25,
    instrument="HEWLETT-PACKARD,35670A,0,A.02.00",
    resource="GPIB0::11::INSTR",
    simulated=True,
)
RUN_ATTRIBUTES = {
    "status", "started", "finished", "specimen", "hardness_shore_a", "preload_strain",
    "temperature_c", "level_m_per_s2", "direction", "settle_cycles", "integrate_cycles",
    "resolution_hz", "instrument", "resource", "simulated",
}
UNITS = {
    "frequency_hz": "Hz", "time_s": "s", "accelerance_table": "m/s^2/N",
    "accelerance_support": "m/s^2/N", "reference_amplitude": "m/s^2", "source_amplitude": "V",
    "force_amplitude": "N", "flags": "1", "variance_table": "1", "variance_support": "1",
}


def make_segment(start: float, count: int, *, variance: bool = False) -> Segment:
    frequency = start + 0.25 * np.arange(count)
    rng = np.random.default_rng(int(start * 4))
    table = rng.normal(size=count) + 1j * rng.normal(size=count)
    support = rng.normal(size=count) + 1j * rng.normal(size=count)
    return Segment(
        frequency_hz=frequency,
        time_s=np.cumsum(200.0 / frequency),
        accelerance_table=table,
        accelerance_support=support,
        reference_amplitude=np.full(count, 1.4),
        source_amplitude=np.linspace(0.1, 0.5, count),
        force_amplitude=np.linspace(5.0, 90.0, count),
        flags=np.arange(count) % 16,
        variance_table=np.full(count, 1e-4) if variance else None,
        variance_support=np.full(count, 2e-4) if variance else None,
    )


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture()
def campaign_path(tmp_path: Path) -> Path:
    path = tmp_path / "campaign.h5"
    campaign = CampaignFile.create(
        path,
        sequence_text='name = "paper"\n',
        sequence_file="paper.toml",
        station_text='resource = "GPIB0::11::INSTR"\n',
        station_file="lab.toml",
        rig={"table_mass_kg": 3.4, "specimen_count": 2},
        durable=False,
    )
    campaign.start_run("soft-0", SETTINGS)
    campaign.append_segment("soft-0", make_segment(20.0, 30))
    campaign.append_segment("soft-0", make_segment(27.5, 10))
    campaign.finish_run("soft-0")
    return path


def test_written_file_holds_exactly_the_layout(campaign_path: Path) -> None:
    with h5py.File(campaign_path, "r") as h5:
        assert h5.attrs["format"] == "viscorig"
        assert h5.attrs["format_version"] == 1
        assert h5.attrs["software"] == f"viscorig {__version__}"
        created = h5.attrs["created"]
        assert created.endswith("Z") and created[4] == "-" and created[10] == "T"
        assert dict(h5["rig"].attrs) == {"table_mass_kg": 3.4, "specimen_count": 2}
        assert set(h5) == {"rig", "runs", "setup"}
        assert h5["setup/sequence_toml"].asstr()[()] == 'name = "paper"\n'
        assert h5["setup/station_toml"].asstr()[()] == 'resource = "GPIB0::11::INSTR"\n'
        run = h5["runs/soft-0"]
        assert set(run.attrs) == RUN_ATTRIBUTES
        assert run.attrs["status"] == "complete"
        assert run.attrs["finished"] >= run.attrs["started"] != ""
        assert run.attrs["preload_strain"] == 0.104
        assert math.isnan(run.attrs["hardness_shore_a"]) is False
        assert bool(run.attrs["simulated"]) is True
        assert set(run) == set(UNITS) - {"variance_table", "variance_support"}
        for name, dataset in run.items():
            assert dataset.shape == (40,), name
            assert dataset.maxshape == (None,) and dataset.chunks is not None, name
            assert dataset.attrs["units"] == UNITS[name], name
        for name in ("accelerance_table", "accelerance_support"):
            stored = run[name].id.get_type()
            assert stored.get_class() == h5py.h5t.COMPOUND
            assert [stored.get_member_name(i) for i in range(2)] == [b"r", b"i"]
        assert run["flags"].dtype == np.uint16
        assert run["frequency_hz"].dtype == np.float64


def test_round_trip_with_derived_forms(campaign_path: Path) -> None:
    first, second = make_segment(20.0, 30), make_segment(27.5, 10)
    with CampaignFile.open(campaign_path) as campaign:
        assert campaign.run_names == ["soft-0"]
        run = campaign.run("soft-0")
        assert campaign.rig == {"table_mass_kg": 3.4, "specimen_count": 2}
        assert campaign.sequence_text == 'name = "paper"\n'
        assert campaign.station_text == 'resource = "GPIB0::11::INSTR"\n'
        assert campaign.setup_files == {"sequence_file": "paper.toml", "station_file": "lab.toml"}
    assert run.name == "soft-0" and run.points == 40
    assert run.metadata.settings == SETTINGS
    assert run.metadata.status == "complete"
    np.testing.assert_array_equal(
        run.accelerance_table, np.concatenate([first.accelerance_table, second.accelerance_table])
    )
    np.testing.assert_array_equal(run.flags, np.concatenate([np.arange(30), np.arange(10)]) % 16)
    assert run.variance_table is None and run.variance_support is None
    omega = 2 * np.pi * run.frequency_hz
    np.testing.assert_allclose(run.receptance_table(), run.accelerance_table / -(omega**2))
    np.testing.assert_allclose(
        run.dynamic_stiffness_support(),
        frf.accelerance_to_dynamic_stiffness(run.frequency_hz, run.accelerance_support),
    )
    assert run.flagged(SOURCE_AT_LIMIT).sum() == count_flags(run.flags)[SOURCE_AT_LIMIT]
    assert not run.frequency_hz.flags.writeable


def test_optional_variance_is_stored_with_units(tmp_path: Path) -> None:
    path = tmp_path / "v.h5"
    campaign = CampaignFile.create(path, sequence_text="", durable=False)
    campaign.start_run("table", SETTINGS)
    campaign.append_segment("table", make_segment(10.0, 5, variance=True))
    assert campaign.append_segment("table", make_segment(11.25, 3, variance=True)) == 8
    run = campaign.run("table")
    np.testing.assert_array_equal(run.variance_support, np.full(8, 2e-4))
    assert campaign.station_text is None
    with h5py.File(path, "r") as h5:
        assert h5["runs/table/variance_table"].attrs["units"] == "1"
    with pytest.raises(ValueError, match="differ from the run"):
        campaign.append_segment("table", make_segment(12.0, 2))


def test_flag_bits_are_the_contract_values() -> None:
    assert (LEVEL_NOT_REACHED, INPUT_OVERLOAD, SOURCE_AT_LIMIT, FORCE_ABOVE_SHAKER_LIMIT) == (
        1, 2, 4, 8,
    )
    counts = count_flags(np.array([0, 1, 3, 8, 9, 12], dtype=np.uint16))
    assert counts == {
        PointFlag.LEVEL_NOT_REACHED: 3,
        PointFlag.INPUT_OVERLOAD: 1,
        PointFlag.SOURCE_AT_LIMIT: 1,
        PointFlag.FORCE_ABOVE_SHAKER_LIMIT: 3,
        PointFlag.OUTSIDE_SOAK_BAND: 0,
    }
    assert PointFlag.OUTSIDE_SOAK_BAND == 16  # the project's extension (docs/temperature.md)


def test_fits_are_numbered_and_read_back(campaign_path: Path) -> None:
    with CampaignFile.open(campaign_path, mode="a", durable=False) as campaign:
        first = campaign.add_fit(
            "soft-0", model="voigt", band_hz=(20.0, 120.0), rms_error=0.012, noise_floor=0.004,
            parameters={"K_v": (149986.61, 120.0, "N/m"), "C_v": (114.59, 0.8, "N*s/m")},
        )
        second = campaign.add_fit(
            "soft-0", model="maxwell(2)", band_hz=(20, 80), rms_error=0.005, noise_floor=0.004,
            parameters={"K_0": (1.2e5, math.nan, "N/m")},
        )
        assert (first, second) == ("0001", "0002")
        fits = campaign.fits("soft-0")
    assert [fit.model for fit in fits] == ["voigt", "maxwell(2)"]
    assert fits[0].band_hz == (20.0, 120.0) and fits[0].rms_error == 0.012
    assert fits[0].parameters["C_v"].unit == "N*s/m"
    assert fits[0].parameters["K_v"].value == 149986.61
    assert math.isnan(fits[1].parameters["K_0"].stderr)
    with h5py.File(campaign_path, "r") as h5:
        fit = h5["runs/soft-0/fits/0001"]
        assert set(fit.attrs) == {"model", "band_hz", "rms_error", "noise_floor", "created"}
        assert fit["K_v"][()] == 149986.61 and fit["K_v"].attrs["units"] == "N/m"


def test_read_only_campaign_refuses_changes(campaign_path: Path) -> None:
    before = digest(campaign_path)
    with CampaignFile.open(campaign_path) as campaign, pytest.raises(InputError, match="read-only"):
        campaign.add_fit("soft-0", model="voigt", band_hz=(20, 120), rms_error=0.1,
                         noise_floor=0.1, parameters={})
    assert digest(campaign_path) == before


def test_lifecycle_errors_name_the_run(campaign_path: Path) -> None:
    campaign = CampaignFile.open(campaign_path, mode="a", durable=False)
    with pytest.raises(InputError, match=r"/runs/soft-0: run is complete"):
        campaign.append_segment("soft-0", make_segment(30.0, 2))
    with pytest.raises(InputError, match="run exists"):
        campaign.start_run("soft-0", SETTINGS)
    with pytest.raises(InputError, match="not a valid name"):
        campaign.start_run("a/b", SETTINGS)
    # a text the file's readers refuse is not written (a run's attributes half set)
    with pytest.raises(InputError, match="specimen: text of 70000 bytes; at most 65536"):
        campaign.start_run("long", replace(SETTINGS, specimen="S" * 70_000))
    with pytest.raises(InputError, match="specimen: text with a NUL character"):
        campaign.start_run("nul", replace(SETTINGS, specimen="a\x00b"))
    assert "long" not in campaign.run_names and "nul" not in campaign.run_names
    with pytest.raises(InputError, match="no such run"):
        campaign.fits("hard-10")
    assert campaign.resume_run("soft-0") == 40
    assert campaign.append_segment("soft-0", make_segment(30.0, 2)) == 42
    assert not staging_path(campaign_path).exists()
    before = digest(campaign_path)
    with pytest.raises(InputError, match="never overwritten"):
        CampaignFile.create(campaign_path, sequence_text="")
    assert digest(campaign_path) == before


def test_inconsistent_segment_is_refused_before_any_write(campaign_path: Path) -> None:
    with pytest.raises(ValueError, match="differ in length"):
        Segment([1.0, 2.0], [1.0], [1j], [1j], [1.0], [1.0], [1.0], [0]).columns()
    with pytest.raises(ValueError, match="16 bits"):
        Segment([1.0], [1.0], [1j], [1j], [1.0], [1.0], [1.0], [70000]).columns()
    # a frequency the file's reader refuses is not written
    for frequency in (0.0, -1.0, 2e6, np.nan):
        with pytest.raises(ValueError, match=r"1 of 2 frequencies are not numbers from 1e-06 "
                                             r"to 1e\+06 Hz \(the first, point 2"):
            Segment([1.0, frequency], [1.0, 2.0], [1j, 1j], [1j, 1j], [1.0, 1.0], [1.0, 1.0],
                    [1.0, 1.0], [0, 0]).columns()


@pytest.mark.parametrize(("field", "value", "said"), [
    ("level_m_per_s2", 1e308, "a finite number above 0 and at most 10000"),
    ("level_m_per_s2", 0.0, "a finite number above 0 and at most 10000"),
    ("hardness_shore_a", 160.0, "a finite number at least 0 and at most 100"),
    ("settle_cycles", 2**62, "a whole number at least 0 and at most 1e+09"),
    ("resolution_hz", -0.25, "a finite number above 0 and at most 1e+06"),
    ("temperature_c", -300.0, "a finite number above -273.15 and at most 1500"),
])
def test_run_settings_the_reader_refuses_are_not_written(
        campaign_path: Path, field: str, value: float, said: str) -> None:
    campaign = CampaignFile.open(campaign_path, mode="a", durable=False)
    before = digest(campaign_path)
    with pytest.raises(InputError, match=f"{field}: .*, which no reader of the file takes "
                                         + re.escape(f"({said})")):
        campaign.start_run("soft-10", replace(SETTINGS, **{field: value}))
    assert "soft-10" not in campaign.run_names and digest(campaign_path) == before


def test_a_fit_the_reader_refuses_is_not_written(campaign_path: Path) -> None:
    campaign = CampaignFile.open(campaign_path, mode="a", durable=False)
    before = digest(campaign_path)
    with pytest.raises(InputError, match="parameter K_v = nan, which no reader"):
        campaign.add_fit("soft-0", model="voigt", band_hz=(20.0, 40.0), rms_error=0.01,
                         noise_floor=0.01, parameters={"K_v": (np.nan, 1.0, "N/m")})
    with pytest.raises(InputError, match=r"is not 0 <= lo < hi <= 1e\+06 Hz"):
        campaign.add_fit("soft-0", model="voigt", band_hz=(20.0, 2e6), rms_error=0.01,
                         noise_floor=0.01, parameters={"K_v": (1.0, 1.0, "N/m")})
    assert campaign.fits("soft-0") == [] and digest(campaign_path) == before


def write_plain_campaign(path: Path, *, real_imag_names: tuple[str, str] = ("r", "i")) -> None:
    """A campaign written by another program with plain h5py, as data-format.md describes."""
    complex_type = np.dtype([(real_imag_names[0], "<f8"), (real_imag_names[1], "<f8")])
    with h5py.File(path, "w") as h5:
        h5.attrs.update({"format": "viscorig", "format_version": 1,
                         "created": "2024-05-01T12:00:00Z", "software": "matlab-export 1.0"})
        h5.create_group("rig").attrs["table_stiffness_n_per_m"] = 50194.0
        run = h5.create_group("runs/table")
        run.attrs.update({
            "status": "aborted", "started": "2024-05-01T12:00:01Z",
            "finished": "2024-05-01T12:10:00Z", "specimen": "none", "hardness_shore_a": np.nan,
            "preload_strain": 0.0, "temperature_c": 24.5, "level_m_per_s2": 1.4,
            "direction": "down", "settle_cycles": 50, "integrate_cycles": 20,
            "resolution_hz": 0.5, "instrument": "", "resource": "", "simulated": 0,
        })
        frequency = np.array([30.0, 29.5, 29.0])
        columns = {
            "frequency_hz": (frequency, "Hz"),
            "time_s": (np.array([3.0, 6.0, 9.0]), "s"),
            "reference_amplitude": (np.full(3, 1.4), "m/s^2"),
            "source_amplitude": (np.full(3, 0.2), "V"),
            "force_amplitude": (np.array([1, 2, 3], dtype=np.int32), "N"),
            "flags": (np.array([0, 1, 9], dtype=np.int32), "1"),
            "probe_temperature": (np.array([24.5, 24.6, 24.7]), "degC"),
        }
        for name, values in (("accelerance_table", (1.0, -2.0)), ("accelerance_support",
                                                                 (np.nan, np.nan))):
            data = np.zeros(3, dtype=complex_type)
            data[real_imag_names[0]], data[real_imag_names[1]] = values
            columns[name] = (data, "m/s^2/N")
        for name, (values, units) in columns.items():
            run.create_dataset(name, data=values).attrs["units"] = units


@pytest.mark.parametrize("names", [("r", "i"), ("real", "imag")])
def test_reads_a_file_written_with_plain_h5py(tmp_path: Path, names: tuple[str, str]) -> None:
    path = tmp_path / "other.h5"
    write_plain_campaign(path, real_imag_names=names)
    with CampaignFile.open(path) as campaign:
        run = campaign.run("table")
        assert campaign.rig == {"table_stiffness_n_per_m": 50194.0}
        assert campaign.sequence_text is None and campaign.fits("table") == []
    assert run.metadata.status == "aborted" and run.metadata.direction == "down"
    assert run.metadata.simulated is False and run.metadata.settle_cycles == 50
    np.testing.assert_array_equal(run.accelerance_table, np.full(3, 1.0 - 2.0j))
    assert np.isnan(run.accelerance_support).all()
    assert run.force_amplitude.dtype == np.float64 and run.flags.dtype == np.uint16
    assert run.extra["probe_temperature"][1] == "degC"


def as_matlab_writes(path: Path) -> None:
    """Rewrite every attribute of a campaign file as MATLAB's ``h5writeatt`` stores it: each
    number in an array of one value, each text a fixed-length string, and the fit's parameter
    datasets as 1 × 1 matrices (MATLAB has no scalars)."""
    with h5py.File(path, "r+") as h5:
        def rewrite(name: str, obj: h5py.HLObject) -> None:
            for key, value in list(obj.attrs.items()):
                if isinstance(value, str):
                    obj.attrs[key] = np.bytes_(value.encode())
                elif np.ndim(value) == 0:
                    obj.attrs[key] = np.array([value], dtype=np.asarray(value).dtype)
        rewrite("/", h5)
        h5.visititems(rewrite)
        fit = h5.create_group("runs/table/fits/0001")
        for key, value in (("model", "voigt"), ("created", "2024-05-01T12:11:00Z")):
            fit.attrs[key] = np.bytes_(value.encode())
        fit.attrs["band_hz"] = np.array([[12.0, 28.0]])
        for key, value in (("rms_error", 0.01), ("noise_floor", 0.008)):
            fit.attrs[key] = np.array([value])
        parameter = fit.create_dataset("K_v", data=np.array([[1.2e5]]))
        parameter.attrs["stderr"] = np.array([300.0])
        parameter.attrs["units"] = np.bytes_(b"N/m")


def test_reads_a_file_whose_single_values_are_arrays_of_one_as_matlab_writes(
        tmp_path: Path) -> None:
    path = tmp_path / "matlab.h5"
    write_plain_campaign(path)
    with CampaignFile.open(path) as campaign:
        before = campaign.run("table")
    as_matlab_writes(path)
    with h5py.File(path, "r") as h5:  # (what the file holds, as h5py shows it)
        assert h5.attrs["format_version"].shape == (1,)
        assert h5["runs/table"].attrs["level_m_per_s2"].shape == (1,)
    with CampaignFile.open(path) as campaign:
        run = campaign.run("table")
        assert campaign.rig == {"table_stiffness_n_per_m": 50194.0}
        (fit,) = campaign.fits("table")
    assert repr(run.metadata) == repr(before.metadata)  # (repr: NaN equals NaN)
    assert fit.band_hz == (12.0, 28.0) and fit.rms_error == 0.01
    assert fit.parameters["K_v"] == Estimate(1.2e5, 300.0, "N/m")


def test_a_vector_stored_as_a_one_row_matrix_is_named_with_how_to_write_it(
        tmp_path: Path) -> None:
    path = tmp_path / "matlab.h5"
    write_plain_campaign(path)
    with h5py.File(path, "r+") as h5:
        frequency = h5["runs/table/frequency_hz"][()]
        del h5["runs/table/frequency_hz"]
        h5["runs/table"].create_dataset("frequency_hz", data=frequency[None, :]).attrs[
            "units"] = "Hz"
    expected = (r"frequency_hz: shape \(1, 3\) is not 1-D: a vector stored as a one-row matrix "
                r"\(in MATLAB, h5create\(file, name, N\)\)")
    with pytest.raises(InputError, match=expected), CampaignFile.open(path) as campaign:
        campaign.run("table")


def damage(path: Path, how: str) -> str:
    """Damage a valid campaign file with plain h5py; return the object the error must name."""
    if how == "not hdf5":
        path.write_text("frequency,accelerance\n20,1\n")
        return "not a readable HDF5 file"
    if how.startswith("truncated"):
        size = path.stat().st_size
        with open(path, "r+b") as handle:
            handle.truncate(int(size * float(how.split()[1])))
        return "not a readable HDF5 file"
    with h5py.File(path, "r+") as h5:
        run = h5["runs/soft-0"]
        if how == "no runs group":
            del h5["runs"]
            return "/runs: group missing"
        if how == "wrong format":
            h5.attrs["format"] = "other"
            return "/: format is 'other'"
        if how == "newer version":
            h5.attrs["format_version"] = 2
            return "format_version 2"
        if how == "missing dataset":
            del run["flags"]
            return "/runs/soft-0/flags: dataset missing"
        if how == "wrong dtype":
            del run["frequency_hz"]
            run.create_dataset("frequency_hz", data=np.array([b"x"] * 40)).attrs["units"] = "Hz"
            return "/runs/soft-0/frequency_hz: dtype"
        if how == "complex as real":
            del run["accelerance_table"]
            run.create_dataset("accelerance_table", data=np.ones(40)).attrs["units"] = "m/s^2/N"
            return "/runs/soft-0/accelerance_table: dtype float64 is not complex"
        if how == "wrong shape":
            del run["time_s"]
            run.create_dataset("time_s", data=np.ones((20, 2))).attrs["units"] = "s"
            return "/runs/soft-0/time_s: shape (20, 2)"
        if how == "wrong units":
            run["frequency_hz"].attrs["units"] = "kHz"
            return "/runs/soft-0/frequency_hz: units 'kHz'"
        if how == "no units":
            del run["force_amplitude"].attrs["units"]
            return "/runs/soft-0/force_amplitude: no units"
        if how == "short dataset":
            run["source_amplitude"].resize((39,))
            return "/runs/soft-0: datasets differ in length"
        if how == "bad status":
            run.attrs["status"] = "finished"
            return "/runs/soft-0.status: 'finished' is not one of"
        if how == "missing attribute":
            del run.attrs["level_m_per_s2"]
            return "/runs/soft-0.level_m_per_s2: attribute missing"
        if how == "text for number":
            run.attrs["preload_strain"] = "10 %"
            return "/runs/soft-0.preload_strain: not a number"
        if how == "infinite level":
            run.attrs["level_m_per_s2"] = np.inf
            return "/runs/soft-0.level_m_per_s2: inf; needs a finite number above 0"
        if how == "negative resolution":
            run.attrs["resolution_hz"] = -0.25
            return "/runs/soft-0.resolution_hz: -0.25; needs a finite number above 0"
        if how == "hardness past the scale":
            run.attrs["hardness_shore_a"] = 160.0
            return "/runs/soft-0.hardness_shore_a: 160.0; needs a finite number at least 0 " \
                "and at most 100"
        if how == "below absolute zero":
            run.attrs["temperature_c"] = -300.0
            return "/runs/soft-0.temperature_c: -300.0; needs a finite number above -273.15"
        if how == "level past any shaker":
            run.attrs["level_m_per_s2"] = 1e308
            return "/runs/soft-0.level_m_per_s2: 1e+308; needs a finite number above 0 and " \
                "at most 10000"
        if how == "cycles past any run":
            run.attrs["settle_cycles"] = np.int64(2**62)
            return "/runs/soft-0.settle_cycles: 4611686018427387904; needs a whole number " \
                "at least 0 and at most 1e+09"
        if how == "resolution past any analyser":
            run.attrs["resolution_hz"] = 1e308
            return "/runs/soft-0.resolution_hz: 1e+308; needs a finite number above 0 and " \
                "at most 1e+06"
        if how == "run is a dataset":
            del h5["runs/soft-0"]
            h5["runs/soft-0"] = np.zeros(3)
            return "/runs/soft-0: not a group"
    raise AssertionError(how)


DAMAGES = [
    "not hdf5", "truncated 0.5", "truncated 0.9", "truncated 0.01", "no runs group",
    "wrong format", "newer version", "missing dataset", "wrong dtype", "complex as real",
    "wrong shape", "wrong units", "no units", "short dataset", "bad status",
    "missing attribute", "text for number", "infinite level", "negative resolution",
    "hardness past the scale", "below absolute zero", "level past any shaker",
    "cycles past any run", "resolution past any analyser", "run is a dataset",
]


@pytest.mark.parametrize("how", DAMAGES)
def test_damaged_file_is_one_input_error_and_unchanged(campaign_path: Path, how: str) -> None:
    expected = damage(campaign_path, how)
    before = digest(campaign_path)
    with pytest.raises(InputError) as caught, CampaignFile.open(campaign_path) as campaign:
        campaign.run("soft-0")
    message = str(caught.value)
    assert message.startswith(str(campaign_path)), message
    assert expected in message
    assert "\n" not in message
    with pytest.raises(InputError):  # appending is refused as well, and writes nothing
        campaign = CampaignFile.open(campaign_path, mode="a", durable=False)
        campaign.append_segment("soft-0", make_segment(40.0, 2))
    assert digest(campaign_path) == before
    assert not staging_path(campaign_path).exists()


def test_missing_file_and_folder_are_input_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        CampaignFile.open(tmp_path / "absent.h5")
    with pytest.raises(InputError, match="not a file"):
        CampaignFile.open(tmp_path)
    with pytest.raises(InputError, match="cannot create"):
        CampaignFile.create(tmp_path / "no-folder" / "c.h5", sequence_text="")
    with pytest.raises(InputError, match="unknown /rig attribute 'mass'"):
        CampaignFile.create(tmp_path / "c.h5", sequence_text="", rig={"mass": 3.4})
    assert not (tmp_path / "c.h5").exists()


@pytest.mark.parametrize("name", ["soft-0\n", "soft-0\r", "", "-x", "a/b", "x" * 65])
def test_a_name_is_refused_unless_it_is_plain_to_its_end(name: str) -> None:
    from viscorig.storage.campaign import check_name

    with pytest.raises(InputError, match="not a valid name"):
        check_name(name, "run name")


@pytest.mark.parametrize(("name", "value", "said"), [
    ("table_mass_kg", -3.4, "-3.4; needs a finite number above 0"),
    ("table_stiffness_n_per_m", 0.0, "0.0; needs a finite number above 0"),
    ("table_damping_ns_per_m", -50.0, "-50.0; needs a finite number at least 0"),
    ("geometry_factor_m", np.inf, "inf; needs a finite number above 0"),
    ("geometry_factor_m", 1e300, "1e+300; needs a finite number above 0 and at most 1e+06"),
    ("specimen_diameter_m", 25.0, "25.0; needs a finite number above 0 and at most 10"),
    ("table_mass_kg", 1e9, "1000000000.0; needs a finite number above 0 and at most 100000")])
def test_a_rig_value_no_rig_has_is_refused(tmp_path: Path, name: str, value: float,
                                           said: str) -> None:
    """A negative table mass in /rig was held fixed in every specimen fit ('M_s = -3.4
    fixed'), and an infinite geometry factor was dropped without a word."""
    path = tmp_path / "c.h5"
    CampaignFile.create(path, sequence_text="", durable=False).close()
    with h5py.File(path, "r+") as h5:
        h5.require_group("rig").attrs[name] = value
    with pytest.raises(InputError, match=re.escape(f"/rig.{name}: {said}")):
        assert CampaignFile.open(path).rig is None
    # and the writer writes no file its reader refuses
    with pytest.raises(InputError, match=re.escape(f"{name} = {value!r}, which no reader")):
        CampaignFile.create(tmp_path / "d.h5", sequence_text="", rig={name: value})
    assert not (tmp_path / "d.h5").exists()
