"""Hostile or merely odd campaign files, made with plain h5py from a valid one.

Each maker changes a copy of a valid campaign file in one way a colleague's script, a USB
stick or an attacker could, and returns the words the refusal must contain (``None`` for a
change that leaves the file readable, such as escape sequences in texts).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np

RUN = "runs/soft-0"
ESCAPES = "\x1b[2J\x1b]0;owned\x07\u202e\x9b31m"


def _resize_all(path: Path, points: int) -> None:
    with h5py.File(path, "r+") as h5:
        for item in h5[RUN].values():
            if isinstance(item, h5py.Dataset):
                item.resize((points,))


def huge_declared(points: int) -> Callable[[Path], str]:
    def make(path: Path) -> str:
        _resize_all(path, points)  # a few bytes on disk: nothing beyond the old points exists
        return f"declares {points} points"
    return make


def external_link(path: Path) -> str:
    other = path.with_name("other.h5")
    with h5py.File(other, "w") as h5:
        h5["data"] = np.ones(40, dtype=complex)
    with h5py.File(path, "r+") as h5:
        del h5[f"{RUN}/accelerance_table"]
        h5[f"{RUN}/accelerance_table"] = h5py.ExternalLink(str(other), "/data")
    return "external link to"


def soft_link_run(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        h5["runs/copy"] = h5py.SoftLink(f"/{RUN}")
    return "soft link to"


def soft_link_runs(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        h5.move("runs", "elsewhere")
        h5["runs"] = h5py.SoftLink("/elsewhere")
    return "soft link to"


def external_storage(path: Path) -> str:
    raw = path.with_name("raw.bin")
    raw.write_bytes(np.arange(40, dtype=float).tobytes())
    with h5py.File(path, "r+") as h5:
        units = h5[f"{RUN}/time_s"].attrs["units"]
        del h5[f"{RUN}/time_s"]
        n = h5[f"{RUN}/frequency_hz"].shape[0]
        dataset = h5.create_dataset(f"{RUN}/time_s", shape=(n,), dtype=float,
                                    external=[(str(raw), 0, h5py.h5f.UNLIMITED)])
        dataset.attrs["units"] = units
    return "external files"


def virtual_dataset(path: Path) -> str:
    source = path.with_name("source.h5")
    with h5py.File(path, "r+") as h5:
        n = h5[f"{RUN}/frequency_hz"].shape[0]
        with h5py.File(source, "w") as other:
            other["f"] = np.arange(n, dtype=float)
        layout = h5py.VirtualLayout(shape=(n,), dtype=float)
        layout[:] = h5py.VirtualSource(str(source), "f", shape=(n,))
        units = h5[f"{RUN}/force_amplitude"].attrs["units"]
        del h5[f"{RUN}/force_amplitude"]
        h5.create_virtual_dataset(f"{RUN}/force_amplitude", layout).attrs["units"] = units
    return "virtual dataset"


def huge_chunk(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        n = h5[f"{RUN}/frequency_hz"].shape[0]
        units = h5[f"{RUN}/source_amplitude"].attrs["units"]
        del h5[f"{RUN}/source_amplitude"]
        dataset = h5.create_dataset(f"{RUN}/source_amplitude", shape=(n,), maxshape=(None,),
                                    chunks=(10**8,), dtype=float, compression="gzip")
        dataset.attrs["units"] = units
    return "chunks of 800000000 bytes"


def text_for_numbers(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        n = h5[f"{RUN}/frequency_hz"].shape[0]
        del h5[f"{RUN}/frequency_hz"]
        dataset = h5.create_dataset(f"{RUN}/frequency_hz", data=["x" * 1000] * n,
                                    dtype=h5py.string_dtype())
        dataset.attrs["units"] = "Hz"
    return "is not a real number"


def compound_with_text(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        n = h5[f"{RUN}/frequency_hz"].shape[0]
        del h5[f"{RUN}/accelerance_support"]
        dtype = np.dtype([("r", float), ("note", h5py.string_dtype())])
        data = np.array([(0.0, "note")] * n, dtype=dtype)
        dataset = h5.create_dataset(f"{RUN}/accelerance_support", data=data)
        dataset.attrs["units"] = "m/s^2/N"
    return "is not complex"


def _run_with_dense_attributes(h5: h5py.File) -> h5py.Group:
    """The run group rebuilt with a new-style object header, which can hold large attributes
    (the file must be open with ``libver="latest"``)."""
    old = h5[RUN]
    new = h5.create_group("runs/rebuilt")
    for key, value in old.attrs.items():
        new.attrs[key] = value
    for key in list(old):
        h5.move(f"{RUN}/{key}", f"runs/rebuilt/{key}")
    del h5[RUN]
    h5.move("runs/rebuilt", RUN)
    return h5[RUN]


def big_attribute(path: Path) -> str:
    with h5py.File(path, "r+", libver="latest") as h5:  # dense attribute storage
        _run_with_dense_attributes(h5).attrs["specimen"] = np.bytes_(b"x" * 2_000_000)
    return "stores 2000000 bytes"


def many_valued_attribute(path: Path) -> str:
    with h5py.File(path, "r+", libver="latest") as h5:  # dense attribute storage
        _run_with_dense_attributes(h5).attrs["level_m_per_s2"] = np.ones(1_000_000)
    return "holds 1000000 values"


def long_text_attribute(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        h5[RUN].attrs.create("specimen", "y" * 5_000_000, dtype=h5py.string_dtype())
    return "text of 5000000 characters"


def many_runs(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        for index in range(1001):
            h5.create_group(f"runs/extra-{index}")
    return "holds 1003 objects"


def escaped_run_name(path: Path) -> str:
    with h5py.File(path, "r+") as h5:
        h5.move(RUN, f"runs/soft{ESCAPES}")
    return "run name"


def oversized_file(path: Path) -> str:
    os.truncate(path, 300 * 1024 * 1024)  # sparse: nothing written to the disk
    return "a campaign file holds at most"


def escapes_in_texts(path: Path) -> None:
    with h5py.File(path, "r+") as h5:
        h5[RUN].attrs["specimen"] = f"soft{ESCAPES}"
        h5[RUN].attrs["instrument"] = f"35670A{ESCAPES}"
        h5["setup"].attrs["sequence_file"] = f"paper{ESCAPES}.toml"
        h5[f"{RUN}/frequency_hz"].attrs["units"] = "Hz"
        fits = h5[RUN].require_group("fits")
        fit = fits.create_group("0001")
        fit.attrs.update({"model": f"voigt{ESCAPES}", "band_hz": np.array([20.0, 120.0]),
                          "rms_error": 0.01, "noise_floor": 0.01, "created": f"now{ESCAPES}"})
        parameter = fit.create_dataset("K_v", data=1.5e5)
        parameter.attrs.update({"stderr": 10.0, "units": f"N/m{ESCAPES}"})


#: name -> maker; every one of these must be refused with one line.
REFUSED: dict[str, Callable[[Path], str]] = {
    "1e12 points": huge_declared(10**12),
    "3e8 points": huge_declared(3 * 10**8),
    "external link": external_link,
    "soft link to a run": soft_link_run,
    "soft link as /runs": soft_link_runs,
    "external storage": external_storage,
    "virtual dataset": virtual_dataset,
    "huge chunk": huge_chunk,
    "text for numbers": text_for_numbers,
    "compound with text": compound_with_text,
    "2 MB attribute": big_attribute,
    "1e6-value attribute": many_valued_attribute,
    "5 MB text attribute": long_text_attribute,
    "1003 runs": many_runs,
    "escapes in a run name": escaped_run_name,
    "300 MB file": oversized_file,
}
