"""FRFs as universal file dataset 58 (read and written with pyuff).

Export writes one dataset 58 record per FRF, preceded by dataset 164 (units: SI, metre and
newton; written first, it also keeps pyuff 2.5 from truncating a leading binary 58 record when
it overwrites a file):

- function type 4 (frequency response function), complex double ordinate (type 6);
- abscissa: data type 18 (frequency), label "Hz", uneven spacing so that every frequency is
  written as it was measured;
- ordinate: data type 12 (acceleration), length exponent 1, label "m/s^2";
- denominator: data type 13 (excitation force), force exponent 1, label "N";
- the table FRF ẍ_s/F_e is response and reference node 1 ("table"), the support FRF ẍ_v/F_v
  node 2 ("disc"), both in direction +X (1); ID line 1 names the run and the dataset
  (``viscorig soft-0 accelerance_table``), ID line 4 the campaign, specimen and flagged points.

The default is binary 58 (``58b``): the numbers are IEEE doubles, so a round trip returns the
same float64 values. Plain ASCII 58 (``binary=False``) is readable by more old tools but stores
values with 12 significant digits and uneven abscissae with 6 (format E13.5).

Import accepts any dataset 58 of function type 4 whose ordinate is acceleration, velocity or
displacement and whose denominator is a force; units come from the axis labels, else from the
file's dataset 164. The records go to the run in order (first ẍ_s/F_e, then ẍ_v/F_v) unless ID
line 1 names the dataset as viscorig writes it.

A universal file is a sequence of datasets, each between two ``    -1`` delimiter lines. pyuff
silently drops a last dataset that has lost its closing delimiter, and reads as many points as
the bytes it finds; so before pyuff reads it, a file must end with a closing delimiter, and
after, every FRF must hold the number of points its record 7 declares, every one finite.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pyuff

from viscorig.errors import InputError
from viscorig.exchange import units
from viscorig.exchange.atomicfile import write_via_path
from viscorig.exchange.frfset import FrfSet, combine_frfs
from viscorig.storage import RunRecord
from viscorig.storage.layout import MAX_RUN_POINTS
from viscorig.version import __version__

FRF_FUNCTION_TYPE = 4
FREQUENCY_DATA_TYPE = 18
DISPLACEMENT_DATA_TYPE = 8
VELOCITY_DATA_TYPE = 11
ACCELERATION_DATA_TYPE = 12
REACTION_FORCE_DATA_TYPE = 9
EXCITATION_FORCE_DATA_TYPE = 13
COMPLEX_TYPES = (5, 6)
#: The largest universal file read (two FRFs of the most points a run holds, in ASCII, are
#: about 12 MB).
MAX_UFF_BYTES = 64 * 1024 * 1024
DELIMITER = b"    -1"

#: dataset name -> (node, entity name, description)
_NODES = {
    "accelerance_table": (1, "table", "x''_s/F_e: table acceleration / excitation force"),
    "accelerance_support": (2, "disc", "x''_v/F_v: disc acceleration / load-cell force"),
}


def _frf_record(run: RunRecord, name: str, campaign_name: str, binary: bool) -> dict[str, Any]:
    node, entity, description = _NODES[name]
    values = np.asarray(getattr(run, name), dtype=complex)
    flagged = int(np.count_nonzero(run.flags))
    m = run.metadata
    record = pyuff.prepare_58(
        binary=int(binary),
        id1=f"viscorig {run.name} {name}"[:80],
        id2=description[:80],
        id3=(m.finished or m.started or "NONE")[:80],
        id4=f"campaign {campaign_name}; specimen {m.specimen}; preload_strain "
            f"{m.preload_strain:g}; flagged points {flagged}"[:80],
        id5=f"viscorig {__version__}"[:80],
        func_type=FRF_FUNCTION_TYPE,
        ver_num=0,
        load_case_id=0,
        rsp_ent_name=entity,
        rsp_node=node,
        rsp_dir=1,
        ref_ent_name=entity,
        ref_node=node,
        ref_dir=1,
        ord_data_type=6,
        num_pts=values.size,
        abscissa_spacing=0,
        abscissa_min=float(run.frequency_hz[0]),
        abscissa_inc=0.0,
        z_axis_value=0.0,
        abscissa_spec_data_type=FREQUENCY_DATA_TYPE,
        abscissa_len_unit_exp=0,
        abscissa_force_unit_exp=0,
        abscissa_temp_unit_exp=0,
        abscissa_axis_units_lab="Hz",
        ordinate_spec_data_type=ACCELERATION_DATA_TYPE,
        ordinate_len_unit_exp=1,
        ordinate_force_unit_exp=0,
        ordinate_temp_unit_exp=0,
        ordinate_axis_units_lab="m/s^2",
        orddenom_spec_data_type=EXCITATION_FORCE_DATA_TYPE,
        orddenom_len_unit_exp=0,
        orddenom_force_unit_exp=1,
        orddenom_temp_unit_exp=0,
        orddenom_axis_units_lab="N",
        z_axis_spec_data_type=0,
        z_axis_len_unit_exp=0,
        z_axis_force_unit_exp=0,
        z_axis_temp_unit_exp=0,
        z_axis_axis_units_lab="NONE",
        data=values,
        x=np.asarray(run.frequency_hz, dtype=float),
        spec_data_type=0,
        return_full_dict=True,
    )
    record.update(abscissa_axis_lab="Frequency", ordinate_axis_lab="Acceleration",
                  orddenom_axis_lab="Force", z_axis_axis_lab="NONE")
    return record


def uff_records(run: RunRecord, campaign_name: str = "",
                binary: bool = True) -> list[dict[str, Any]]:
    """The pyuff datasets for a run: dataset 164 (SI), then one dataset 58 per FRF it has."""
    if not run.points:
        raise InputError("has no measured point to export", f"run '{run.name}'")
    records: list[dict[str, Any]] = [
        pyuff.prepare_164(units_code=1, units_description="SI: meter (newton)", temp_mode=1,
                          length=1.0, force=1.0, temp=1.0, temp_offset=273.15,
                          return_full_dict=True)
    ]
    for name in _NODES:
        values = getattr(run, name)
        if np.all(np.isnan(values)):
            continue  # the support FRF of a bare-table run
        records.append(_frf_record(run, name, campaign_name, binary))
    return records


def write_uff(run: RunRecord, path: Path, campaign_name: str = "", *, binary: bool = True) -> int:
    """Write a run's FRFs to a universal file (replaced atomically); return the FRF count."""
    if run.points < 2:
        raise InputError(f"{run.points} point(s); a universal file's frequency response holds "
                         "two or more", f"run '{run.name}'")
    records = uff_records(run, campaign_name, binary)

    def write(temporary: Path) -> None:
        with contextlib.redirect_stdout(io.StringIO()):  # pyuff prints its warnings
            pyuff.UFF(str(temporary)).write_sets(records, mode="overwrite")

    write_via_path(Path(path), write)
    return len(records) - 1


def _label(record: dict[str, Any], key: str) -> str:
    text = str(record.get(key, "") or "").strip()
    return "" if text.upper() == "NONE" else text


#: Factors of a unit system to SI a dataset 164 may state: from nanometres and micronewtons
#: to kilometres and meganewtons, with room to spare.
UNIT_FACTOR_RANGE = (1e-12, 1e12)


def _direction_sign(record: dict[str, Any], where: str) -> float:
    """+1, or -1 where the response or the reference is along a negative axis (record 6's
    directions ``-1..-6``): the response to a force along +X is minus that along -X."""
    sign = 1.0
    for key, name in (("rsp_dir", "response"), ("ref_dir", "reference")):
        try:
            direction = int(record.get(key, 0))
        except (TypeError, ValueError):
            raise InputError(f"{name} direction {record.get(key)!r} is not a number",
                             where) from None
        if not -6 <= direction <= 6:
            raise InputError(f"{name} direction {direction} is none of -6..6", where)
        sign *= -1.0 if direction < 0 else 1.0
    return sign


def _system_factors(unit_set: dict[str, Any] | None, where: str) -> tuple[float, float] | None:
    """(length, force) factors file units -> SI from dataset 164 (SI = divide by the factor);
    ``None`` without one."""
    if unit_set is None:
        return None
    try:
        length, force = float(unit_set["length"]), float(unit_set["force"])
    except (KeyError, TypeError, ValueError):
        return None
    low, high = UNIT_FACTOR_RANGE
    for name, factor in (("length", length), ("force", force)):
        if not low <= factor <= high:
            raise InputError(f"{name} factor {factor:g} is not a unit's factor to SI (from "
                             f"{low:g} to {high:g})", f"{where}: dataset 164")
    return 1.0 / length, 1.0 / force


def _ordinate_factor(record: dict[str, Any], system: tuple[float, float] | None, where: str
                     ) -> tuple[float, int]:
    """(factor to SI, power of iω that turns the ordinate into acceleration)."""
    kind = int(record.get("ordinate_spec_data_type", 0))
    label = _label(record, "ordinate_axis_units_lab")
    tables = {
        ACCELERATION_DATA_TYPE: (units.ACCELERATION_UNITS, "acceleration", 0),
        VELOCITY_DATA_TYPE: (units.VELOCITY_UNITS, "velocity", 1),
        DISPLACEMENT_DATA_TYPE: (units.DISPLACEMENT_UNITS, "displacement", 2),
    }
    if kind not in tables:
        raise InputError(
            f"ordinate data type {kind} is not acceleration (12), velocity (11) or "
            "displacement (8)", where)
    table, quantity, power = tables[kind]
    if label:
        return units.factor(label, table, quantity, f"{where}: ordinate units"), power
    if system is None:
        raise InputError("states no ordinate units (no label, no dataset 164)", where)
    return system[0] ** int(record.get("ordinate_len_unit_exp", 1)), power


def _denominator_factor(record: dict[str, Any], system: tuple[float, float] | None, where: str
                        ) -> float:
    kind = int(record.get("orddenom_spec_data_type", 0))
    label = _label(record, "orddenom_axis_units_lab")
    if kind not in (EXCITATION_FORCE_DATA_TYPE, REACTION_FORCE_DATA_TYPE) and not (
        kind == 0 and label
    ):
        raise InputError(f"denominator data type {kind} is not a force (13 or 9)", where)
    if label:
        return units.factor(label, units.FORCE_UNITS, "force", f"{where}: denominator units")
    if system is None:
        raise InputError("states no denominator units (no label, no dataset 164)", where)
    return system[1] ** int(record.get("orddenom_force_unit_exp", 1))


def _abscissa_hz(record: dict[str, Any], where: str) -> np.ndarray:
    kind = int(record.get("abscissa_spec_data_type", 0))
    label = _label(record, "abscissa_axis_units_lab")
    if kind not in (FREQUENCY_DATA_TYPE, 0) or (kind == 0 and not label):
        raise InputError(f"abscissa data type {kind} is not frequency (18)", where)
    scale = units.factor(label, units.FREQUENCY_UNITS, "frequency", f"{where}: abscissa units") \
        if label else 1.0
    return np.asarray(record["x"], dtype=float) * scale


def _delimiters(data: bytes) -> list[int]:
    """Offsets of the ``    -1`` delimiter lines, found as pyuff finds them."""
    found, at = [], data.find(DELIMITER)
    while at != -1:
        end = at + len(DELIMITER)
        if end == len(data) or data[end] in (10, 13) or data[end:at + 80] == b" " * (80 - 6):
            found.append(at)
        at = data.find(DELIMITER, at + 1)
    return found


def check_blocks(data: bytes, where: str) -> None:
    """Refuse a universal file whose last dataset is not closed (a truncated file).

    Raises
    ------
    InputError
        No delimiter, an odd number of them, or anything but blanks after the last.
    """
    delimiters = _delimiters(data)
    if not delimiters:
        raise InputError("no universal-file dataset found (not a UFF file?)", where)
    if len(delimiters) % 2:
        raise InputError(f"the dataset that starts at byte {delimiters[-1]} has no closing "
                         f"'    -1' line: the file is truncated", where)
    tail = data[delimiters[-1] + len(DELIMITER):]
    if tail.strip():
        raise InputError(f"{len(tail.strip())} bytes after the last dataset's closing "
                         "'    -1' line: a dataset without delimiters, or a damaged file", where)


def _check_points(record: dict[str, Any], here: str) -> None:
    declared = int(record.get("num_pts", -1))
    found, axis = np.asarray(record["data"]).size, np.asarray(record["x"]).size
    if declared > MAX_RUN_POINTS:
        raise InputError(f"declares {declared} points; a run holds at most {MAX_RUN_POINTS}",
                         here)
    if found != declared or axis != declared:
        raise InputError(f"declares {declared} points but holds {found} values and {axis} "
                         "frequencies: a truncated or damaged record", here)


def read_uff(path: Path) -> FrfSet:
    """Read the FRFs (dataset 58, function type 4) of a universal file as accelerances.

    Raises
    ------
    InputError
        The file is missing or not a universal file, holds no FRF or more than two, an FRF is
        not complex, or its units are not acceleration (or velocity, displacement) over force.
    """
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise InputError("no such file", where)
    size = path.stat().st_size
    if size > MAX_UFF_BYTES:
        raise InputError(f"{size} bytes; a universal file of one run is read up to "
                         f"{MAX_UFF_BYTES}", where)
    try:
        check_blocks(path.read_bytes(), where)
    except OSError as error:
        raise InputError(f"cannot read the file ({error.strerror})", where) from None
    try:
        with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            uff = pyuff.UFF(str(path))
            types = [int(t) for t in uff.get_set_types()]
            sets = [uff.read_sets(i) if t in (58, 164) else {} for i, t in enumerate(types)]
    except Exception as error:  # pyuff raises bare Exception for any malformed block
        raise InputError(f"not a readable universal file ({error})", where) from None
    if not types:
        raise InputError("no universal-file dataset found (not a UFF file?)", where)
    unit_sets = [s for s, t in zip(sets, types, strict=True) if t == 164]
    system = _system_factors(unit_sets[0] if unit_sets else None, where)
    frfs: dict[str, tuple[np.ndarray, np.ndarray, str]] = {}
    first: dict[str, int] = {}  # the dataset that named each
    ordered: list[tuple[np.ndarray, np.ndarray, str]] = []
    for index, (record, kind) in enumerate(zip(sets, types, strict=True)):
        if kind != 58 or int(record.get("func_type", -1)) != FRF_FUNCTION_TYPE:
            continue
        here = f"{where}: dataset {index + 1} (58, '{_label(record, 'id1')}')"
        if int(record.get("ord_data_type", 0)) not in COMPLEX_TYPES:
            raise InputError("ordinate is real; a frequency response must be complex", here)
        _check_points(record, here)
        frequency = _abscissa_hz(record, here)
        ordinate, power = _ordinate_factor(record, system, here)
        denominator = _denominator_factor(record, system, here)
        values = np.asarray(record["data"], dtype=np.complex128) * (ordinate / denominator)
        values = values * _direction_sign(record, here)
        if values.shape != frequency.shape:
            raise InputError(f"{values.size} values but {frequency.size} frequencies", here)
        if power:
            values = values * (2j * np.pi * frequency) ** power
        entry = (frequency, values, here)
        named = _label(record, "id1").split()
        if len(named) == 3 and named[0] == "viscorig" and named[2] in _NODES:
            if named[2] in frfs:
                raise InputError(f"a second record named {named[2]}, after dataset "
                                 f"{first[named[2]]}: which FRF each is cannot be told", here)
            frfs[named[2]], first[named[2]] = entry, index + 1
        ordered.append(entry)
    if not ordered:
        raise InputError("holds no frequency response (dataset 58, function type 4)", where)
    if len(ordered) > 2:
        raise InputError(f"holds {len(ordered)} frequency responses; a run has two", where)
    if frfs and len(frfs) == len(ordered):
        if "accelerance_table" not in frfs:
            raise InputError("holds ẍ_v/F_v but not ẍ_s/F_e; a run needs the table FRF", where)
        ordered = [frfs[name] for name in _NODES if name in frfs]
    return combine_frfs([e[0] for e in ordered], [e[1] for e in ordered], [e[2] for e in ordered],
                   f"UFF {path.name}")
