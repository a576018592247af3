"""Material models over temperature and frequency: DMA data, master curves by time-temperature
superposition, shift functions, Prony series, consistency checks and FE material cards.

Small modules, one job each:

- :mod:`~viscorig.materials.table`: the data (a modulus table);
- :mod:`~viscorig.materials.dmafile`: reading DMA CSV tables;
- :mod:`~viscorig.materials.dmastore`: DMA runs in a campaign file (``/dma``);
- :mod:`~viscorig.materials.rigdata`: shear moduli from rig runs;
- :mod:`~viscorig.materials.sources`: the table of named runs;
- :mod:`~viscorig.materials.shift`: shift factors (spline master curve);
- :mod:`~viscorig.materials.shiftfunctions`: WLF, Arrhenius;
- :mod:`~viscorig.materials.vertical`: Ferry's vertical shift factor;
- :mod:`~viscorig.materials.prony`: Prony series and the fractional model;
- :mod:`~viscorig.materials.joint`: shifts refined together with the Prony series;
- :mod:`~viscorig.materials.kkcheck`: Kramers-Kronig check;
- :mod:`~viscorig.materials.superposition`: does superposition hold (van Gurp-Palmen);
- :mod:`~viscorig.materials.master`: all of it, as one result;
- :mod:`~viscorig.materials.fecards`: Abaqus, ANSYS and LS-DYNA cards.
"""
