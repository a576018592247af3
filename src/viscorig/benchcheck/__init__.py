"""The one-minute station self-test a technician runs before a campaign (``viscorig bench
check``).

:mod:`viscorig.benchcheck.procedure` measures (identity and options; each input's range and
noise with the source off; a low-level sine at three frequencies at a fixed drive, then with the
level loop closed); :mod:`viscorig.benchcheck.checks` judges the readings against what the rig's
physics implies for each transducer's role and names what is wrong and what to do, one line per
check. The physics: below and above the table's resonance the table's equation of motion links
the excitation force, the device force and the table acceleration through the table's mass,
stiffness and damping; the disc accelerometer reads the table's motion through the stiff load
cell; the excitation force follows the source through the shaker's gain.
"""

from viscorig.benchcheck.checks import Readings, Verdict, assess
from viscorig.benchcheck.procedure import CheckSettings, measure

__all__ = ["CheckSettings", "Readings", "Verdict", "assess", "measure"]
