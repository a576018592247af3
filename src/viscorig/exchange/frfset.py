"""FRFs travelling between viscorig and other tools, and how they enter a campaign run.

Every reader (UFF 58, CSV, SDF) returns an :class:`FrfSet`: accelerances in m/s²/N on one
frequency axis in Hz, whatever units the file used. :func:`import_run` then checks that the set
is whole (every value finite, lengths equal, each frequency once, within a run's bound of
points) and writes it as one new run of a campaign file, by rising frequency whatever order the
file had, in a single commit, so bad input never changes the file and an import is never
partial.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.frf import FREQUENCY_RANGE_HZ
from viscorig.storage import RunSettings, Segment
from viscorig.storage.campaign import campaign_for_import, check_name
from viscorig.storage.layout import MAX_RUN_POINTS

#: Relative tolerance within which two files' frequency axes count as the same.
AXIS_RTOL = 1e-9


@dataclass
class FrfSet:
    """The FRFs of one run, ready to be stored.

    Attributes
    ----------
    frequency_hz
        Frequency of each point, Hz.
    accelerance_table
        ẍ_s/F_e in m/s²/N (all NaN when absent).
    accelerance_support
        ẍ_v/F_v in m/s²/N (all NaN when absent, as on a bare table).
    flags
        Point flags (data-format.md bit mask); zeros when the source has none.
    time_s
        Seconds since the run's start at each point; NaN when the source has none.
    source
        Where the data came from, for the run's ``instrument`` attribute.
    """

    frequency_hz: NDArray[np.float64]
    accelerance_table: NDArray[np.complex128]
    accelerance_support: NDArray[np.complex128]
    flags: NDArray[np.uint16] | None = None
    time_s: NDArray[np.float64] | None = None
    source: str = ""
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        n = np.asarray(self.frequency_hz).size
        self.frequency_hz = np.asarray(self.frequency_hz, dtype=float)
        self.accelerance_table = np.asarray(self.accelerance_table, dtype=complex)
        self.accelerance_support = np.asarray(self.accelerance_support, dtype=complex)
        if self.flags is None:
            self.flags = np.zeros(n, dtype=np.uint16)
        if self.time_s is None:
            self.time_s = np.full(n, np.nan)


def combine_frfs(
    frequency_hz: list[NDArray[np.float64]],
    frfs: list[NDArray[np.complex128]],
    names: list[str],
    source: str,
) -> FrfSet:
    """One or two FRFs on the same axis -> an :class:`FrfSet` (first table, second support).

    Raises
    ------
    InputError
        No FRF, more than two, axes that differ, or an axis that is not finite and positive.
    """
    if not frfs:
        raise InputError("holds no frequency response", source)
    if len(frfs) > 2:
        raise InputError(f"holds {len(frfs)} frequency responses; a run has two "
                         "(ẍ_s/F_e, then ẍ_v/F_v)", source)
    axis = np.asarray(frequency_hz[0], dtype=float)
    if axis.size == 0 or not np.all(np.isfinite(axis)) or np.any(axis <= 0):
        raise InputError("frequency axis is empty, not finite, or not positive", names[0])
    for other, name in zip(frequency_hz[1:], names[1:], strict=True):
        if other.shape != axis.shape or not np.allclose(other, axis, rtol=AXIS_RTOL, atol=0):
            raise InputError(
                f"frequency axis ({other.size} points, {other[0]:g}-{other[-1]:g} Hz) differs "
                f"from {names[0]}'s ({axis.size} points, {axis[0]:g}-{axis[-1]:g} Hz)", name)
    nan = np.full(axis.shape, np.nan + 1j * np.nan)
    support = frfs[1] if len(frfs) == 2 else nan
    return FrfSet(axis, frfs[0], support, source=source)


def _first_bad(bad: np.ndarray, frequency_hz: np.ndarray) -> str:
    """``point 17 of 401 (23.5 Hz)``: the first point where ``bad`` holds, as a reader finds it
    in the file's order."""
    index = int(np.flatnonzero(bad)[0])
    frequency = frequency_hz[index]
    at = f" ({frequency:g} Hz)" if np.isfinite(frequency) else ""
    return f"point {index + 1} of {bad.size}{at}"


def check_whole(frfs: FrfSet) -> None:
    """Refuse a set that a truncated, damaged or hand-made file would give.

    Every reader's set passes here before it becomes a run, so each hole is closed once for
    CSV, UFF and SDF alike; the first offending point is named in the file's order.

    Raises
    ------
    InputError
        Lengths differ, more points than a run holds, a frequency that is not finite and
        positive or lies outside :data:`~viscorig.frf.FREQUENCY_RANGE_HZ`, a frequency given
        twice, a non-finite value of ẍ_s/F_e, a ẍ_v/F_v that is only partly present, or a value
        with a subnormal part.
    """
    where = frfs.source or "import"
    n = frfs.frequency_hz.size
    lengths = {len(frfs.accelerance_table), len(frfs.accelerance_support),
               len(frfs.flags), len(frfs.time_s)}  # type: ignore[arg-type]
    if lengths != {n}:
        raise InputError(f"columns of different lengths ({n} frequencies)", where)
    if n == 0:
        raise InputError("holds no point", where)
    if n > MAX_RUN_POINTS:
        raise InputError(f"{n} points; a run holds at most {MAX_RUN_POINTS}", where)
    frequency = frfs.frequency_hz
    bad = ~np.isfinite(frequency) | (frequency <= 0)
    if bad.any():
        raise InputError(f"{int(bad.sum())} of {n} frequencies are not finite and positive, "
                         f"the first at {_first_bad(bad, frequency)}", where)
    low, high = FREQUENCY_RANGE_HZ
    bad = (frequency < low) | (frequency > high)
    if bad.any():
        raise InputError(f"{int(bad.sum())} of {n} frequencies lie outside {low:g} to {high:g} "
                         f"Hz, the first at {_first_bad(bad, frequency)}: no vibration analyser "
                         "measures there (a damaged file?)", where)
    order = np.argsort(frequency, kind="stable")
    repeated = np.flatnonzero(np.diff(frequency[order]) == 0)
    if repeated.size:
        first, second = sorted(order[repeated[0]:repeated[0] + 2])
        raise InputError(f"frequency {frequency[first]:g} Hz is given twice (points "
                         f"{first + 1} and {second + 1} of {n}); a run holds one value per "
                         "frequency", where)
    bad = ~np.isfinite(frfs.accelerance_table)
    if bad.any():
        raise InputError(f"{int(bad.sum())} of {n} values of ẍ_s/F_e are not finite, the first "
                         f"at {_first_bad(bad, frequency)} (a truncated or damaged file?)",
                         where)
    missing = ~np.isfinite(frfs.accelerance_support)
    if 0 < missing.sum() < n:
        raise InputError(f"{int(missing.sum())} of {n} values of ẍ_v/F_v are not finite, the "
                         f"first at {_first_bad(missing, frequency)} (a truncated or damaged "
                         "file?)", where)
    for label, values in (("ẍ_s/F_e", frfs.accelerance_table),
                          ("ẍ_v/F_v", frfs.accelerance_support)):
        bad = _subnormal(np.asarray(values, dtype=complex))
        if bad.any():
            raise InputError(
                f"{int(bad.sum())} of {n} values of {label} have a part below "
                f"{np.finfo(float).tiny:.1e} in magnitude, the first at "
                f"{_first_bad(bad, frequency)}: a subnormal number, which no analyser writes "
                "(a damaged file?)", where)


def _subnormal(values: NDArray[np.complex128]) -> NDArray[np.bool_]:
    """Points with a real or imaginary part that is a subnormal double (non-zero, below the
    smallest normal number): what damaged exponent bits of a stored double read as."""
    tiny = np.finfo(float).tiny
    parts = np.stack([values.real, values.imag])
    return np.any((parts != 0) & (np.abs(parts) < tiny), axis=0)


@dataclass(frozen=True)
class ImportSettings:
    """What the user says about an imported run (the files do not carry it)."""

    specimen: str = "unknown"
    hardness_shore_a: float = math.nan
    preload_strain: float = 0.0
    temperature_c: float = math.nan
    level_m_per_s2: float = math.nan


def import_run(campaign_path: Path, run_name: str, frfs: FrfSet, settings: ImportSettings) -> int:
    """Store ``frfs`` as a new, complete run ``run_name`` of a campaign file.

    The campaign file is created when it does not exist. Everything is checked before the file
    is touched; the run is written whole and complete in one commit (and a campaign file this
    call created is removed again if that commit fails).

    Returns
    -------
    int
        Points stored.

    Raises
    ------
    InputError
        Bad run name, run exists, the file is not a campaign, or the data cannot be stored.
    """
    check_name(run_name, "--run")
    check_whole(frfs)
    if settings.specimen.strip().lower() in {"none", ""} and np.any(
        np.isfinite(frfs.accelerance_support)
    ):
        raise InputError("a bare-table run (specimen 'none') has no ẍ_v/F_v; "
                         "give --specimen or import one FRF", run_name)
    steps = np.diff(frfs.frequency_hz)
    # stored by rising frequency whatever the file's order (check_whole refused repeats); rows
    # that ran from high to low keep that order as the run's sweep direction
    direction = "down" if steps.size and np.all(steps < 0) else "up"
    keep = np.argsort(frfs.frequency_hz, kind="stable")
    resolution = float(np.median(np.abs(steps))) if steps.size else math.nan
    run_settings = RunSettings(
        specimen=settings.specimen,
        level_m_per_s2=settings.level_m_per_s2,
        direction=direction,
        settle_cycles=0,
        integrate_cycles=0,
        resolution_hz=resolution,
        hardness_shore_a=settings.hardness_shore_a,
        preload_strain=settings.preload_strain,
        temperature_c=settings.temperature_c,
        instrument=f"imported from {frfs.source}"[:200],
        simulated=False,
    )
    n = keep.size
    segment = Segment(
        frequency_hz=frfs.frequency_hz[keep],
        time_s=frfs.time_s[keep],  # type: ignore[index]
        accelerance_table=frfs.accelerance_table[keep],
        accelerance_support=frfs.accelerance_support[keep],
        reference_amplitude=np.full(n, np.nan),
        source_amplitude=np.full(n, np.nan),
        force_amplitude=np.full(n, np.nan),
        flags=frfs.flags[keep],  # type: ignore[index]
    )
    segment.columns()  # raises ValueError on inconsistent arrays, before the file is touched
    with campaign_for_import(Path(campaign_path), run_name) as campaign:
        return campaign.add_run(run_name, run_settings, segment)
