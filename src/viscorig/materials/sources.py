"""The modulus table of named runs of a campaign file: DMA runs (``/dma``) or rig runs
(``/runs``), several rig runs of one specimen making one table."""

from __future__ import annotations

from dataclasses import replace

from viscorig.errors import InputError
from viscorig.materials.dmastore import dma_run_names, read_dma
from viscorig.materials.rigdata import disc_mass_of, identified_disc_mass, rig_modulus_table
from viscorig.materials.table import ModulusTable, concatenate
from viscorig.storage import CampaignFile


def modulus_table(campaign: CampaignFile, runs: list[str], disc_mass_kg: float | None = None,
                  kstar_source: str = "support") -> ModulusTable:
    """One table of the named runs (see the module text).

    Raises
    ------
    InputError
        No runs, a name that is neither a run nor a DMA run, a run named twice, or a run that
        cannot give a modulus (what is missing is named).
    """
    if not runs:
        raise InputError("no run given", "--run")
    if len(set(runs)) != len(runs):
        raise InputError("a run is named twice", "--run")
    dma, rig = set(dma_run_names(campaign)), set(campaign.run_names)
    basis = ""
    unidentified = [name for name in runs if name in rig and name not in dma
                    and disc_mass_of(campaign, name) is None]
    shared = disc_mass_kg
    if disc_mass_kg is None and kstar_source == "support" and unidentified:
        shared, basis = identified_disc_mass(campaign, unidentified)
    tables = []
    for name in runs:
        if name in dma:
            tables.append(read_dma(campaign, name))
        elif name in rig:
            mass = disc_mass_kg if disc_mass_kg is not None or name not in unidentified \
                else shared
            tables.append(rig_modulus_table(campaign, name, mass, kstar_source))
        else:
            known = ", ".join(sorted(dma | rig)) or "none"
            raise InputError(f"no such run (runs: {known})", f"{campaign.path}: {name}")
    if len(tables) == 1:
        table = tables[0]
    else:
        table = concatenate(tables, source=f"{campaign.path.name}: {', '.join(runs)}")
    return replace(table, source=f"{table.source} ({basis})") if basis else table
