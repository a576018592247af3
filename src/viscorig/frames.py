"""Runs and fits as pandas DataFrames and xarray Datasets, for notebooks and scripts.

The frequency is the index (pandas) or the coordinate (xarray), named ``frequency_hz``; every
column or variable keeps its unit in ``attrs["units"]`` (xarray: each variable's
``attrs["units"]``; pandas: ``frame.attrs["units"]``, a mapping column -> unit). pandas and
xarray are optional (``pip install "viscorig[notebook]"``) and imported only when called.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from viscorig.errors import InputError

#: Units of a run's datasets (data-format.md), as written in the campaign file.
RUN_UNITS = {
    "time_s": "s",
    "accelerance_table": "m/s^2/N",
    "accelerance_support": "m/s^2/N",
    "reference_amplitude": "m/s^2",
    "source_amplitude": "V",
    "force_amplitude": "N",
    "flags": "1",
    "variance_table": "1",
    "variance_support": "1",
}


def _missing(module: str) -> InputError:
    return InputError(f"{module} is not installed; pip install \"viscorig[notebook]\"",
                      "notebook")


def pandas() -> Any:
    """The pandas module, or an error saying how to install it."""
    try:
        import pandas as module
    except ImportError:
        raise _missing("pandas") from None
    return module


def xarray() -> Any:
    """The xarray module, or an error saying how to install it."""
    try:
        import xarray as module
    except ImportError:
        raise _missing("xarray") from None
    return module


def run_columns(run) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """A stored run's per-point arrays and their units."""
    columns = {name: np.asarray(getattr(run, name)) for name in RUN_UNITS
               if getattr(run, name, None) is not None}
    units = {name: RUN_UNITS[name] for name in columns}
    for name, (values, unit) in run.extra.items():
        columns[name], units[name] = np.asarray(values), unit
    return columns, units


def to_pandas(frequency_hz: np.ndarray, columns: Mapping[str, np.ndarray],
              units: Mapping[str, str], attributes: Mapping[str, Any]) -> Any:
    """A DataFrame indexed by ``frequency_hz``, with ``attrs["units"]`` and the attributes."""
    index = pandas().Index(np.asarray(frequency_hz, dtype=float), name="frequency_hz")
    frame = pandas().DataFrame(dict(columns), index=index)
    frame.attrs.update(attributes)
    frame.attrs["units"] = {"frequency_hz": "Hz", **units}
    return frame


def to_xarray(frequency_hz: np.ndarray, columns: Mapping[str, np.ndarray],
              units: Mapping[str, str], attributes: Mapping[str, Any],
              scalars: Mapping[str, tuple[float, dict[str, Any]]] | None = None) -> Any:
    """A Dataset on the coordinate ``frequency_hz`` (Hz); each variable has its ``units``.

    ``scalars``: name -> (value, attributes), for fitted parameters.
    """
    variables: dict[str, Any] = {
        name: ("frequency_hz", np.asarray(values), {"units": units.get(name, "")})
        for name, values in columns.items()
    }
    for name, (value, attrs) in (scalars or {}).items():
        variables[name] = ((), value, attrs)
    coordinate = {"frequency_hz": ("frequency_hz", np.asarray(frequency_hz, dtype=float),
                                   {"units": "Hz", "long_name": "frequency"})}
    return xarray().Dataset(variables, coords=coordinate, attrs=_netcdf_safe(attributes))


def _netcdf_safe(attributes: Mapping[str, Any]) -> dict[str, Any]:
    """Attributes as numbers and strings (booleans as 0/1), so a Dataset can be written out."""
    safe: dict[str, Any] = {}
    for key, value in attributes.items():
        if isinstance(value, bool):
            safe[key] = int(value)
        elif isinstance(value, int | float | str):
            safe[key] = value
        elif value is not None:
            safe[key] = str(value)
    return safe
