"""DMA runs in a campaign file: ``/dma/<name>``, a run of its own kind beside ``/runs``.

Layout (an extension of data-format.md, documented in ``docs/materials.md``)::

    /dma/<name>           attrs: kind = "dma", modulus ("E" | "G"), source (file name),
                                 created (ISO 8601 UTC), points
      frequency_hz        float64, units "Hz"
      temperature_c       float64, units "degC"
      storage_modulus_pa  float64, units "Pa"
      loss_modulus_pa     float64, units "Pa"
      set_index           int64,   units "1" (the isothermal sweep of each point)

A DMA run's name must not be a name of ``/runs`` and the reverse, so ``--run NAME`` names one
thing. Readers of ``/runs`` never see a DMA run; readers that do not know ``/dma`` ignore it.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from viscorig.errors import InputError
from viscorig.materials.table import ModulusTable
from viscorig.storage import CampaignFile, layout, reading, untrusted
from viscorig.storage.campaign import campaign_for_import, check_name, utc_now

#: dataset name -> (table attribute, units, dtype)
COLUMNS = {
    "frequency_hz": ("frequency_hz", "Hz", np.float64),
    "temperature_c": ("temperature_c", "degC", np.float64),
    "storage_modulus_pa": ("storage_pa", "Pa", np.float64),
    "loss_modulus_pa": ("loss_pa", "Pa", np.float64),
    "set_index": ("set_index", "1", np.int64),
}
TEMPERATURE_UNITS = {"degC", "°C", "C", "celsius"}


def import_dma(campaign_path: Path, name: str, table: ModulusTable,
               specimen: str | None = None) -> int:
    """Store ``table`` as DMA run ``name`` (the campaign file is created when missing), with
    the name of its ``specimen`` when given (the DMA runs of one specimen, one per temperature,
    make one master curve in the report).

    Returns
    -------
    int
        Points stored.

    Raises
    ------
    InputError
        Bad name, a run or DMA run of that name exists, or the file cannot be written.
    """
    check_name(name, "--run")
    table.check(table.source or "DMA table")
    path = Path(campaign_path)
    with campaign_for_import(path, name) as campaign, campaign.commit() as h5:
        group = h5.require_group(layout.DMA_GROUP)
        if name in group:
            raise InputError("DMA run exists; imports never overwrite a run",
                             f"{path}: /{layout.DMA_GROUP}/{name}")
        run = group.create_group(name)
        run.attrs.update({"kind": "dma", "modulus": table.modulus,
                          "source": table.source[:200], "created": utc_now(),
                          "points": np.int64(table.points)})
        if specimen is not None:
            run.attrs["specimen"] = specimen[:200]
        for dataset, (attribute, units, dtype) in COLUMNS.items():
            values = np.asarray(getattr(table, attribute), dtype=dtype)
            run.create_dataset(dataset, data=values).attrs["units"] = units
    return table.points


def dma_specimen(campaign: CampaignFile, name: str) -> str | None:
    """The specimen DMA run ``name`` was imported for, or ``None`` where none was named."""
    path = campaign.path
    with campaign.reading() as h5, reading.guarded(path, f"/{layout.DMA_GROUP}/{name}"):
        run = h5[layout.DMA_GROUP][name]
        if not isinstance(run, h5py.Group) or "specimen" not in run.attrs:
            return None
        return str(reading.text_attribute(run, "specimen", path))


def dma_run_names(campaign: CampaignFile) -> list[str]:
    """Names of the DMA runs of a campaign file ([] when it has none)."""
    with campaign.reading() as h5, reading.guarded(campaign.path, f"/{layout.DMA_GROUP}"):
        untrusted.check_link(h5, layout.DMA_GROUP, campaign.path)
        group = h5.get(layout.DMA_GROUP)
        if group is None:
            return []
        if not isinstance(group, h5py.Group):
            raise InputError("not a group", f"{campaign.path}: /{layout.DMA_GROUP}")
        names = untrusted.members(group, campaign.path, layout.MAX_RUNS)
        for name in names:
            untrusted.check_stored_name(name, campaign.path, f"/{layout.DMA_GROUP}", "DMA run")
        return names


def read_dma(campaign: CampaignFile, name: str) -> ModulusTable:
    """DMA run ``name`` as a :class:`ModulusTable`, every object checked before it is read."""
    path = campaign.path
    where = f"{path}: /{layout.DMA_GROUP}/{name}"
    if name not in dma_run_names(campaign):
        raise InputError("no such DMA run", where)
    with campaign.reading() as h5, reading.guarded(path, f"/{layout.DMA_GROUP}/{name}"):
        group = h5[layout.DMA_GROUP]
        untrusted.check_link(group, name, path)
        run = group[name]
        if not isinstance(run, h5py.Group):
            raise InputError("not a group", where)
        modulus = reading.text_attribute(run, "modulus", path)
        values = {}
        lengths = set()
        for dataset, (attribute, units, _) in COLUMNS.items():
            untrusted.check_link(run, dataset, path)
            item = run.get(dataset)
            if not isinstance(item, h5py.Dataset):
                raise InputError("dataset missing", f"{where}/{dataset}")
            lengths.add(untrusted.check_values_dataset(item, path))
            found = reading.attribute(item, "units", path)
            good = found in TEMPERATURE_UNITS if units == "degC" else \
                layout.unit_matches(units, str(found))
            if not good:
                raise InputError(f"units {found!r}, expected {units!r}", f"{where}/{dataset}")
            if untrusted.number_kind(item.dtype) not in ("real", "integer"):
                raise InputError(f"dtype {item.dtype} is not a real number", f"{where}/{dataset}")
            values[attribute] = item[()].astype(np.int64 if attribute == "set_index"
                                                else np.float64)
        if len(lengths) != 1:
            raise InputError("datasets differ in length", where)
        source = reading.attribute(run, "source", path)
    table = ModulusTable(modulus=modulus, source=f"{path.name}:{name}" if not source
                         else f"{source}", **values)
    table.check(where)
    return table
