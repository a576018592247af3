"""The modulus table of named runs of a campaign file: DMA runs (``/dma``) or rig runs
(``/runs``), several rig runs of one specimen making one table; and their master curve.

Rig runs never identified take the disc's mass ``M_v`` from fits of the runs
(:func:`~viscorig.materials.rigdata.identified_disc_mass`); its standard error is carried into
the shift factors' covariance (the table one standard error of ``M_v`` up, its shifts' change
taken as a systematic error common to every shift)."""

from __future__ import annotations

from dataclasses import replace

from viscorig.errors import InputError
from viscorig.materials.dmastore import dma_run_names, read_dma
from viscorig.materials.master import MasterCurve, build_master
from viscorig.materials.rigdata import disc_mass_of, identified_disc_mass, rig_modulus_table
from viscorig.materials.table import ModulusTable, concatenate
from viscorig.storage import CampaignFile


def master_curve(campaign: CampaignFile, runs: list[str], reference_temperature_c: float | None
                 = None, disc_mass_kg: float | None = None,
                 kstar_source: str = "support", vertical: str = "none",
                 expansion_per_k: float = 0.0) -> MasterCurve:
    """The master curve of the named runs (``viscorig master``), with the identified disc
    mass's error in the shifts' (see the module text); ``vertical`` and ``expansion_per_k`` as
    :func:`~viscorig.materials.master.build_master` takes them.

    Raises
    ------
    InputError
        No runs, a name that is neither a run nor a DMA run, a run named twice, a run that
        cannot give a modulus (what is missing is named), or as
        :func:`~viscorig.materials.master.build_master`.
    """
    table, perturbed = _tables(campaign, runs, disc_mass_kg, kstar_source)
    return build_master(table, tuple(runs), reference_temperature_c, systematic=perturbed,
                        vertical=vertical, expansion_per_k=expansion_per_k)


def _tables(campaign: CampaignFile, runs: list[str], disc_mass_kg: float | None,
            kstar_source: str) -> tuple[ModulusTable, ModulusTable | None]:
    """The table, and the same with an identified ``M_v`` one standard error up (or None)."""
    if not runs:
        raise InputError("no run given", "--run")
    if len(set(runs)) != len(runs):
        raise InputError("a run is named twice", "--run")
    dma, rig = set(dma_run_names(campaign)), set(campaign.run_names)
    unknown = [name for name in runs if name not in dma | rig]
    if unknown:
        known = ", ".join(sorted(dma | rig)) or "none"
        raise InputError(f"no such run (runs: {known})", f"{campaign.path}: {unknown[0]}")
    unidentified = [name for name in runs if name in rig and name not in dma
                    and disc_mass_of(campaign, name) is None]
    if disc_mass_kg is not None or kstar_source != "support" or not unidentified:
        return _joined(campaign, runs, dma, {}, disc_mass_kg, kstar_source), None
    mass = identified_disc_mass(campaign, unidentified)
    table = _joined(campaign, runs, dma, dict.fromkeys(unidentified, mass.value), None,
                    kstar_source)
    up = _joined(campaign, runs, dma, dict.fromkeys(unidentified, mass.value + mass.stderr),
                 None, kstar_source)
    return replace(table, source=f"{table.source} ({mass.basis})"), up


def _joined(campaign: CampaignFile, runs: list[str], dma: set[str], masses: dict[str, float],
            disc_mass_kg: float | None, kstar_source: str) -> ModulusTable:
    tables = [read_dma(campaign, name) if name in dma else
              rig_modulus_table(campaign, name, masses.get(name, disc_mass_kg), kstar_source)
              for name in runs]
    if len(tables) == 1:
        return tables[0]
    return concatenate(tables, source=f"{campaign.path.name}: {', '.join(runs)}")
