"""The 35670A's limits that the core plans and checks against, in one place.

From the analyser's programming guide (swept-sine option 1D2, four channels). The driver
(``agilent35670a``) and the simulator (``rigsim``) keep their own copies: the core imports
neither, and the simulator shares no code with the core.
"""

from __future__ import annotations

import math

#: The source sets swept-sine frequencies in steps of 15.625 mHz (rounded down to a step).
FREQUENCY_STEP_HZ = 0.015625
#: Lowest four-channel swept-sine frequency, Hz.
MIN_FREQUENCY_HZ = 0.03125
#: Highest four-channel swept-sine frequency, Hz.
MAX_FREQUENCY_HZ = 25600.0
#: Most points of one linear sweep (402-801 measured points display as 801).
ANALYSER_MAX_POINTS = 801
#: ``SWE:DWEL`` (integration) range, in cycles as printed.
MIN_INTEGRATE_CYCLES = 1
MAX_INTEGRATE_CYCLES = 234
#: The analyser's highest source output, V peak.
ANALYSER_SOURCE_MAX_V = 5.0
#: Lowest auto-level reference level, V peak (``SOUR:VOLT:REF``: -69.276 dBVrms, option 1D2):
#: with a 10.2 mV/(m/s²) accelerometer, 0.048 m/s².
MIN_REFERENCE_VPK = math.sqrt(2.0) * 10 ** (-69.276 / 20)
