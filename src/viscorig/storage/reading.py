"""Reading a campaign file defensively: every defect becomes an InputError naming the object.

A campaign file may come from another program (MATLAB, a colleague's h5py script) or from a
damaged disk, so nothing is trusted: the structure is checked before any value is read
(:mod:`viscorig.storage.untrusted`: links, sizes, dtypes), each attribute and dataset is checked
for presence, type, shape and units before it is used, and every text is handed out without
control characters (:func:`viscorig.storage.text.printable`). The file is opened read-only and
never written, so reading works on a full disk or a read-only mount.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal, overload

import h5py
import numpy as np
from numpy.typing import NDArray

from viscorig import frf
from viscorig.errors import InputError
from viscorig.numbers import Estimate
from viscorig.storage import layout, untrusted
from viscorig.storage.records import FitRecord, JointFitRecord, RunMetadata, RunRecord
from viscorig.storage.text import printable

#: What h5py raises on damaged objects, missing members, or values of an unexpected type.
HDF5_FAULTS = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError)


def check_path(path: Path) -> None:
    """The path names a regular file no larger than any campaign file."""
    if not path.exists():
        raise InputError("no such file", str(path))
    if not path.is_file():
        raise InputError("not a file", str(path))
    size = path.stat().st_size
    if size > layout.MAX_FILE_BYTES:
        raise InputError(f"{size} bytes; a campaign file holds at most {layout.MAX_FILE_BYTES}",
                         str(path))


@contextlib.contextmanager
def open_for_reading(path: Path) -> Iterator[h5py.File]:
    """Open a campaign file read-only, turning every failure into an InputError.

    HDF5's own file lock is taken where the file system allows it ("best-effort"): a campaign
    file is replaced, never changed in place, so readers need no lock, and file systems without
    ``flock`` (some network mounts) would otherwise refuse to open the file at all.
    """
    check_path(path)
    try:
        h5 = h5py.File(path, "r", locking="best-effort")
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


def _decode(value: Any, keep: str = "") -> Any:
    if isinstance(value, bytes):
        return printable(value.decode("utf-8", errors="replace"), keep=keep)
    if isinstance(value, str):
        return printable(value, keep=keep)
    if isinstance(value, np.ndarray) and value.size == 1:
        # a scalar, or one value in an array of one: MATLAB's h5writeatt, netCDF and Igor Pro
        # write every single number so
        return _decode(value.reshape(())[()], keep)
    if isinstance(value, np.generic):
        return value.item()
    return value


def attribute(obj: h5py.HLObject, name: str, path: Path) -> Any:
    """An attribute's value, checked for size and kind before it is read; text is printable.

    Returns ``None`` when the attribute is absent.
    """
    if name not in obj.attrs:
        return None
    untrusted.check_attributes(obj, path)
    untrusted.check_attribute(obj, name, path)
    value = _decode(obj.attrs[name])
    if isinstance(value, str) and len(value) > layout.MAX_ATTRIBUTE_BYTES:
        raise InputError(f"text of {len(value)} characters; at most "
                         f"{layout.MAX_ATTRIBUTE_BYTES}", f"{path}: {obj.name}.{name}")
    return value


def attributes(obj: h5py.HLObject, path: Path) -> dict[str, Any]:
    """Every attribute of an object whose name is printable, each read as :func:`attribute`."""
    untrusted.check_attributes(obj, path)
    return {printable(key): attribute(obj, key, path) for key in obj.attrs}


def read_setup_text(item: h5py.HLObject, path: Path) -> str:
    """A ``/setup`` text dataset (scalar string), newlines and tabs kept."""
    where = f"{path}: {item.name}"
    text = isinstance(item, h5py.Dataset) and item.shape == () and (
        h5py.check_string_dtype(item.dtype) is not None)
    if not text:
        raise InputError("not a text dataset", where)
    untrusted.check_values_dataset(item, path, scalar=True)
    value = _decode(item[()], keep="\n\t")
    if len(value) > layout.MAX_SETUP_TEXT:
        raise InputError(f"text of {len(value)} characters; at most {layout.MAX_SETUP_TEXT}",
                         where)
    return str(value)


def text_attribute(obj: h5py.HLObject, name: str, path: Path) -> str:
    """A string attribute."""
    value = attribute(obj, name, path)
    if not isinstance(value, str):
        problem = "missing" if value is None else f"not text ({type(value).__name__})"
        raise InputError(f"attribute {problem}", f"{path}: {obj.name}.{name}")
    return value


@overload
def read_number(obj: h5py.HLObject, name: str, path: Path, *, integer: Literal[True],
                held: layout.NumberRange | None = None) -> int: ...


@overload
def read_number(obj: h5py.HLObject, name: str, path: Path, *, integer: Literal[False] = False,
                held: layout.NumberRange | None = None) -> float: ...


def read_number(obj: h5py.HLObject, name: str, path: Path, *, integer: bool = False,
                held: layout.NumberRange | None = None) -> float:
    """A numeric scalar attribute (NaN allowed for floats); with ``held``, one of the values it
    holds (:meth:`~.layout.NumberRange.holds`, the writer's test too)."""
    value = attribute(obj, name, path)
    problem = None
    if value is None:
        problem = "attribute missing"
    elif isinstance(value, bool) or not isinstance(value, int | float):
        problem = f"not a number ({type(value).__name__})"
    elif integer and (not math.isfinite(value) or value != int(value)):
        problem = f"not a whole number ({value!r})"
    elif held is not None and not held.holds(float(value)):
        problem = f"{value!r}; needs {held.describe()}"
    if problem is not None:
        raise InputError(problem, f"{path}: {obj.name}.{name}")
    return int(value) if integer else float(value)


def read_bool(obj: h5py.HLObject, name: str, path: Path) -> bool:
    """A boolean attribute (h5py enum, or 0/1)."""
    value = attribute(obj, name, path)
    if value is not None and (isinstance(value, bool) or value in (0, 1)):
        return bool(value)
    problem = "attribute missing" if value is None else f"not a boolean ({value!r})"
    raise InputError(problem, f"{path}: {obj.name}.{name}")


def read_choice(obj: h5py.HLObject, name: str, path: Path, choices: tuple[str, ...]) -> str:
    """A text attribute that must be one of ``choices``."""
    value = text_attribute(obj, name, path)
    if value not in choices:
        where = f"{path}: {obj.name}.{name}"
        raise InputError(f"{value!r} is not one of {', '.join(choices)}", where)
    return value


def check_root(h5: h5py.File, path: Path) -> None:
    """Check the root attributes that make a file a viscorig campaign this code reads."""
    with guarded(path, "/"):
        if "format" not in h5.attrs:
            raise InputError("not a viscorig campaign file (no format attribute)", f"{path}: /")
        name = text_attribute(h5, "format", path)
        if name != layout.FORMAT_NAME:
            raise InputError(f"format is {name!r}, not {layout.FORMAT_NAME!r}", f"{path}: /")
        version = read_number(h5, "format_version", path, integer=True)
        if version != layout.FORMAT_VERSION:
            raise InputError(
                f"format_version {version} is not {layout.FORMAT_VERSION}, the version this "
                "viscorig reads",
                f"{path}: /",
            )
        untrusted.check_link(h5, layout.RUNS_GROUP, path)
        group = h5.get(layout.RUNS_GROUP)
        if not isinstance(group, h5py.Group):
            raise InputError("group missing", f"{path}: /{layout.RUNS_GROUP}")


def check_structure(h5: h5py.File, path: Path) -> None:
    """:func:`check_root`, then the whole layout's structure (links, names, bounds)."""
    check_root(h5, path)
    with guarded(path, "/"):
        untrusted.check_structure(h5, path)


def read_rig(h5: h5py.File, path: Path) -> dict[str, float | int]:
    """The /rig attributes this layout defines (others are kept out); {} if /rig is absent."""
    untrusted.check_link(h5, layout.RIG_GROUP, path)
    group = h5.get(layout.RIG_GROUP)
    if group is None:
        return {}
    with guarded(path, f"/{layout.RIG_GROUP}"):
        if not isinstance(group, h5py.Group):
            raise InputError("not a group", f"{path}: /{layout.RIG_GROUP}")
        return {name: _number(group, name, path, held)
                for name, held in layout.RIG_NUMBERS.items() if name in group.attrs}


def run_group(h5: h5py.File, name: str, path: Path) -> h5py.Group:
    """The group of run ``name``."""
    where = f"{path}: /{layout.RUNS_GROUP}/{name}"
    untrusted.check_link(h5, layout.RUNS_GROUP, path)
    runs = h5[layout.RUNS_GROUP]
    if name not in runs:
        known = ", ".join(printable(key) for key in untrusted.members(runs, path, layout.MAX_RUNS))
        link = h5.get(layout.DMA_GROUP, getlink=True)
        dma = h5[layout.DMA_GROUP] if isinstance(link, h5py.HardLink) else None
        if isinstance(dma, h5py.Group) and name in dma:
            raise InputError(f"no such run (runs: {known or 'none'}); '{printable(name)}' is a DMA "
                             "sweep, a material's modulus over frequency: see viscorig master",
                             where)
        raise InputError(f"no such run (runs: {known or 'none'})", where)
    untrusted.check_link(runs, name, path)
    group = runs[name]
    if not isinstance(group, h5py.Group):
        raise InputError("not a group", where)
    return group


def _number(obj: h5py.HLObject, name: str, path: Path, held: layout.NumberRange
            ) -> int | float:
    """A numeric attribute within ``held``."""
    if held.integer:
        return read_number(obj, name, path, integer=True, held=held)
    return read_number(obj, name, path, held=held)


def read_metadata(group: h5py.Group, path: Path) -> RunMetadata:
    """Every attribute of a run, checked."""
    return RunMetadata(
        status=read_choice(group, "status", path, layout.RUN_STATUSES),
        started=text_attribute(group, "started", path),
        finished=text_attribute(group, "finished", path),
        specimen=text_attribute(group, "specimen", path),
        direction=read_choice(group, "direction", path, layout.DIRECTIONS),
        **{name: _number(group, name, path, held)
           for name, held in layout.RUN_NUMBERS.items()},  # type: ignore[arg-type]
        instrument=text_attribute(group, "instrument", path),
        resource=text_attribute(group, "resource", path),
        simulated=read_bool(group, "simulated", path),
    )


def _values(dataset: h5py.Dataset) -> NDArray:
    """A checked 1-D dataset of numbers as float64 or complex128 (compounds r, i converted)."""
    values = dataset[()]
    fields = untrusted.complex_fields(dataset.dtype) if dataset.dtype.names else None
    if fields is not None:
        real, imag = fields
        return values[real].astype(np.float64) + 1j * values[imag].astype(np.float64)
    return values.astype(np.complex128 if values.dtype.kind == "c" else np.float64)


def _read_column(
    dataset: h5py.Group | h5py.Dataset | None, spec: layout.DatasetSpec, where: str, path: Path
) -> NDArray:
    """One per-point dataset, its structure checked already (:func:`untrusted.run_members`):
    1-D, of the expected kind, with the expected units."""
    if dataset is None:
        raise InputError("dataset missing", where)
    if not isinstance(dataset, h5py.Dataset):
        raise InputError("not a dataset", where)
    if dataset.ndim != 1:  # a 1-D one's size, chunks and storage are checked with the run's
        raise InputError(
            f"shape {dataset.shape} is not 1-D{untrusted.matrix_vector_hint(dataset)}", where)
    units = attribute(dataset, "units", path)
    if not isinstance(units, str):
        raise InputError("no units attribute", where)
    if not layout.unit_matches(spec.units, units):
        raise InputError(f"units {units!r}, expected {spec.units!r}", where)
    dtype = dataset.dtype
    kind = untrusted.number_kind(dtype)
    if spec.kind == "complex":
        if kind != "complex":
            raise InputError(f"dtype {dtype} is not complex (compound r, i)", where)
        return _values(dataset)
    if spec.kind == "count":
        if kind != "integer":
            raise InputError(f"dtype {dtype} is not a whole number", where)
        values = dataset[()]
        if values.size and values.min() < 0:
            raise InputError("negative counts", where)
        return values.astype(np.int64)
    if spec.kind == "flags":
        if kind != "integer":
            raise InputError(f"dtype {dtype} is not an integer bit mask", where)
        values = dataset[()]
        if values.size and (values.min() < 0 or values.max() > 0xFFFF):
            raise InputError("flags outside 0..65535", where)
        return values.astype(np.uint16)
    if kind not in ("real", "integer"):
        raise InputError(f"dtype {dtype} is not a real number", where)
    return _values(dataset)


def read_run(h5: h5py.File, name: str, path: Path) -> RunRecord:
    """A whole run, checked: attributes, datasets, equal lengths."""
    group = run_group(h5, name, path)
    with guarded(path, group.name):
        # links, names, points: before any value is read; each member opened once
        items, _ = untrusted.run_members(group, path, fits=False)
        datasets = {key: item for key, item in items.items() if isinstance(item, h5py.Dataset)}
        lengths = {key: item.shape[0] for key, item in datasets.items() if item.ndim == 1}
        if len(set(lengths.values())) > 1:
            detail = ", ".join(f"{key} {length}" for key, length in lengths.items())
            raise InputError(f"datasets differ in length ({detail})", f"{path}: {group.name}")
        metadata = read_metadata(group, path)
        where = f"{path}: {group.name}/"
        columns: dict[str, Any] = {  # Run checks each column's dtype and length
            spec.name: _read_column(items.get(spec.name), spec, where + spec.name, path)
            for spec in layout.REQUIRED_DATASETS
        }
        for spec in layout.OPTIONAL_DATASETS:
            columns[spec.name] = (_read_column(items[spec.name], spec, where + spec.name, path)
                                  if spec.name in items else None)
        extra: dict[str, tuple[NDArray, str]] = {}
        for key, item in datasets.items():
            if key in layout.KNOWN_DATASETS:
                continue
            if item.ndim == 1 and untrusted.number_kind(item.dtype) is not None:
                units = attribute(item, "units", path)
                extra[key] = (_values(item) if item.dtype.names else item[()],
                              str(units if units is not None else ""))
        problem = frf.frequency_problem(columns["frequency_hz"])
        if problem is not None:
            raise InputError(problem, where + "frequency_hz")
        for values in (*columns.values(), *(value for value, _ in extra.values())):
            if values is not None:
                values.setflags(write=False)
        return RunRecord(name=name, metadata=metadata, extra=extra, **columns)


def read_fits(h5: h5py.File, run_name: str, path: Path) -> list[FitRecord]:
    """The fits of a run, in id order."""
    group = run_group(h5, run_name, path)
    untrusted.check_link(group, layout.FITS_GROUP, path)
    fits_group = group.get(layout.FITS_GROUP)
    if fits_group is None:
        return []
    result = []
    with guarded(path, f"{group.name}/{layout.FITS_GROUP}"):
        if not isinstance(fits_group, h5py.Group):
            raise InputError("not a group", f"{path}: {fits_group.name}")
        for fit_id, fit in _fit_groups(fits_group, path):
            weighting = attribute(fit, "weighting", path)
            result.append(
                FitRecord(
                    id=fit_id,
                    run=run_name,
                    model=text_attribute(fit, "model", path),
                    band_hz=_pair(fit, "band_hz", path),
                    rms_error=read_number(fit, "rms_error", path),
                    noise_floor=read_number(fit, "noise_floor", path),
                    created=text_attribute(fit, "created", path),
                    parameters=_read_parameters(fit, path),
                    correlation=_read_correlation(fit, path),
                    weighting=weighting if isinstance(weighting, str) else "",
                )
            )
    return result


def read_joint_fits(h5: h5py.File, path: Path) -> list[JointFitRecord]:
    """The fits of several runs together (``/fits/<id>``), in id order; [] when there are
    none."""
    name = layout.JOINT_FITS_GROUP
    untrusted.check_link(h5, name, path)
    group = h5.get(name)
    if group is None:
        return []
    result = []
    with guarded(path, f"/{name}"):
        if not isinstance(group, h5py.Group):
            raise InputError("not a group", f"{path}: /{name}")
        untrusted.check_attributes(group, path)
        for fit_id, fit in _fit_groups(group, path):
            result.append(_read_joint_fit(fit_id, fit, path))
    return result


def _fit_groups(fits: h5py.Group, path: Path) -> Iterator[tuple[str, h5py.Group]]:
    """Each fit of a fits group (a run's ``fits`` or ``/fits``), in id order: at most
    :data:`~.layout.MAX_FITS`, each a hard link to a group with a stored name."""
    for fit_id in sorted(untrusted.members(fits, path, layout.MAX_FITS)):
        untrusted.check_stored_name(fit_id, path, fits.name, "fit")
        fit = fits[fit_id]
        if not isinstance(fit, h5py.Group):
            raise InputError("not a group", f"{path}: {fit.name}")
        yield fit_id, fit


def _pair(fit: h5py.Group, name: str, path: Path) -> tuple[float, float]:
    """A two-number attribute ``[lo, hi]``."""
    value = attribute(fit, name, path)
    try:
        pair = np.asarray([] if value is None else value, dtype=float).ravel()
    except (TypeError, ValueError):
        pair = np.empty(0)
    if pair.shape != (2,):
        raise InputError(f"{name} is not [lo, hi]", f"{path}: {fit.name}.{name}")
    high = frf.FREQUENCY_RANGE_HZ[1]
    if not 0 <= pair[0] <= pair[1] <= high:
        raise InputError(f"{name} [{pair[0]:g}, {pair[1]:g}] is not a band from 0 to {high:g} "
                         "Hz, low end first", f"{path}: {fit.name}.{name}")
    return float(pair[0]), float(pair[1])


def _names(value: Any) -> tuple[str, ...]:
    """Names stored as one text separated by spaces, or as an array of texts."""
    if isinstance(value, np.ndarray):
        return tuple(str(_decode(item)) for item in value.ravel())
    return tuple(str(value).split()) if isinstance(value, str) else ()


def _read_joint_fit(fit_id: str, fit: h5py.Group, path: Path) -> JointFitRecord:
    runs = _names(attribute(fit, "runs", path))
    if not runs:
        raise InputError("names no runs", f"{path}: {fit.name}.runs")
    for run in runs:
        untrusted.check_stored_name(run, path, f"{fit.name}.runs", "run")
    extra = {key: value for key, value in attributes(fit, path).items()
             if key not in layout.JOINT_FIT_ATTRIBUTES}
    weighting = attribute(fit, "weighting", path)
    return JointFitRecord(
        id=fit_id,
        model=text_attribute(fit, "model", path),
        runs=runs,
        band_hz=_pair(fit, "band_hz", path),
        reduced_chi_square=read_number(fit, "reduced_chi_square", path),
        points=read_number(fit, "points", path, integer=True),
        created=text_attribute(fit, "created", path),
        parameters=_read_parameters(fit, path),
        correlation=_read_correlation(fit, path),
        weighting=weighting if isinstance(weighting, str) else "",
        extra=extra,
    )


def _read_parameters(fit: h5py.Group, path: Path) -> dict[str, Estimate]:
    """A fit's parameters (its datasets and groups but the correlation), by name."""
    parameters = {}
    for key in untrusted.members(fit, path, layout.MAX_MEMBERS):
        untrusted.check_stored_name(key, path, fit.name, "parameter")
        parameter = _read_parameter(fit[key], path)
        if parameter is not None:
            parameters[key] = parameter
    return parameters


def _read_correlation(
    fit: h5py.Group, path: Path
) -> tuple[tuple[str, ...], NDArray[np.float64]] | None:
    """The fit's correlation matrix and its parameter names, if stored (and well formed)."""
    item = fit.get(layout.FIT_CORRELATION)
    if not isinstance(item, h5py.Dataset) or item.ndim != 2:
        return None
    stored = item.attrs.get("parameters", "")
    if isinstance(stored, np.ndarray):  # names as an array of texts
        stored = " ".join(v.decode() if isinstance(v, bytes) else str(v) for v in stored.ravel())
    names = tuple((stored.decode() if isinstance(stored, bytes) else str(stored)).split())
    matrix = np.asarray(item[()], dtype=float)
    if matrix.shape != (len(names), len(names)):
        raise InputError("correlation does not match its parameter names", f"{path}: {item.name}")
    return names, matrix


def _read_parameter(item: h5py.HLObject, path: Path) -> Estimate | None:
    """A parameter stored as a scalar dataset (attrs stderr, units) or a group (attrs value,
    stderr, units); other objects in a fit group are not parameters."""
    if isinstance(item, h5py.Dataset):
        if item.size != 1:
            return None
        if untrusted.number_kind(item.dtype) not in ("real", "integer"):
            held = "text" if h5py.check_string_dtype(item.dtype) else f"dtype {item.dtype}"
            raise InputError(f"a parameter's value is a real number, not {held}",
                             f"{path}: {item.name}")
        untrusted.check_values_dataset(item, path, scalar=True)
        value = float(np.asarray(item[()]).reshape(()))
    else:
        value = read_number(item, "value", path)
    if not math.isfinite(value):
        raise InputError(f"value {value} is not a finite number", f"{path}: {item.name}")
    stderr = read_number(item, "stderr", path) if "stderr" in item.attrs else math.nan
    unit = text_attribute(item, "units", path) if "units" in item.attrs else ""
    return Estimate(value=value, stderr=stderr, unit=unit)
