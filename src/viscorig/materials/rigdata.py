"""Shear moduli of one specimen from rig runs at several temperatures.

Each run is one isothermal set. ``K*`` comes from the support FRF by Eq. (5),
``K* = F_v/X_v + ω² M_v`` (exact whatever the load cell's stiffness), with the disc mass ``M_v``
from the newest fit stored for the run that has one (``identify --model voigt`` gives it), or
given outright; or (``kstar_source="fit"``) from the newest stored fit of a specimen model,
evaluated at the run's frequencies (the identified model's K*). The modulus is ``G* = K*/θ``
with the rig's geometry factor θ (``/rig`` attributes ``geometry_factor_m``, or
``specimen_diameter_m`` and ``specimen_height_m``). The temperature of each point is the run's
per-point ``temperature_c`` dataset where it has one, else its ``temperature_c`` attribute.
Flagged points and points whose K* has no positive real and imaginary part are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viscorig.errors import InputError
from viscorig.estimates import kstar_from_support
from viscorig.identify import identify_run, recorded_temperature_c
from viscorig.materials.table import ModulusTable
from viscorig.models import Context, parse_spec
from viscorig.numbers import with_uncertainty
from viscorig.rig import RigDescription
from viscorig.storage import CampaignFile


def disc_mass_of(campaign: CampaignFile, run_name: str) -> float | None:
    """``M_v`` (kg) of the newest fit of the run that identified one, else ``None``."""
    for fit in reversed(campaign.fits(run_name)):
        parameter = fit.parameters.get("M_v")
        if parameter is not None and math.isfinite(parameter.value) and parameter.value >= 0:
            return float(parameter.value)
    return None


#: The models whose ``M_v`` master takes, the one of lower BIC per run, for runs that were
#: never identified (a load cell's compliance left out biases ``M_v`` by several %).
DISC_MASS_MODELS = ("fractional", "fractional+load_cell")
#: Largest relative standard error of a run's ``M_v`` that master averages.
DISC_MASS_PRECISION = 0.05


@dataclass(frozen=True)
class DiscMass:
    """The disc's mass ``M_v`` found from the runs, kg, with its standard error and how."""

    value: float
    stderr: float
    basis: str


def identified_disc_mass(campaign: CampaignFile, runs: list[str]) -> DiscMass:
    """``M_v`` for rig runs of one specimen that were never identified: each run fitted with
    :data:`DISC_MASS_MODELS` (the table's parameters from its bare-table run), the fit of lower
    BIC kept, the disc's mass taken as the weighted mean over the runs, since the disc does not
    change with the temperature its rubber is measured at. Its standard error is the larger of
    the mean's and the runs' scatter over the square root of their number: what the models
    leave out moves each run's ``M_v`` a little, differently at each temperature.

    Raises
    ------
    InputError
        No run could be fitted (what is missing is named).
    """
    masses, weights = [], []
    for name in runs:
        result = min((identify_run(campaign, name, spec)[0] for spec in DISC_MASS_MODELS),
                     key=lambda fitted: fitted.bic)
        estimate = result.parameters.get("M_v")
        if (estimate is None or any("M_v is at a bound" in text for text in result.warnings)
                or not 0 < estimate.stderr <= DISC_MASS_PRECISION * estimate.value):
            continue
        masses.append(estimate.value)
        weights.append(1.0 / estimate.stderr**2)
    if not masses:
        raise InputError("no disc mass M_v: the runs do not tell it within "
                         f"{DISC_MASS_PRECISION:.0%} (identify a run with a model that fits "
                         "it, viscorig identify ... --model, or give --disc-mass)",
                         f"{campaign.path}")
    mass = float(np.average(masses, weights=weights))
    stderr = 1.0 / math.sqrt(sum(weights))
    if len(masses) > 1:
        stderr = max(stderr, float(np.std(masses, ddof=1)) / math.sqrt(len(masses)))
    basis = (f"M_v {with_uncertainty(mass, stderr)} kg, the mean of its fits to "
             f"{len(masses)} run(s), its error in the shifts'")
    return DiscMass(mass, stderr, basis)


def _kstar_of_fit(campaign: CampaignFile, run_name: str, frequency_hz: np.ndarray,
                  where: str) -> np.ndarray:
    """K* of the newest stored fit of the run whose model has a specimen."""
    for fit in reversed(campaign.fits(run_name)):
        model = parse_spec(fit.model)
        term = model.modulus_term
        if term is None or not term.has_disc:
            continue
        # K* needs the specimen's parameters only; the table's (held fixed) may not be stored
        values = {name: math.nan for name in model.names}
        values.update({name: p.value for name, p in fit.parameters.items()})
        kstar = np.asarray(model.kstar(Context(frequency_hz), values), dtype=complex)
        if np.isfinite(kstar).all():
            return kstar
    raise InputError("no stored fit of a specimen model to take K* from: identify the run "
                     "first (viscorig identify ... --model maxwell) or use the support FRF",
                     where)


def rig_modulus_table(campaign: CampaignFile, run_name: str,
                      disc_mass_kg: float | None = None,
                      kstar_source: str = "support") -> ModulusTable:
    """The shear modulus table of one rig run (one set).

    ``kstar_source`` is ``"support"`` (Eq. 5 from the support FRF) or ``"fit"`` (the newest
    stored fit's K*).

    Raises
    ------
    InputError
        What is missing, named: the support FRF (a bare-table run), the temperature, the disc
        mass, or the geometry factor.
    """
    where = f"{campaign.path}: /runs/{run_name}"
    run = campaign.run(run_name)
    theta = RigDescription.from_attributes(campaign.rig).theta
    if theta is None:
        raise InputError("the rig's geometry factor is unknown, so K* cannot become a modulus: "
                         "set /rig geometry_factor_m, or specimen_diameter_m and "
                         "specimen_height_m", f"{campaign.path}: /rig")
    if kstar_source not in ("support", "fit"):
        raise InputError(f"{kstar_source!r} is not support or fit", "--kstar")
    frequency = np.asarray(run.frequency_hz, dtype=float)
    support = np.asarray(run.accelerance_support)
    if kstar_source == "fit":
        kstar = _kstar_of_fit(campaign, run_name, frequency, where)
    else:
        if not np.isfinite(support).any():
            raise InputError("no support FRF (ẍ_v/F_v): a bare-table run has no K*", where)
        mass = disc_mass_kg if disc_mass_kg is not None else disc_mass_of(campaign, run_name)
        if mass is None:
            raise InputError("no disc mass M_v: identify the run first (viscorig identify ... "
                             "--model voigt) or give --disc-mass", where)
        kstar = kstar_from_support(frequency, support, mass)
    temperature = recorded_temperature_c(run, every_point=False)
    if temperature is None:
        temperature = np.full(frequency.size, run.metadata.temperature_c)
    if not np.isfinite(temperature).any():
        raise InputError("no temperature (the temperature_c attribute is NaN and there is no "
                         "per-point temperature_c dataset)", where)
    keep = (~run.flagged() & np.isfinite(kstar) & (kstar.real > 0) & (kstar.imag > 0)
            & np.isfinite(temperature) & (frequency > 0))
    if keep.sum() < 2:
        raise InputError(f"{int(keep.sum())} usable point(s) (unflagged, with K* of positive "
                         "real and imaginary part); a set needs two or more", where)
    return ModulusTable(
        frequency_hz=frequency[keep], temperature_c=temperature[keep],
        storage_pa=kstar.real[keep] / theta, loss_pa=kstar.imag[keep] / theta,
        set_index=np.zeros(int(keep.sum()), dtype=np.int64), modulus="G",
        source=run_name, set_names=(run_name,),
    )
