"""The 35670A's identity and the ranges its settings may take (swept-sine option 1D2)."""

from __future__ import annotations

__all__ = [
    "DEFAULT_IDN",
    "DEFAULT_OPTIONS",
    "FREQUENCY_STEP_HZ",
    "MAX_CYCLES",
    "MAX_FREQUENCY_2CH_HZ",
    "MAX_FREQUENCY_4CH_HZ",
    "MAX_POINTS",
    "MAX_SOURCE_VPK",
    "MIN_DWELL_S",
    "MIN_POINTS",
]

#: ``*IDN?`` answer. The vendor string differs by era; ours says where it comes from.
DEFAULT_IDN = "Agilent Technologies,35670A,RIGSIM0001,A.02.02"
#: Installed options: 1D2 swept sine, AY6 four channels.
DEFAULT_OPTIONS: tuple[str, ...] = ("1D2", "AY6")
#: Points per swept-sine sweep (inferred from the display table: 402-801 points show as 801).
MAX_POINTS = 801
MIN_POINTS = 2  # (inferred)
#: Source and frequency resolution of the swept sine.
FREQUENCY_STEP_HZ = 0.015625
MAX_FREQUENCY_2CH_HZ = 51200.0
MAX_FREQUENCY_4CH_HZ = 25600.0
MAX_SOURCE_VPK = 5.0
MIN_DWELL_S = 250e-6
MAX_CYCLES = 1.0e6  # the manual's upper cycle limit is illegible (inferred)
