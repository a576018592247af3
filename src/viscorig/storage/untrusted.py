"""Checks of a campaign file's structure before any value of it is read.

A campaign file may come from a colleague, a USB stick or an old version, and HDF5 lets a file
declare anything: a dataset of 10^12 points (a few bytes on disk when nothing was written), a
chunk of gigabytes, a link into another file, an attribute of megabytes. h5py would follow the
link and allocate what the file declares. So before a value is read, what it would cost is
checked against the bounds of :mod:`viscorig.storage.layout`, from the file's metadata only:

- links: only hard links are followed; a soft, external or user-defined link where the layout
  has an object is refused (the file is not opened further);
- counts: runs, fits, members of a group, attributes of an object;
- datasets: rank, points, dtype, chunk size, and no virtual or external storage (both point
  into other files);
- attributes: number of values, dtype and stored bytes;
- names: runs, datasets and parameters follow the project's naming rule, so a name printed on
  a terminal cannot carry escape sequences.
"""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np

from viscorig.errors import InputError
from viscorig.storage import layout

#: Names of the two fields of a complex number stored as a compound, as tools write them.
COMPLEX_FIELD_NAMES = (("r", "i"), ("real", "imag"), ("re", "im"), ("Re", "Im"))


def _shown(name: str) -> str:
    """A name as it may be printed (control characters escaped)."""
    return "".join(char if char.isprintable() else repr(char)[1:-1] for char in name)[:80]


def members(group: h5py.Group, path: Path, limit: int) -> list[str]:
    """The names in ``group``, each a hard link; at most ``limit`` of them.

    Raises
    ------
    InputError
        Too many members, or a soft, external or user-defined link.
    """
    where = f"{path}: {group.name}"
    count = len(group)
    if count > limit:
        raise InputError(f"holds {count} objects; at most {limit} are read", where)
    names = list(group.keys())
    for name in names:
        check_link(group, name, path)
    return names


def check_link(group: h5py.Group, name: str, path: Path) -> None:
    """Refuse ``group[name]`` unless it is a hard link (or absent)."""
    link = group.get(name, getlink=True)
    if link is None or isinstance(link, h5py.HardLink):
        return
    where = f"{path}: {group.name.rstrip('/')}/{_shown(name)}"
    if isinstance(link, h5py.ExternalLink):
        target = f"{_shown(link.filename)}:{_shown(link.path)}"
        raise InputError(f"external link to {target}; links are not followed", where)
    if isinstance(link, h5py.SoftLink):
        raise InputError(f"soft link to {_shown(link.path)}; links are not followed", where)
    raise InputError("a user-defined link; links are not followed", where)


def check_stored_name(name: str, path: Path, parent: str, what: str) -> None:
    """Refuse a run, dataset or parameter name outside the naming rule."""
    if not layout.NAME.fullmatch(name):
        raise InputError(f"{what} name {_shown(name)!r} is not valid ({layout.NAME_RULE})",
                         f"{path}: {parent}")


def check_attributes(obj: h5py.HLObject, path: Path) -> None:
    """Refuse an object with more attributes than any viscorig object has."""
    count = len(obj.attrs)
    if count > layout.MAX_ATTRIBUTES:
        raise InputError(f"holds {count} attributes; at most {layout.MAX_ATTRIBUTES} are read",
                         f"{path}: {obj.name}")


def check_attribute(obj: h5py.HLObject, name: str, path: Path) -> None:
    """Refuse an attribute whose value would be large, or of a kind no reader expects."""
    attribute = obj.attrs.get_id(name)
    shape = attribute.shape or ()
    values = math.prod(shape)
    problem = None
    if values > layout.MAX_ATTRIBUTE_VALUES:
        problem = f"holds {values} values; at most {layout.MAX_ATTRIBUTE_VALUES}"
    elif (dtype := attribute.dtype).kind == "O" and h5py.check_string_dtype(dtype) is None:
        problem = f"dtype {dtype} (variable-length, not text) is not read"
    elif dtype.kind not in "biufSUO" and not _is_bool_enum(dtype):
        problem = f"dtype {dtype} is not a number, a boolean or text"
    elif (size := attribute.get_storage_size()) > layout.MAX_ATTRIBUTE_BYTES:
        problem = f"stores {size} bytes; at most {layout.MAX_ATTRIBUTE_BYTES}"
    if problem is not None:
        raise InputError(problem, f"{path}: {obj.name}.{_shown(name)}")


def _is_bool_enum(dtype: np.dtype) -> bool:
    return h5py.check_enum_dtype(dtype) is not None and dtype.kind in "iub"


def check_values_dataset(dataset: h5py.Dataset, path: Path, *, scalar: bool = False) -> int:
    """Check a dataset of numbers before reading it; return its number of points.

    Parameters
    ----------
    scalar
        Expect a scalar (a fit parameter) instead of a 1-D per-point dataset.
    """
    where = f"{path}: {dataset.name}"
    if dataset.is_virtual:
        raise InputError("a virtual dataset (its data lives in other files) is not read", where)
    if dataset.external:
        raise InputError("a dataset stored in external files is not read", where)
    if scalar:
        if dataset.size != 1:  # (a scalar, or one value in an array of one, as MATLAB writes)
            raise InputError(f"shape {dataset.shape} is not a scalar", where)
        return 1
    if dataset.ndim != 1:
        raise InputError(f"shape {dataset.shape} is not 1-D{matrix_vector_hint(dataset)}",
                         where)
    points = int(dataset.shape[0])
    if points > layout.MAX_RUN_POINTS:
        raise InputError(f"declares {points} points; a run holds at most "
                         f"{layout.MAX_RUN_POINTS}", where)
    chunks = dataset.chunks
    if chunks is not None:
        chunk_bytes = math.prod(chunks) * max(dataset.dtype.itemsize, 1)
        if chunk_bytes > layout.MAX_CHUNK_BYTES:
            raise InputError(f"chunks of {chunk_bytes} bytes; at most "
                             f"{layout.MAX_CHUNK_BYTES}", where)
    return points


def matrix_vector_hint(dataset: h5py.Dataset) -> str:
    """How to write a vector stored as a matrix of one row or one column (MATLAB's
    ``h5create(file, name, size(x))``) as the 1-D dataset the layout holds; else ``""``."""
    if dataset.ndim == 2 and 1 in dataset.shape:
        return ": a vector stored as a one-row matrix (in MATLAB, h5create(file, name, N))"
    return ""


def number_kind(dtype: np.dtype) -> str | None:
    """``"real"``, ``"integer"``, ``"complex"`` (native or a two-field compound) or None."""
    if dtype.kind in "iu" and dtype.itemsize <= 8:
        return "integer"
    if dtype.kind == "f" and dtype.itemsize <= 8:
        return "real"
    if dtype.kind == "c" and dtype.itemsize <= 16:
        return "complex"
    if dtype.names is not None and complex_fields(dtype) is not None:
        return "complex"
    return None


def complex_fields(dtype: np.dtype) -> tuple[str, str] | None:
    """The (real, imaginary) field names of a compound holding a complex number."""
    names = set(dtype.names or ())
    for real, imag in COMPLEX_FIELD_NAMES:
        if names == {real, imag} and all(
            dtype[field].kind == "f" and dtype[field].itemsize <= 8 for field in (real, imag)
        ):
            return real, imag
    return None


def check_structure(h5: h5py.File, path: Path) -> None:
    """Check the whole layout's structure (links, names, counts, points), reading no values.

    Raises
    ------
    InputError
        The first thing found outside the layout or its bounds, named.
    """
    for name in (layout.RUNS_GROUP, layout.RIG_GROUP, layout.SETUP_GROUP):
        check_link(h5, name, path)
    check_attributes(h5, path)
    runs = h5[layout.RUNS_GROUP]
    total = 0
    for run_name in members(runs, path, layout.MAX_RUNS):
        check_stored_name(run_name, path, runs.name, "run")
        run = runs[run_name]
        if not isinstance(run, h5py.Group):
            raise InputError("not a group", f"{path}: {run.name}")
        total += check_run(run, path)
        if total > layout.MAX_CAMPAIGN_POINTS:
            raise InputError(f"runs hold more than {layout.MAX_CAMPAIGN_POINTS} points together",
                             f"{path}: /{layout.RUNS_GROUP}")
    for name in (layout.RIG_GROUP, layout.SETUP_GROUP):
        group = h5.get(name)
        if isinstance(group, h5py.Group):
            check_attributes(group, path)
            members(group, path, layout.MAX_MEMBERS)


def check_run(group: h5py.Group, path: Path) -> int:
    """Check one run group's structure, its fits' included; return its points (the length of
    ``frequency_hz``)."""
    return run_members(group, path)[1]


def run_members(
    group: h5py.Group, path: Path, *, fits: bool = True
) -> tuple[dict[str, h5py.Group | h5py.Dataset], int]:
    """Check one run group's structure (its fits' too unless ``fits`` is false: a reader of the
    run's values does not open them); return its members, each opened once, and its points."""
    check_attributes(group, path)
    points = 0
    opened: dict[str, h5py.Group | h5py.Dataset] = {}
    for name in members(group, path, layout.MAX_MEMBERS):
        check_stored_name(name, path, group.name, "dataset")
        item = opened[name] = group[name]
        if isinstance(item, h5py.Dataset):
            check_attributes(item, path)
            if item.ndim == 1:
                length = check_values_dataset(item, path)
                points = length if name == "frequency_hz" else points
        elif fits and name == layout.FITS_GROUP and isinstance(item, h5py.Group):
            for fit_id in members(item, path, layout.MAX_FITS):
                check_stored_name(fit_id, path, item.name, "fit")
                fit = item[fit_id]
                if isinstance(fit, h5py.Group):
                    check_attributes(fit, path)
                    for parameter in members(fit, path, layout.MAX_MEMBERS):
                        check_stored_name(parameter, path, fit.name, "parameter")
    return opened, points
