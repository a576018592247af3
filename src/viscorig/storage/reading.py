"""Reading a campaign file defensively: every defect becomes an InputError naming the object.

A campaign file may come from another program (MATLAB, a colleague's h5py script) or from a
damaged disk, so nothing is trusted: each attribute and dataset is checked for presence, type,
shape and units before it is used.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.storage import layout
from viscorig.storage.records import Fit, FitParameter, Run, RunMetadata

#: What h5py raises on damaged objects, missing members, or values of an unexpected type.
HDF5_FAULTS = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError)


@contextlib.contextmanager
def open_for_reading(path: Path) -> Iterator[h5py.File]:
    """Open a campaign file read-only, turning every failure into an InputError."""
    if not path.exists():
        raise InputError("no such file", str(path))
    if not path.is_file():
        raise InputError("not a file", str(path))
    try:
        h5 = h5py.File(path, "r")
    except HDF5_FAULTS as error:
        reason = str(error).split("(")[0].strip().rstrip(":") or type(error).__name__
        raise InputError(
            f"not a readable HDF5 file (truncated, corrupt or locked): {reason}", str(path)
        ) from None
    try:
        yield h5
    finally:
        with contextlib.suppress(*HDF5_FAULTS):
            h5.close()


@contextlib.contextmanager
def guarded(path: Path, what: str) -> Iterator[None]:
    """Turn an h5py fault while reading ``what`` into an InputError naming it."""
    try:
        yield
    except InputError:
        raise
    except HDF5_FAULTS as error:
        detail = str(error) or type(error).__name__
        raise InputError(f"cannot be read ({detail})", f"{path}: {what}") from None


def _decode(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray) and value.shape == ():
        return _decode(value[()])
    if isinstance(value, np.generic):
        return value.item()
    return value


def read_text(obj: h5py.HLObject, name: str, path: Path) -> str:
    """A string attribute."""
    value = _decode(obj.attrs[name]) if name in obj.attrs else None
    if not isinstance(value, str):
        problem = "missing" if value is None else f"not text ({type(value).__name__})"
        raise InputError(f"attribute {problem}", f"{path}: {obj.name}.{name}")
    return value


def read_number(obj: h5py.HLObject, name: str, path: Path, *, integer: bool = False) -> float:
    """A numeric scalar attribute (NaN allowed for floats)."""
    where = f"{path}: {obj.name}.{name}"
    if name not in obj.attrs:
        raise InputError("attribute missing", where)
    value = _decode(obj.attrs[name])
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"not a number ({type(value).__name__})", where)
    if integer:
        if not math.isfinite(value) or value != int(value):
            raise InputError(f"not a whole number ({value!r})", where)
        return int(value)
    return float(value)


def read_bool(obj: h5py.HLObject, name: str, path: Path) -> bool:
    """A boolean attribute (h5py enum, or 0/1)."""
    where = f"{path}: {obj.name}.{name}"
    if name not in obj.attrs:
        raise InputError("attribute missing", where)
    value = _decode(obj.attrs[name])
    if isinstance(value, bool) or value in (0, 1):
        return bool(value)
    raise InputError(f"not a boolean ({value!r})", where)


def read_choice(obj: h5py.HLObject, name: str, path: Path, choices: tuple[str, ...]) -> str:
    """A text attribute that must be one of ``choices``."""
    value = read_text(obj, name, path)
    if value not in choices:
        where = f"{path}: {obj.name}.{name}"
        raise InputError(f"{value!r} is not one of {', '.join(choices)}", where)
    return value


def check_root(h5: h5py.File, path: Path) -> None:
    """Check the root attributes that make a file a viscorig campaign this code reads."""
    with guarded(path, "/"):
        if "format" not in h5.attrs:
            raise InputError("not a viscorig campaign file (no format attribute)", f"{path}: /")
        name = read_text(h5, "format", path)
        if name != layout.FORMAT_NAME:
            raise InputError(f"format is {name!r}, not {layout.FORMAT_NAME!r}", f"{path}: /")
        version = read_number(h5, "format_version", path, integer=True)
        if version != layout.FORMAT_VERSION:
            raise InputError(
                f"format_version {version} is not {layout.FORMAT_VERSION}, the version this "
                "viscorig reads",
                f"{path}: /",
            )
        group = h5.get(layout.RUNS_GROUP)
        if not isinstance(group, h5py.Group):
            raise InputError("group missing", f"{path}: /{layout.RUNS_GROUP}")


def read_rig(h5: h5py.File, path: Path) -> dict[str, float | int]:
    """The /rig attributes this layout defines (others are kept out); {} if /rig is absent."""
    group = h5.get(layout.RIG_GROUP)
    if group is None:
        return {}
    with guarded(path, f"/{layout.RIG_GROUP}"):
        if not isinstance(group, h5py.Group):
            raise InputError("not a group", f"{path}: /{layout.RIG_GROUP}")
        rig: dict[str, float | int] = {}
        for name in layout.RIG_FLOAT_ATTRIBUTES:
            if name in group.attrs:
                rig[name] = read_number(group, name, path)
        for name in layout.RIG_INT_ATTRIBUTES:
            if name in group.attrs:
                rig[name] = read_number(group, name, path, integer=True)
        return rig


def run_group(h5: h5py.File, name: str, path: Path) -> h5py.Group:
    """The group of run ``name``."""
    where = f"{path}: /{layout.RUNS_GROUP}/{name}"
    runs = h5[layout.RUNS_GROUP]
    if name not in runs:
        known = ", ".join(runs.keys()) or "none"
        raise InputError(f"no such run (runs: {known})", where)
    group = runs[name]
    if not isinstance(group, h5py.Group):
        raise InputError("not a group", where)
    return group


def read_metadata(group: h5py.Group, path: Path) -> RunMetadata:
    """Every attribute of a run, checked."""
    return RunMetadata(
        status=read_choice(group, "status", path, layout.RUN_STATUSES),
        started=read_text(group, "started", path),
        finished=read_text(group, "finished", path),
        specimen=read_text(group, "specimen", path),
        hardness_shore_a=read_number(group, "hardness_shore_a", path),
        preload_strain=read_number(group, "preload_strain", path),
        temperature_c=read_number(group, "temperature_c", path),
        level_m_per_s2=read_number(group, "level_m_per_s2", path),
        direction=read_choice(group, "direction", path, layout.DIRECTIONS),
        settle_cycles=read_number(group, "settle_cycles", path, integer=True),
        integrate_cycles=read_number(group, "integrate_cycles", path, integer=True),
        resolution_hz=read_number(group, "resolution_hz", path),
        instrument=read_text(group, "instrument", path),
        resource=read_text(group, "resource", path),
        simulated=read_bool(group, "simulated", path),
    )


def _complex_from_compound(values: np.ndarray) -> NDArray[np.complex128] | None:
    names = values.dtype.names or ()
    for real, imag in (("r", "i"), ("real", "imag"), ("re", "im"), ("Re", "Im")):
        if set(names) == {real, imag}:
            return values[real].astype(np.float64) + 1j * values[imag].astype(np.float64)
    return None


def read_column(group: h5py.Group, spec: layout.DatasetSpec, path: Path) -> NDArray:
    """One per-point dataset: 1-D, of the expected kind, with the expected units."""
    where = f"{path}: {group.name}/{spec.name}"
    dataset = group.get(spec.name)
    if dataset is None:
        raise InputError("dataset missing", where)
    if not isinstance(dataset, h5py.Dataset):
        raise InputError("not a dataset", where)
    if dataset.ndim != 1:
        raise InputError(f"shape {dataset.shape} is not 1-D", where)
    units = _decode(dataset.attrs.get("units"))
    if not isinstance(units, str):
        raise InputError("no units attribute", where)
    if not layout.unit_matches(spec.units, units):
        raise InputError(f"units {units!r}, expected {spec.units!r}", where)
    dtype = dataset.dtype
    values = dataset[()]
    if spec.kind == "complex":
        if dtype.kind == "c":
            return values.astype(np.complex128)
        converted = _complex_from_compound(values) if dtype.names else None
        if converted is None:
            raise InputError(f"dtype {dtype} is not complex (compound r, i)", where)
        return converted
    if spec.kind == "flags":
        if dtype.kind not in "iu":
            raise InputError(f"dtype {dtype} is not an integer bit mask", where)
        if values.size and (values.min() < 0 or values.max() > 0xFFFF):
            raise InputError("flags outside 0..65535", where)
        return values.astype(np.uint16)
    if dtype.kind not in "fiu":
        raise InputError(f"dtype {dtype} is not a real number", where)
    return values.astype(np.float64)


def read_run(h5: h5py.File, name: str, path: Path) -> Run:
    """A whole run, checked: attributes, datasets, equal lengths."""
    group = run_group(h5, name, path)
    with guarded(path, group.name):
        metadata = read_metadata(group, path)
        columns = {spec.name: read_column(group, spec, path) for spec in layout.REQUIRED_DATASETS}
        for spec in layout.OPTIONAL_DATASETS:
            columns[spec.name] = read_column(group, spec, path) if spec.name in group else None
        extra: dict[str, tuple[NDArray, str]] = {}
        for key, item in group.items():
            if key in layout.KNOWN_DATASETS or not isinstance(item, h5py.Dataset):
                continue
            if item.ndim == 1 and item.dtype.kind in "fiuc":
                extra[key] = (item[()], str(_decode(item.attrs.get("units", ""))))
        lengths = {key: len(value) for key, value in columns.items() if value is not None}
        lengths.update({key: len(value) for key, (value, _) in extra.items()})
        if len(set(lengths.values())) > 1:
            detail = ", ".join(f"{key} {length}" for key, length in lengths.items())
            raise InputError(f"datasets differ in length ({detail})", f"{path}: {group.name}")
        for values in (*columns.values(), *(value for value, _ in extra.values())):
            if values is not None:
                values.setflags(write=False)
        return Run(name=name, metadata=metadata, extra=extra, **columns)


def read_fits(h5: h5py.File, run_name: str, path: Path) -> list[Fit]:
    """The fits of a run, in id order."""
    group = run_group(h5, run_name, path)
    fits_group = group.get(layout.FITS_GROUP)
    if fits_group is None:
        return []
    result = []
    with guarded(path, f"{group.name}/{layout.FITS_GROUP}"):
        for fit_id in sorted(fits_group):
            fit = fits_group[fit_id]
            if not isinstance(fit, h5py.Group):
                raise InputError("not a group", f"{path}: {fit.name}")
            band = np.asarray(fit.attrs.get("band_hz", []), dtype=float).ravel()
            if band.shape != (2,):
                raise InputError("band_hz is not [lo, hi]", f"{path}: {fit.name}.band_hz")
            parameters = {}
            for key, item in fit.items():
                parameter = _read_parameter(item, path)
                if parameter is not None:
                    parameters[key] = parameter
            correlation = _read_correlation(fit, path)
            result.append(
                Fit(
                    id=fit_id,
                    run=run_name,
                    model=read_text(fit, "model", path),
                    band_hz=(float(band[0]), float(band[1])),
                    rms_error=read_number(fit, "rms_error", path),
                    noise_floor=read_number(fit, "noise_floor", path),
                    created=read_text(fit, "created", path),
                    parameters=parameters,
                    correlation=correlation,
                )
            )
    return result


def _read_correlation(
    fit: h5py.Group, path: Path
) -> tuple[tuple[str, ...], NDArray[np.float64]] | None:
    """The fit's correlation matrix and its parameter names, if stored (and well formed)."""
    item = fit.get(layout.FIT_CORRELATION)
    if not isinstance(item, h5py.Dataset) or item.ndim != 2:
        return None
    names = tuple(
        n.decode() if isinstance(n, bytes) else str(n) for n in item.attrs.get("parameters", [])
    )
    matrix = np.asarray(item[()], dtype=float)
    if matrix.shape != (len(names), len(names)):
        raise InputError("correlation does not match its parameter names", f"{path}: {item.name}")
    return names, matrix


def _read_parameter(item: h5py.HLObject, path: Path) -> FitParameter | None:
    """A parameter stored as a scalar dataset (attrs stderr, units) or a group (attrs value,
    stderr, units); other objects in a fit group are not parameters."""
    if isinstance(item, h5py.Dataset):
        if item.shape != () or item.dtype.kind not in "fiu":
            return None
        value = float(item[()])
    else:
        value = read_number(item, "value", path)
    stderr = read_number(item, "stderr", path) if "stderr" in item.attrs else math.nan
    unit = read_text(item, "units", path) if "units" in item.attrs else ""
    return FitParameter(value=value, stderr=stderr, unit=unit)
