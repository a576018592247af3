"""Material models over temperature and frequency: DMA data, master curves by time-temperature
superposition, shift functions, Prony series, consistency checks and FE material cards.

Small modules, one job each: :mod:`~viscorig.materials.table` (the data),
:mod:`~viscorig.materials.dmafile` (reading DMA CSV tables), :mod:`~viscorig.materials.dmastore`
(DMA runs in a campaign file), :mod:`~viscorig.materials.rigdata` (moduli from rig runs),
:mod:`~viscorig.materials.shift` (shift factors), :mod:`~viscorig.materials.shiftfunctions`
(WLF, Arrhenius), :mod:`~viscorig.materials.prony` (Prony and fractional models),
:mod:`~viscorig.materials.kkcheck` (Kramers-Kronig check),
:mod:`~viscorig.materials.superposition` (does superposition hold),
:mod:`~viscorig.materials.master` (all of it, as one result) and
:mod:`~viscorig.materials.fecards` (Abaqus, ANSYS, LS-DYNA cards).
"""
