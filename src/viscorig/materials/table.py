"""A modulus table: storage and loss modulus per (frequency, temperature) point, SI units.

The one form every source of material data takes before a master curve is built from it: a DMA
file (:mod:`viscorig.materials.dmafile`), a DMA run stored in a campaign file
(:mod:`viscorig.materials.dmastore`), or rig runs of one specimen at several temperatures
(:mod:`viscorig.materials.rigdata`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.storage.layout import TEMPERATURE_RANGE_C

#: What the modulus is: tensile/Young's ("E") or shear ("G").
MODULUS_KINDS = ("E", "G")
#: Frequencies a modulus is measured at (Hz): from a creep test's decades of hours to an
#: ultrasonic one's megahertz, with room to spare; outside them a number is a unit or a file
#: gone wrong.
FREQUENCY_RANGE_HZ = (1e-9, 1e9)
#: Moduli a master curve uses (Pa): from the loss modulus of a thin liquid to ten times
#: diamond's; outside them (a denormal 1e-320, an instrument's overflow marker) a value is
#: kept as measured and left out (:meth:`ModulusTable.usable`).
MODULUS_RANGE_PA = (1e-6, 1e13)
#: Points a master curve is fitted on at most: about a minute of fitting. Isothermal sweeps
#: hold tens to a few thousand.
MAX_MASTER_POINTS = 10_000


@dataclass(frozen=True)
class ModulusTable:
    """Storage and loss modulus of one material over frequency and temperature.

    Attributes
    ----------
    frequency_hz, temperature_c, storage_pa, loss_pa
        One value per point (Hz, °C, Pa, Pa).
    set_index
        The isothermal sweep each point belongs to (0, 1, ...): points of one set share one
        shift factor.
    modulus
        ``"E"`` or ``"G"``.
    source
        Where the data came from (a file name, run names), for messages and FE-card comments.
    """

    frequency_hz: NDArray[np.float64]
    temperature_c: NDArray[np.float64]
    storage_pa: NDArray[np.float64]
    loss_pa: NDArray[np.float64]
    set_index: NDArray[np.int64]
    modulus: str = "E"
    source: str = ""
    set_names: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        n = np.asarray(self.frequency_hz).size
        for name in ("temperature_c", "storage_pa", "loss_pa", "set_index"):
            if np.asarray(getattr(self, name)).size != n:
                raise ValueError(f"{name} has {np.asarray(getattr(self, name)).size} values, "
                                 f"frequency_hz {n}")
        if self.modulus not in MODULUS_KINDS:
            raise InputError(f"modulus {self.modulus!r} is not one of E, G", self.source or None)

    @property
    def points(self) -> int:
        """Number of points."""
        return int(np.asarray(self.frequency_hz).size)

    @property
    def sets(self) -> NDArray[np.int64]:
        """The set numbers, in increasing order."""
        return np.unique(self.set_index)

    def set_temperatures_c(self) -> NDArray[np.float64]:
        """Mean temperature of each set (°C), in the order of :attr:`sets`."""
        return np.array([self.temperature_c[self.set_index == s].mean() for s in self.sets])

    def check(self, where: str) -> None:
        """Refuse a table no master curve can be built from, naming the first bad point.

        A modulus that is not positive (a DMA instrument reports a slightly negative loss
        modulus where tan δ is below its resolution) is kept as measured: :meth:`usable` leaves
        the point out of master curves.

        Raises
        ------
        InputError
            More than :data:`MAX_MASTER_POINTS` points, a frequency outside
            :data:`FREQUENCY_RANGE_HZ`, a temperature outside the range a specimen is measured
            at, or fewer than two usable points.
        """
        if self.points > MAX_MASTER_POINTS:
            raise InputError(f"{self.points} points; a master curve is fitted on at most "
                             f"{MAX_MASTER_POINTS} (isothermal sweeps hold a few thousand: "
                             "import the sweeps of one specimen, or fewer temperatures)", where)
        low, high = FREQUENCY_RANGE_HZ
        checks = (
            ("frequency_hz", (self.frequency_hz >= low) & (self.frequency_hz <= high),
             f"frequency must be a number from {low:g} to {high:g} Hz"),
            ("temperature_c", np.isfinite(self.temperature_c)
             & (self.temperature_c > TEMPERATURE_RANGE_C[0])
             & (self.temperature_c <= TEMPERATURE_RANGE_C[1]),
             f"temperature must be a number above {TEMPERATURE_RANGE_C[0]:g} °C and at most "
             f"{TEMPERATURE_RANGE_C[1]:g} °C"),
        )
        for name, good, what in checks:
            good = np.asarray(good) & np.isfinite(getattr(self, name))
            if not good.all():
                index = int(np.flatnonzero(~good)[0])
                raise InputError(f"{what}, not {getattr(self, name)[index]!r} (point {index + 1})",
                                 f"{where}: {name}")
        usable = int(self.usable().sum())
        if usable < 2:
            raise InputError(f"{usable} point(s) with a storage and loss modulus in range; a "
                             "master curve needs more", where)

    def usable(self) -> NDArray[np.bool_]:
        """Points whose storage and loss moduli are both numbers within
        :data:`MODULUS_RANGE_PA`."""
        return _within_moduli(self.storage_pa) & _within_moduli(self.loss_pa)

    def point_records(self, which: NDArray[np.bool_], why: str) -> list[dict]:
        """The points where ``which`` is true, each with its number (from 1), set, temperature,
        frequency, both moduli and ``why``."""
        return [self._record(index, why) for index in np.flatnonzero(which).tolist()]

    def unusable_points(self) -> list[dict]:
        """Every point :meth:`usable` leaves out (as :meth:`point_records` gives them), with
        why."""
        low, high = MODULUS_RANGE_PA
        out = []
        for index in np.flatnonzero(~self.usable()).tolist():
            bad = [name for name, value in (("storage", self.storage_pa[index]),
                                            ("loss", self.loss_pa[index]))
                   if not _within_moduli(np.array(value))]
            out.append(self._record(index, " and ".join(bad) + f" modulus not a number from "
                                    f"{low:g} to {high:g} Pa"))
        return out

    def _record(self, index: int, why: str) -> dict:
        return {"point": index + 1, "set": int(self.set_index[index]),
                "temperature_c": float(self.temperature_c[index]),
                "frequency_hz": float(self.frequency_hz[index]),
                "storage_pa": float(self.storage_pa[index]),
                "loss_pa": float(self.loss_pa[index]), "why": why}

    def select(self, keep: NDArray[np.bool_]) -> ModulusTable:
        """The points where ``keep`` is true."""
        return ModulusTable(
            frequency_hz=self.frequency_hz[keep], temperature_c=self.temperature_c[keep],
            storage_pa=self.storage_pa[keep], loss_pa=self.loss_pa[keep],
            set_index=self.set_index[keep], modulus=self.modulus, source=self.source,
            set_names=self.set_names,
        )


def _within_moduli(values: NDArray[np.float64]) -> NDArray[np.bool_]:
    low, high = MODULUS_RANGE_PA
    with np.errstate(invalid="ignore"):
        return np.asarray((values >= low) & (values <= high))


def concatenate(tables: list[ModulusTable], source: str) -> ModulusTable:
    """One table of several (runs of one specimen), each table's sets renumbered after the last.

    Raises
    ------
    InputError
        The tables do not all hold the same kind of modulus.
    """
    kinds = {table.modulus for table in tables}
    if len(kinds) > 1:
        raise InputError(f"runs hold different moduli ({', '.join(sorted(kinds))})", source)
    offset, sets, names = 0, [], list[str]()
    for table in tables:
        _, renumbered = np.unique(table.set_index, return_inverse=True)
        sets.append(renumbered + offset)
        offset += int(renumbered.max()) + 1 if renumbered.size else 0
        names.extend(table.set_names or [table.source] * int(np.unique(renumbered).size))
    return ModulusTable(
        frequency_hz=np.concatenate([t.frequency_hz for t in tables]),
        temperature_c=np.concatenate([t.temperature_c for t in tables]),
        storage_pa=np.concatenate([t.storage_pa for t in tables]),
        loss_pa=np.concatenate([t.loss_pa for t in tables]),
        set_index=np.concatenate(sets).astype(np.int64),
        modulus=kinds.pop(), source=source, set_names=tuple(names),
    )
