"""The rig as identification sees it: the table's parameters and the specimens' geometry factor.

Geometry factor θ (``K* = θ E (1 + iη)``, Eq. 6) is a choice, made explicit here. For one
cylindrical specimen of diameter ``d`` and height ``h`` in shear, Tomlinson's factor is
``π d²/(4h)``. The paper then writes ``θ = π d²/(8h)`` for its device with two specimens,
*half* the single-specimen factor. The two specimens hold the disc from either side and both
shear when it moves, so mechanically they act in parallel, which gives *twice* the factor,
``2 · π d²/(4h)``. The default arrangement ``"paper"`` reproduces the paper's value so that its
moduli can be compared; ``"parallel"`` is the mechanics of two specimens sharing the load, and
``"single"`` is one specimen. The two choices differ by a factor 4 in ``E'`` (``η`` does not
depend on θ). A campaign file may also give θ outright (``/rig`` ``geometry_factor_m``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from viscorig.errors import InputError

#: Arrangement name -> factor multiplying the single-specimen shear factor π d²/(4h).
ARRANGEMENTS: dict[str, str] = {
    "paper": "π d²/(8h): the paper's value for its two-specimen device (half of one specimen)",
    "parallel": "count · π d²/(4h): specimens sharing the load in parallel",
    "single": "π d²/(4h): one specimen in shear",
}


#: Sizes a specimen's diameter and height can have (m): a micrometre to ten metres.
SPECIMEN_SIZE_RANGE_M = (1e-6, 10.0)


def geometry_factor(
    diameter_m: float, height_m: float, count: int = 2, arrangement: str = "paper"
) -> float:
    """Geometry factor θ in metres for cylindrical specimens in shear (see the module text).

    Parameters
    ----------
    diameter_m, height_m
        Specimen diameter and height (m).
    count
        Number of specimens (used by ``"parallel"``).
    arrangement
        ``"paper"`` (default, ``π d²/(8h)``), ``"parallel"`` (``count · π d²/(4h)``) or
        ``"single"`` (``π d²/(4h)``).
    """
    if not (diameter_m > 0 and height_m > 0):
        raise InputError(f"specimen diameter {diameter_m} m and height {height_m} m must be > 0")
    low, high = SPECIMEN_SIZE_RANGE_M
    if not (low <= diameter_m <= high and low <= height_m <= high):
        raise InputError(f"specimen diameter {diameter_m:g} m and height {height_m:g} m must lie "
                         f"between {low:g} and {high:g} m")
    single = math.pi * diameter_m**2 / (4.0 * height_m)
    if arrangement == "paper":
        return single / 2.0
    if arrangement == "parallel":
        if count < 1:
            raise InputError(f"specimen count {count} must be at least 1")
        return count * single
    if arrangement == "single":
        return single
    raise InputError(f"unknown arrangement '{arrangement}' (one of: {', '.join(ARRANGEMENTS)})")


@dataclass(frozen=True)
class RigDescription:
    """Table parameters and specimen geometry, as far as they are known.

    Attributes
    ----------
    table_mass_kg, table_stiffness_n_per_m, table_damping_ns_per_m
        ``M_s, K_s, C_s`` of the table suspension (``None`` when unknown).
    specimen_diameter_m, specimen_height_m, specimen_count
        Specimen geometry (``None`` when unknown; the paper gives ``h = 12 mm`` and no ``d``).
    arrangement
        How θ follows from the geometry (:data:`ARRANGEMENTS`).
    geometry_factor_m
        θ given outright; overrides the geometry.
    table_mass_stderr_kg, table_stiffness_stderr_n_per_m, table_damping_stderr_ns_per_m
        Standard uncertainties of the table's values (``None``: exact, as far as anyone said).
    """

    table_mass_kg: float | None = None
    table_stiffness_n_per_m: float | None = None
    table_damping_ns_per_m: float | None = None
    specimen_diameter_m: float | None = None
    specimen_height_m: float | None = None
    specimen_count: int = 2
    arrangement: str = "paper"
    geometry_factor_m: float | None = None
    table_mass_stderr_kg: float | None = None
    table_stiffness_stderr_n_per_m: float | None = None
    table_damping_stderr_ns_per_m: float | None = None

    @classmethod
    def from_attributes(cls, attributes: Mapping[str, float | int]) -> RigDescription:
        """From a campaign file's ``/rig`` attributes (data-format.md)."""

        def number(key: str) -> float | None:
            value = attributes.get(key)
            return None if value is None or not math.isfinite(float(value)) else float(value)

        return cls(
            table_mass_kg=number("table_mass_kg"),
            table_stiffness_n_per_m=number("table_stiffness_n_per_m"),
            table_damping_ns_per_m=number("table_damping_ns_per_m"),
            specimen_diameter_m=number("specimen_diameter_m"),
            specimen_height_m=number("specimen_height_m"),
            specimen_count=_count(attributes.get("specimen_count")),
            geometry_factor_m=number("geometry_factor_m"),
            table_mass_stderr_kg=number("table_mass_stderr_kg"),
            table_stiffness_stderr_n_per_m=number("table_stiffness_stderr_n_per_m"),
            table_damping_stderr_ns_per_m=number("table_damping_stderr_ns_per_m"),
        )

    @property
    def table(self) -> dict[str, float] | None:
        """``{"M_s", "K_s", "C_s"}`` when all three are known, else ``None``."""
        values = (self.table_mass_kg, self.table_stiffness_n_per_m, self.table_damping_ns_per_m)
        if any(value is None for value in values):
            return None
        return dict(zip(("M_s", "K_s", "C_s"), values, strict=True))  # type: ignore[arg-type]

    @property
    def table_stderr(self) -> dict[str, float] | None:
        """Standard uncertainties given for ``M_s, K_s, C_s`` (positive ones only), or ``None``."""
        given = zip(
            ("M_s", "K_s", "C_s"),
            (self.table_mass_stderr_kg, self.table_stiffness_stderr_n_per_m,
             self.table_damping_stderr_ns_per_m),
            strict=True,
        )
        stderr = {name: value for name, value in given if value is not None and value > 0}
        return stderr or None

    @property
    def theta(self) -> float | None:
        """Geometry factor θ in metres, or ``None`` when neither θ nor the geometry is known."""
        if self.geometry_factor_m is not None:
            if not self.geometry_factor_m > 0:
                raise InputError(f"geometry factor {self.geometry_factor_m:g} m must be > 0",
                                 "/rig")
            return self.geometry_factor_m
        if self.specimen_diameter_m is None or self.specimen_height_m is None:
            return None
        return geometry_factor(
            self.specimen_diameter_m, self.specimen_height_m, self.specimen_count, self.arrangement
        )


def _count(value: object) -> int:
    """``/rig`` ``specimen_count``: 2 (the paper's device) when absent or NaN; as given
    otherwise (a count below one is refused where the count matters)."""
    if value is None:
        return 2
    number = float(value)  # type: ignore[arg-type]
    return int(number) if math.isfinite(number) else 2
