"""The campaign file: create it, record runs segment by segment, read runs, store fits.

The layout is the public contract of ``shared/docs/data-format.md``. Every change is one atomic
commit (see :mod:`viscorig.storage.atomic`), so the file is closed between commits and a writer
killed at any instant leaves every committed segment intact and no partial one. Readers open
the file only for the duration of one call, so they always see one committed state.

Additions to the contract, both readable by any HDF5 tool:

- ``/setup``: scalar UTF-8 string datasets ``sequence_toml`` (the sequence text the campaign
  ran) and, when a station file was used, ``station_toml``; attributes ``sequence_file`` and
  ``station_file`` name the original files. ``resume`` needs nothing but the campaign file.
- Fit ids are four-digit counters per run (``0001``, ``0002``, ...); each parameter is a scalar
  float64 dataset holding the value, with attributes ``stderr`` and ``units``.
- Dimension scales (HDF5 Dimension Scale specification, as netCDF-4 uses them):
  ``/runs/<name>/frequency_hz`` is a dimension scale named ``frequency_hz`` (attributes
  ``CLASS = "DIMENSION_SCALE"``, ``NAME``, ``REFERENCE_LIST``), and every other 1-D dataset of
  the run has it attached to its only dimension (attribute ``DIMENSION_LIST``). xarray (through
  h5netcdf), Panoply and MATLAB's ``ncread`` then see frequency as the coordinate of each run.
  They are attributes only: format_version stays 1, a reader that ignores them reads the file
  as before, and a file written without them gains them at its next write to that run.
- Rig time and plans. Every run written by ``viscorig run`` has the attribute ``test_time_s``:
  the time the run occupied the rig (settle, integration and the instrument's own time per
  point as measured; on a simulated rig its simulated test time), updated in the commit of
  each segment. A run measured by an adaptive plan (a sequence's ``plan = "adaptive"``) stores
  every point it measured in measurement order, its first look and its repeats of one
  frequency included, with per-point int64 datasets ``settle_cycles`` and
  ``integrate_cycles`` (units "1"; the run attributes of the same names then hold the bounds
  the step allowed), ``time_s`` being the running sum of each point's rig time; attributes
  ``plan`` ("adaptive"), ``plan_model``, ``plan_targets`` (``K_v=0.001 C_v=0.002``),
  ``plan_reason`` (why it stopped: "targets met", "dwell limit", ...), ``plan_state`` and
  ``plan_relative_stderr``. Analysis reads such a run merged (:meth:`RunRecord.merged`: frequency
  order, one point per frequency).
- A fit may carry the attribute ``weighting``: ``"noise"`` (generalised least squares under
  the run's noise model, the project's estimate) or ``"uniform"`` (the paper's method).
- ``/fits/<id>``, beside ``/runs``: fits of several runs together (the Payne effect's Kraus
  model from runs at several levels, ``identify --run A --run B --run C --model kraus``), ids
  counted as a run's fits are; attributes ``model``, ``runs`` (the run names, separated by
  spaces, in the fit's order), ``band_hz``, ``reduced_chi_square``, ``points`` (int64),
  ``created``, ``weighting`` and what the model adds (``displacement_range_m`` [lo, hi]);
  parameters and ``correlation`` as in a run's fit. Re-identifying adds a fit, as it does to a
  run. Readers of ``/runs`` never see these; readers that do not know ``/fits`` ignore it.
- Next to the file, while a writer has it: ``.NAME.lock``, the writer lock and a JSON record of
  who holds it (:mod:`viscorig.storage.writelock`); during a commit, ``.NAME.commit``, the new
  file before it replaces the old one (:mod:`viscorig.storage.atomic`).
- ``/journal``: the bench's notes and run events with their time (:mod:`viscorig.storage.journal`).
- Bounds a reader enforces before reading any value (:mod:`viscorig.storage.layout`): at most
  100,000 points per run and 1,000,000 per file, 1,000 runs, 1,000 fits per run, 64 objects per
  run or fit, 256 attributes per object, 16 values and 64 KiB per attribute, 1 MiB per setup
  text, 16 MiB per chunk, 256 MiB per file; only hard links.
"""

from __future__ import annotations

import contextlib
import math
import weakref
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import h5py
import numpy as np
from numpy.typing import ArrayLike, NDArray

from viscorig.errors import InputError
from viscorig.frf import FREQUENCY_RANGE_HZ
from viscorig.storage import journal, layout, reading, room, untrusted, writelock
from viscorig.storage.atomic import atomic_commit
from viscorig.storage.records import (
    FitRecord,
    JointFitRecord,
    RunMetadata,
    RunRecord,
    RunSettings,
    Segment,
)
from viscorig.version import __version__


def utc_now() -> str:
    """The current time as ISO 8601 UTC, to the second (``2024-05-01T12:00:00Z``)."""
    return datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")


def check_name(name: str, what: str) -> str:
    """A run or parameter name usable as an HDF5 object name."""
    if not isinstance(name, str) or not layout.NAME.fullmatch(name):
        raise InputError(f"{name!r} is not a valid name ({layout.NAME_RULE})", what)
    return name


class CampaignFile:
    """One campaign file, read-only (``mode="r"``) or appendable (``mode="a"``).

    Use :meth:`open` for an existing file and :meth:`create` for a new one; both work as context
    managers. No HDF5 handle is held between calls.

    Examples
    --------
    >>> with CampaignFile.open("paper.h5") as campaign:      # doctest: +SKIP
    ...     run = campaign.run("soft-0")
    ...     k_star = run.dynamic_stiffness_support()
    """

    def __init__(self, path: Path, mode: str, durable: bool) -> None:
        self.path = path
        self.mode = mode
        self.durable = durable
        self._writer: weakref.finalize | None = None

    def _hold(self) -> None:
        """Take the writer lock (mode "a"), released by :meth:`close`, at the latest at exit."""
        if self._writer is not None and self._writer.alive:
            return
        try:
            writelock.acquire(self.path)
        except OSError as error:
            raise room.write_failure(error, self.path, before_writing=True) from None
        self._writer = weakref.finalize(self, writelock.release, self.path)

    def _release(self) -> None:
        if self._writer is not None:
            self._writer()

    # -- opening ---------------------------------------------------------------------------

    @classmethod
    def open(cls, path: str | Path, mode: str = "r", *, durable: bool = True) -> Self:
        """Open an existing campaign file.

        Parameters
        ----------
        path
            The campaign file.
        mode
            ``"r"`` (read only) or ``"a"`` (runs, segments and fits may be added).
        durable
            ``fsync`` every commit (see :func:`viscorig.storage.atomic.atomic_commit`).

        Raises
        ------
        InputError
            The file is missing, not HDF5, damaged, or not a viscorig format 1 campaign.
        CampaignInUseError
            Mode "a" and another process is writing the file (its error names it).
        NoRoomError
            Mode "a" and there is no room to commit (disk full, ``ulimit -f``, read-only).

        Notes
        -----
        Mode "a" takes the file's writer lock before anything else and holds it until
        :meth:`close` (or the end of the process): one writer per campaign file, while any
        number of readers may read it (:mod:`viscorig.storage.writelock`).
        """
        if mode not in ("r", "a"):
            raise ValueError(f"mode must be 'r' or 'a', not {mode!r}")
        campaign = cls(Path(path), mode, durable)
        if mode == "a":
            reading.check_path(campaign.path)
            campaign._hold()
        try:
            with campaign._reading() as h5:
                reading.check_structure(h5, campaign.path)
            if mode == "a":
                size = campaign.path.stat().st_size
                room.check_room(campaign.path, size + room.HEADROOM_BYTES)
        except BaseException:
            campaign._release()
            raise
        return campaign

    @classmethod
    def create(
        cls,
        path: str | Path,
        *,
        sequence_text: str,
        sequence_file: str = "",
        station_text: str | None = None,
        station_file: str = "",
        rig: Mapping[str, float | int] | None = None,
        durable: bool = True,
    ) -> Self:
        """Create a new campaign file (never overwrites one) and return it in mode ``"a"``.

        Parameters
        ----------
        path
            The new file.
        sequence_text, sequence_file
            The sequence TOML the campaign runs, and the name of the file it came from.
        station_text, station_file
            The station TOML, if a station file is used (``None`` for the simulated rig).
        rig
            ``/rig`` attributes (all optional): table_mass_kg, table_stiffness_n_per_m,
            table_damping_ns_per_m, specimen_diameter_m, specimen_height_m, specimen_count,
            geometry_factor_m.

        Raises
        ------
        InputError
            The file exists, its folder is not writable, or a rig attribute is unknown.
        """
        rig_attributes = _checked_rig(dict(rig or {}), str(path))
        campaign = cls(Path(path), "a", durable)
        folder = campaign.path.parent if str(campaign.path.parent) else Path(".")
        if not folder.is_dir():
            raise InputError("cannot create the campaign file (folder does not exist)",
                             str(path))
        campaign._hold()
        try:
            room.check_room(campaign.path, room.HEADROOM_BYTES)
            with atomic_commit(campaign.path, create=True, durable=durable) as h5:
                h5.attrs["format"] = layout.FORMAT_NAME
                h5.attrs["format_version"] = np.int64(layout.FORMAT_VERSION)
                h5.attrs["created"] = utc_now()
                h5.attrs["software"] = f"viscorig {__version__}"
                rig_group = h5.create_group(layout.RIG_GROUP)
                for key, value in rig_attributes.items():
                    rig_group.attrs[key] = value
                h5.create_group(layout.RUNS_GROUP, track_order=True)
                setup = h5.create_group(layout.SETUP_GROUP)
                text = h5py.string_dtype("utf-8")
                setup.create_dataset(layout.SEQUENCE_TEXT, data=sequence_text, dtype=text)
                setup.attrs["sequence_file"] = sequence_file
                if station_text is not None:
                    setup.create_dataset(layout.STATION_TEXT, data=station_text, dtype=text)
                setup.attrs["station_file"] = station_file
        except FileExistsError:
            campaign._release()
            raise InputError("file exists; campaigns are never overwritten", str(path)) from None
        except BaseException:
            campaign._release()
            raise
        return campaign

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Release the writer lock (mode "a"); no HDF5 handle is held between calls.

        A write after :meth:`close` takes the lock again.
        """
        self._release()

    # -- reading ---------------------------------------------------------------------------

    def _reading(self) -> contextlib.AbstractContextManager[h5py.File]:
        return reading.open_for_reading(self.path)

    @property
    def attributes(self) -> dict[str, object]:
        """The root attributes: format, format_version, created, software."""
        with self._reading() as h5, reading.guarded(self.path, "/"):
            return reading.attributes(h5, self.path)

    @property
    def rig(self) -> dict[str, float | int]:
        """The ``/rig`` attributes that are set."""
        with self._reading() as h5:
            return reading.read_rig(h5, self.path)

    @property
    def run_names(self) -> list[str]:
        """Names of the runs, in the order they were started."""
        with self._reading() as h5, reading.guarded(self.path, f"/{layout.RUNS_GROUP}"):
            names = untrusted.members(h5[layout.RUNS_GROUP], self.path, layout.MAX_RUNS)
            for name in names:
                untrusted.check_stored_name(name, self.path, f"/{layout.RUNS_GROUP}", "run")
            return names

    def run(self, name: str) -> RunRecord:
        """Read run ``name`` whole (metadata and every dataset).

        Raises
        ------
        InputError
            No such run, or the run is damaged or not in the layout.
        """
        with self._reading() as h5, reading.guarded(self.path, f"/{layout.RUNS_GROUP}/{name}"):
            return reading.read_run(h5, name, self.path)

    def run_metadata(self, name: str) -> RunMetadata:
        """The attributes of run ``name``, checked, without reading its datasets (which runs to
        read whole).

        Raises
        ------
        InputError
            No such run, or its attributes are damaged or not in the layout.
        """
        where = f"/{layout.RUNS_GROUP}/{name}"
        with self._reading() as h5, reading.guarded(self.path, where):
            return reading.read_metadata(reading.run_group(h5, name, self.path), self.path)

    def run_attributes(self, name: str) -> dict[str, object]:
        """Every attribute of run ``name``: its settings and lifecycle, and the annotations a
        writer added (``test_time_s``, the limits it ran under, an adaptive plan's outcome)."""
        where = f"/{layout.RUNS_GROUP}/{name}"
        with self._reading() as h5, reading.guarded(self.path, where):
            return reading.attributes(reading.run_group(h5, name, self.path), self.path)

    def runs(self) -> Iterator[RunRecord]:
        """Every run, in the order they were started."""
        for name in self.run_names:
            yield self.run(name)

    def fits(self, run_name: str) -> list[FitRecord]:
        """The fits stored for a run, oldest first."""
        where = f"/{layout.RUNS_GROUP}/{run_name}/{layout.FITS_GROUP}"
        with self._reading() as h5, reading.guarded(self.path, where):
            return reading.read_fits(h5, run_name, self.path)

    def joint_fits(self) -> list[JointFitRecord]:
        """The fits of several runs together stored under ``/fits``, oldest first ([] when
        there are none)."""
        with self._reading() as h5, reading.guarded(self.path, f"/{layout.JOINT_FITS_GROUP}"):
            return reading.read_joint_fits(h5, self.path)

    def _setup_text(self, dataset: str) -> str | None:
        where = f"/{layout.SETUP_GROUP}/{dataset}"
        with self._reading() as h5, reading.guarded(self.path, where):
            untrusted.check_link(h5, layout.SETUP_GROUP, self.path)
            setup = h5.get(layout.SETUP_GROUP)
            if not isinstance(setup, h5py.Group):
                return None
            untrusted.check_link(setup, dataset, self.path)
            item = setup.get(dataset)
            if item is None:
                return None
            return reading.read_setup_text(item, self.path)

    @property
    def sequence_text(self) -> str | None:
        """The sequence TOML the campaign was run with (None if the file has none)."""
        return self._setup_text(layout.SEQUENCE_TEXT)

    @property
    def station_text(self) -> str | None:
        """The station TOML the campaign was run with (None for the simulated rig)."""
        return self._setup_text(layout.STATION_TEXT)

    @property
    def setup_files(self) -> dict[str, str]:
        """Names of the files the sequence and station texts came from."""
        with self._reading() as h5, reading.guarded(self.path, f"/{layout.SETUP_GROUP}"):
            untrusted.check_link(h5, layout.SETUP_GROUP, self.path)
            group = h5.get(layout.SETUP_GROUP)
            if not isinstance(group, h5py.Group):
                return {}
            return {key: str(value) for key, value in reading.attributes(group, self.path).items()}

    # -- writing ---------------------------------------------------------------------------

    @contextlib.contextmanager
    def _commit(self) -> Iterator[h5py.File]:
        """One atomic commit; file-system failures become InputErrors naming the file."""
        if self.mode != "a":
            raise InputError("opened read-only; open with mode='a' to change it", str(self.path))
        self._hold()
        try:
            with atomic_commit(self.path, durable=self.durable) as h5:
                reading.check_root(h5, self.path)  # never build on a file that is not a campaign
                yield h5
        except OSError as error:
            raise InputError(f"cannot read the campaign file to change it ({error.strerror})",
                             str(self.path)) from None

    def commit(self) -> contextlib.AbstractContextManager[h5py.File]:
        """One atomic change of the file, for the documented extensions of the layout (such as
        the ``/dma`` runs of :mod:`viscorig.materials.dmastore`): the h5py file to change, whole
        or not at all."""
        return self._commit()

    def reading(self) -> contextlib.AbstractContextManager[h5py.File]:
        """The file opened read-only, every open failure an InputError naming it."""
        return self._reading()

    def start_run(self, name: str, settings: RunSettings) -> None:
        """Create ``/runs/<name>`` with status "running" and empty datasets.

        Raises
        ------
        InputError
            The name is not valid or a run of that name exists (use :meth:`resume_run`).
        """
        check_name(name, f"{self.path}: run name")
        attributes = _settings_attributes(settings)
        with self._commit() as h5:
            self._new_run(h5, name, attributes)

    def _new_run(self, h5: h5py.File, name: str, attributes: dict[str, object]) -> h5py.Group:
        runs = h5[layout.RUNS_GROUP]
        if name in runs:
            raise InputError("run exists", f"{self.path}: /{layout.RUNS_GROUP}/{name}")
        if len(runs) >= layout.MAX_RUNS:
            raise InputError(f"holds {layout.MAX_RUNS} runs, the most a campaign file may hold",
                             f"{self.path}: /{layout.RUNS_GROUP}")
        group = runs.create_group(name)
        group.attrs.update(attributes)
        group.attrs["status"] = "running"
        group.attrs["started"] = utc_now()
        group.attrs["finished"] = ""
        for spec in layout.REQUIRED_DATASETS:
            _create_column(group, spec.name, _STORED_DTYPES[spec.kind], spec.units)
        _link_frequency_scale(group)
        return group

    def add_run(self, name: str, settings: RunSettings, segment: Segment,
                status: str = "complete") -> int:
        """Store a whole run (e.g. an import) in one commit: all of it, or nothing.

        Returns
        -------
        int
            The number of points stored.
        """
        check_name(name, f"{self.path}: run name")
        if status not in layout.RUN_STATUSES:
            raise ValueError(f"status must be one of {layout.RUN_STATUSES}, not {status!r}")
        attributes = _settings_attributes(settings)
        columns = segment.columns()
        with self._commit() as h5:
            group = self._new_run(h5, name, attributes)
            points = _append_columns(group, columns, self.path)
            group.attrs["status"] = status
            if status != "running":
                group.attrs["finished"] = utc_now()
            return points

    def append_segment(
        self, run_name: str, segment: Segment,
        attributes: Mapping[str, str | float | int | bool] | None = None,
    ) -> int:
        """Append a segment's points to a running run in one atomic commit.

        ``attributes`` are run attributes set in the same commit (what the run knows after this
        segment: its ``test_time_s``), checked as :meth:`annotate` checks them.

        Returns
        -------
        int
            The number of points the run holds after the commit.

        Raises
        ------
        ValueError
            The segment's arrays are inconsistent, or its set of datasets differs from the run's.
        InputError
            No such run, or the run is not "running".
        """
        columns = segment.columns()
        checked = self._annotation(attributes or {}, dataset=None)
        with self._commit() as h5:
            group = reading.run_group(h5, run_name, self.path)
            status = reading.read_choice(group, "status", self.path, layout.RUN_STATUSES)
            if status != "running":
                raise InputError(f"run is {status}; only a running run takes points",
                                 f"{self.path}: {group.name}")
            points = _append_columns(group, columns, self.path)
            group.attrs.update(checked)
            return points

    def finish_run(self, run_name: str, status: str = "complete") -> None:
        """Mark a run "complete" or "aborted" and stamp ``finished``."""
        if status not in ("complete", "aborted"):
            raise ValueError(f"status must be 'complete' or 'aborted', not {status!r}")
        with self._commit() as h5:
            group = reading.run_group(h5, run_name, self.path)
            group.attrs["status"] = status
            group.attrs["finished"] = utc_now()

    def resume_run(self, run_name: str) -> int:
        """Set a run back to "running" (``finished`` = "") to continue it; return its points."""
        with self._commit() as h5:
            group = reading.run_group(h5, run_name, self.path)
            group.attrs["status"] = "running"
            group.attrs["finished"] = ""
            return int(group["frequency_hz"].shape[0])

    def annotate(
        self, run_name: str, attributes: Mapping[str, str | float | int | bool],
        dataset: str | None = None,
    ) -> None:
        """Add descriptive attributes to a run group, or to one of its datasets, in one commit.

        For what the layout leaves open and a reader should know (how ``time_s`` was clocked,
        why ``source_amplitude`` is NaN, the limits a sweep ran under). Attributes the layout
        defines (a run's settings and lifecycle, a dataset's ``units``) cannot be changed here.

        Raises
        ------
        InputError
            No such run or dataset, a reserved or invalid name, or a value that is not text,
            a number or a boolean.
        """
        checked = self._annotation(attributes, dataset)
        with self._commit() as h5:
            group = reading.run_group(h5, run_name, self.path)
            target = group if dataset is None else group.get(dataset)
            if not isinstance(target, h5py.Group | h5py.Dataset):
                raise InputError("no such dataset", f"{self.path}: {group.name}/{dataset}")
            target.attrs.update(checked)

    def _annotation(
        self, attributes: Mapping[str, str | float | int | bool], dataset: str | None
    ) -> dict[str, object]:
        """Annotation attributes checked: valid names, not the layout's own, plain values."""
        reserved = {"units"} if dataset else {"status", "started", "finished",
                                              *RunSettings.__dataclass_fields__}
        checked: dict[str, object] = {}
        for key, value in attributes.items():
            check_name(key, f"{self.path}: attribute")
            if key in reserved:
                raise InputError("is defined by the layout; not an annotation",
                                 f"{self.path}: attribute {key!r}")
            if isinstance(value, bool | np.bool_):
                checked[key] = np.bool_(value)
            elif isinstance(value, str | int | float | np.integer | np.floating):
                checked[key] = value
            else:
                raise InputError(f"{type(value).__name__} is not text, a number or a boolean",
                                 f"{self.path}: attribute {key!r}")
        return checked

    def add_journal_entry(self, kind: str, text: str, run: str = "") -> journal.JournalEntry:
        """Append a note or a run event to ``/journal`` (:mod:`viscorig.storage.journal`) in one
        commit; return the entry as stored.

        Raises
        ------
        InputError
            An unknown kind, an empty or too long text, or a full journal.
        """
        text = journal.check_entry(kind, text, f"{self.path}: /{journal.JOURNAL_GROUP}")
        entry = journal.JournalEntry(utc_now(), kind, str(run), text)
        with self._commit() as h5:
            journal.append(h5, entry, self.path)
        return entry

    @property
    def journal(self) -> list[journal.JournalEntry]:
        """Every entry of ``/journal``, in the order written (none when there is no journal)."""
        with self._reading() as h5, reading.guarded(self.path, f"/{journal.JOURNAL_GROUP}"):
            return journal.read(h5, self.path)

    def add_fit(
        self,
        run_name: str,
        *,
        model: str,
        band_hz: tuple[float, float],
        rms_error: float,
        noise_floor: float,
        parameters: Mapping[str, tuple[float, float, str]],
        correlation: tuple[Sequence[str], ArrayLike] | None = None,
        weighting: str | None = None,
    ) -> str:
        """Store an identification result under ``/runs/<run>/fits/<id>``.

        Parameters
        ----------
        run_name
            The run fitted.
        model
            Model spec string (design.md), e.g. ``"voigt"``.
        band_hz
            (lo, hi) band fitted, Hz.
        rms_error, noise_floor
            Error measures of design.md (dimensionless).
        parameters
            name -> (value, stderr, unit), an :class:`~viscorig.numbers.Estimate` or any such
            triple; stderr NaN when unknown.
        correlation
            (names, matrix): the correlation matrix of the named parameters, stored as the
            2-D dataset ``correlation`` with attribute ``parameters`` (the names, in order,
            separated by spaces).
        weighting
            How the fit weighted the points (``"noise"``, ``"uniform"``), stored as the fit's
            attribute ``weighting``.

        Returns
        -------
        str
            The new fit's id.
        """
        where = f"{self.path}: fit of {run_name}"
        lo, hi = _checked_band(band_hz, where, same=False)
        if not isinstance(model, str) or not model.strip():
            raise InputError("model spec is empty", where)
        checked, names, matrix = _checked_parameters(parameters, correlation, where)
        with self._commit() as h5:
            group = reading.run_group(h5, run_name, self.path)
            untrusted.check_link(group, layout.FITS_GROUP, self.path)
            return _write_fit(group.require_group(layout.FITS_GROUP), where, {
                "model": model, "band_hz": np.array([lo, hi]), "rms_error": float(rms_error),
                "noise_floor": float(noise_floor)}, weighting, checked, names, matrix)


    def add_joint_fit(
        self,
        runs: Sequence[str],
        *,
        model: str,
        band_hz: tuple[float, float],
        reduced_chi_square: float,
        points: int,
        parameters: Mapping[str, tuple[float, float, str]],
        correlation: tuple[Sequence[str], ArrayLike] | None = None,
        weighting: str | None = None,
        attributes: Mapping[str, str | float | int | Sequence[float]] | None = None,
    ) -> str:
        """Store a fit of several runs together under ``/fits/<id>`` (module text) in one
        commit, and return its id.

        Parameters
        ----------
        runs
            The runs fitted (two or more, each a run of the file), in the fit's order.
        model
            What was fitted, e.g. ``"kraus"``.
        band_hz
            (lo, hi) band fitted, Hz.
        reduced_chi_square, points
            Of the fit.
        parameters, correlation, weighting
            As :meth:`add_fit`.
        attributes
            Further attributes of the fit (names not the ones above): text, a number, or
            numbers (stored as a float64 array).

        Raises
        ------
        InputError
            Fewer than two runs, a run the file does not have, an invalid band, name or value.
        """
        where = f"{self.path}: /{layout.JOINT_FITS_GROUP}"
        names = tuple(check_name(run, f"{where}: run") for run in runs)
        if len(set(names)) < 2:
            raise InputError("a joint fit names two or more runs", where)
        lo, hi = _checked_band(band_hz, where, same=True)
        if not isinstance(model, str) or not model.strip():
            raise InputError("model spec is empty", where)
        checked, order, matrix = _checked_parameters(parameters, correlation, where)
        reserved = layout.JOINT_FIT_ATTRIBUTES
        more: dict[str, object] = {}
        for key, given in (attributes or {}).items():
            check_name(key, f"{where}: attribute")
            if key in reserved:
                raise InputError("is defined by the layout", f"{where}: attribute {key!r}")
            if isinstance(given, str | int | float | np.integer | np.floating):
                more[key] = given
            else:
                array = np.asarray(given, dtype=float).ravel()
                if array.size > layout.MAX_ATTRIBUTE_VALUES:
                    raise InputError(f"more than {layout.MAX_ATTRIBUTE_VALUES} values",
                                     f"{where}: attribute {key!r}")
                more[key] = array
        with self._commit() as h5:
            for run in names:
                reading.run_group(h5, run, self.path)  # each a run of this file
            untrusted.check_link(h5, layout.JOINT_FITS_GROUP, self.path)
            return _write_fit(h5.require_group(layout.JOINT_FITS_GROUP), where, {
                "model": model, "runs": " ".join(names),  # one text: run names hold no space
                "band_hz": np.array([lo, hi]), "reduced_chi_square": float(reduced_chi_square),
                "points": np.int64(points), **more}, weighting, checked, order, matrix)


_STORED_DTYPES = {"float": np.float64, "complex": np.complex128, "flags": np.uint16}


def _create_column(group: h5py.Group, name: str, dtype: object, units: str) -> None:
    dataset = group.create_dataset(
        name, shape=(0,), maxshape=(None,), chunks=(layout.CHUNK_POINTS,), dtype=dtype
    )
    dataset.attrs["units"] = units


def _append_columns(group: h5py.Group, columns: dict[str, tuple[np.ndarray, str | None]],
                    path: Path) -> int:
    """Append one segment's columns to a run group; return the run's points after it."""
    points = group["frequency_hz"].shape[0]
    present = {key for key, item in group.items() if isinstance(item, h5py.Dataset)}
    if points and set(columns) != present:
        raise ValueError(
            f"segment datasets {sorted(columns)} differ from the run's {sorted(present)}"
        )
    total = points + len(columns["frequency_hz"][0])
    if total > layout.MAX_RUN_POINTS:
        raise InputError(f"{total} points; a run holds at most {layout.MAX_RUN_POINTS}",
                         f"{path}: {group.name}")
    created = False
    for key, (values, units) in columns.items():
        if key not in group:
            spec = layout.KNOWN_DATASETS.get(key)
            _create_column(group, key, values.dtype, spec.units if spec else units or "1")
            created = True
        dataset = group[key]
        dataset.resize((total,))
        dataset[points:] = values
    if created or not h5py.h5ds.is_scale(group["frequency_hz"].id):
        _link_frequency_scale(group)
    return total


def _link_frequency_scale(group: h5py.Group) -> None:
    """Make ``frequency_hz`` the dimension scale of every per-point dataset of a run, so that
    netCDF-aware tools (xarray with h5netcdf, Panoply) see frequency as the coordinate.

    Idempotent; a file written before scales existed gains them at its next write.
    """
    frequency = group["frequency_hz"]
    if not h5py.h5ds.is_scale(frequency.id):
        frequency.make_scale("frequency_hz")
    for item in group.values():
        if isinstance(item, h5py.Dataset) and item.ndim == 1 and item.name != frequency.name \
                and not h5py.h5ds.is_attached(item.id, frequency.id, 0):
            item.dims[0].attach_scale(frequency)


def _settings_attributes(settings: RunSettings) -> dict[str, object]:
    values = asdict(settings)
    values = {key: values[key] for key in RunSettings.__dataclass_fields__}
    if values["direction"] not in layout.DIRECTIONS:
        raise ValueError(f"direction must be 'up' or 'down', not {values['direction']!r}")
    for key, held in layout.RUN_NUMBERS.items():
        if not held.holds(float(values[key])):
            raise InputError(f"{values[key]!r}, which no reader of the file takes "
                             f"({held.describe()})", key)
        values[key] = np.int64(values[key]) if held.integer else np.float64(values[key])
    values["simulated"] = np.bool_(values["simulated"])
    for key in ("specimen", "instrument", "resource"):
        values[key] = str(values[key])
        size = len(values[key].encode("utf-8", "surrogatepass"))
        if size > layout.MAX_ATTRIBUTE_BYTES or "\x00" in values[key]:
            what = (f"text of {size} bytes; at most {layout.MAX_ATTRIBUTE_BYTES}"
                    if size > layout.MAX_ATTRIBUTE_BYTES else "text with a NUL character")
            raise InputError(f"{what}, which no reader of the file takes", key)
    return values


def _checked_rig(rig: Mapping[str, Any], where: str) -> dict[str, object]:
    checked: dict[str, object] = {}
    for key, value in rig.items():
        held = layout.RIG_NUMBERS.get(key)
        if held is None:
            raise InputError(f"unknown /rig attribute {key!r} (known: "
                             f"{', '.join(layout.RIG_NUMBERS)})", where)
        if not held.holds(float(value)):
            raise InputError(f"{key} = {value!r}, which no reader of the file takes "
                             f"({held.describe()})", where)
        checked[key] = np.int64(value) if held.integer else np.float64(value)
    return checked


@contextlib.contextmanager
def campaign_for_import(path: Path, run_name: str) -> Iterator[CampaignFile]:
    """The campaign file an import adds the run ``run_name`` to: opened for appending, or created
    where there is none. A run of that name is refused (imports never overwrite a run), and a
    file this import created is removed again when the import fails."""
    created = not path.exists()
    campaign = CampaignFile.create(path, sequence_text="", sequence_file="") if created \
        else CampaignFile.open(path, "a")
    try:
        with campaign:
            if run_name in campaign.run_names:
                raise InputError("run exists; imports never overwrite a run",
                                 f"{path}: /{layout.RUNS_GROUP}/{run_name}")
            yield campaign
    except BaseException:
        if created:
            path.unlink(missing_ok=True)
        raise


def _write_fit(fits: h5py.Group, where: str, attributes: Mapping[str, object],
               weighting: str | None, checked: Mapping[str, tuple[float, float, str]],
               names: Sequence[str], matrix: NDArray[np.float64] | None) -> str:
    """A new fit group in ``fits`` (a run's ``fits`` or ``/fits``): the next id, ``attributes``
    with the creation time and the weighting, a dataset per parameter (value, ``stderr``,
    ``units``) and the correlation matrix. Refused when ``fits`` holds :data:`~.layout.MAX_FITS`
    fits already: a reader refuses more, and the run or file would no longer read."""
    if len(fits) >= layout.MAX_FITS:
        raise InputError(f"holds {layout.MAX_FITS} fits, the most it may hold", where)
    numbers = [int(key) for key in fits if key.isdigit()]
    fit_id = f"{max(numbers, default=0) + 1:04d}"
    fit = fits.create_group(fit_id)
    fit.attrs.update({**attributes, "created": utc_now()})
    if weighting:
        fit.attrs["weighting"] = str(weighting)
    for key, (value, stderr, unit) in checked.items():
        dataset = fit.create_dataset(key, data=np.float64(value))
        dataset.attrs["stderr"] = stderr
        dataset.attrs["units"] = unit
    if matrix is not None:
        dataset = fit.create_dataset(layout.FIT_CORRELATION, data=matrix)
        dataset.attrs["parameters"] = " ".join(names)  # one text: names hold no space
        dataset.attrs["units"] = "1"
    return fit_id


def _checked_band(band_hz: tuple[float, float], where: str, *, same: bool
                  ) -> tuple[float, float]:
    """``band_hz`` as ``(lo, hi)``, refused unless finite with ``0 <= lo < hi`` (``lo <= hi``
    when ``same``: a fit of several runs at one frequency) and ``hi`` within
    :data:`~viscorig.frf.FREQUENCY_RANGE_HZ`."""
    lo, hi = (float(value) for value in band_hz)
    ordered = lo <= hi if same else lo < hi
    if not (math.isfinite(lo) and math.isfinite(hi) and lo >= 0 and ordered
            and hi <= FREQUENCY_RANGE_HZ[1]):
        raise InputError(f"band_hz {band_hz!r} is not 0 <= lo {'<=' if same else '<'} hi <= "
                         f"{FREQUENCY_RANGE_HZ[1]:g} Hz", where)
    return lo, hi


def _checked_parameters(parameters: Mapping[str, tuple[float, float, str]],
                        correlation: tuple[Sequence[str], ArrayLike] | None, where: str
                        ) -> tuple[dict[str, tuple[float, float, str]], tuple[str, ...],
                                   NDArray[np.float64] | None]:
    """A fit's parameters ``{name: (value, stderr, unit)}`` and correlation ``(names, matrix)``
    checked for storing: names that HDF5 can hold, a correlation of the fit's own parameters."""
    checked = {}
    for key, (value, stderr, unit) in parameters.items():
        check_name(key, f"{where}: parameter")
        if not math.isfinite(float(value)):
            raise InputError(f"parameter {key} = {value!r}, which no reader of the file takes "
                             "(a finite number)", where)
        checked[key] = (float(value), float(stderr), str(unit))
    names: tuple[str, ...] = ()
    matrix = None
    if correlation is not None:
        names = tuple(str(name) for name in correlation[0])
        matrix = np.asarray(correlation[1], dtype=float).reshape(len(names), len(names))
        if set(names) - set(checked) or layout.FIT_CORRELATION in checked:
            raise InputError("correlation names parameters the fit does not have", where)
    return checked, names, matrix
