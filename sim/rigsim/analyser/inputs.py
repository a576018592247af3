"""The analyser's inputs as the measurements see them: which are on, ranges, engineering units.

The settings live in the :class:`~rigsim.analyser.settings.SettingStore` (declared in
:mod:`rigsim.analyser.commands.inputs`); this module reads them for the measurements.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigsim.analyser.settings import SettingStore
from rigsim.analyser.units import Level
from rigsim.measurement import INPUT_RANGES_DBVRMS

__all__ = ["CHANNELS", "InputView", "range_step_dbvrms", "snap_range_dbvrms"]

CHANNELS = 4


def snap_range_dbvrms(value_dbvrms: float) -> float:
    """The input range at or above a level (ranges not allowed round up, chapter 18)."""
    candidates = INPUT_RANGES_DBVRMS[value_dbvrms - 1e-9 <= INPUT_RANGES_DBVRMS]
    return float(candidates[-1]) if candidates.size else float(INPUT_RANGES_DBVRMS[0])


def range_step_dbvrms(value_dbvrms: float, steps: int) -> float:
    """The range ``steps`` 2 dB steps above (or below) a range, within +27..-51 dBVrms."""
    return float(min(27.0, max(-51.0, snap_range_dbvrms(value_dbvrms) + 2.0 * steps)))


@dataclass
class InputView:
    """Read access to the input settings.

    Parameters
    ----------
    store
        The instrument's settings.
    """

    store: SettingStore

    def enabled(self, channel: int) -> bool:
        """The input is on (channel 1 always is)."""
        return channel == 1 or bool(self.store.get("inp.state", (channel,)))

    def count(self) -> int:
        """Channels in use: 4 when input 3 or 4 is on, 2 when input 2 is, else 1."""
        if self.enabled(3) or self.enabled(4):
            return 4
        return 2 if self.enabled(2) else 1

    def active(self) -> list[int]:
        """The inputs in use (1, 1-2 or 1-4)."""
        return list(range(1, self.count() + 1))

    def v_per_eu(self, channel: int) -> float | None:
        """Volts per engineering unit when the input is in engineering units, else ``None``."""
        if not self.store.get("volt.user", (channel,)):
            return None
        sfac = float(self.store.get("volt.sfac", (channel,)))
        return sfac if sfac != 0 else None

    def scale(self) -> np.ndarray:
        """Volts per displayed unit of each input (1 when in volts)."""
        return np.array([self.v_per_eu(n) or 1.0 for n in range(1, CHANNELS + 1)])

    def label(self, channel: int) -> str:
        """The unit label of an input's data (``V`` when not in engineering units)."""
        if not self.store.get("volt.user", (channel,)):
            return "V"
        label = str(self.store.get("volt.xdcr", (channel,)))
        return str(self.store.get("volt.user.label", (channel,))) if label == "USER" else label

    def autorange(self, channel: int) -> bool:
        """Autorange is on."""
        return bool(self.store.get("volt.auto", (channel,)))

    def range_dbvrms(self, channel: int) -> float:
        """The range set (or last chosen by autorange), dBVrms."""
        level: Level = self.store.get("volt.range", (channel,))
        return 20.0 * math.log10(level.vpk / math.sqrt(2.0))

    def set_range_dbvrms(self, channel: int, value_dbvrms: float) -> None:
        """Record the range autorange chose (kept in the unit last set)."""
        current: Level = self.store.get("volt.range", (channel,))
        vpk = math.sqrt(2.0) * 10.0 ** (snap_range_dbvrms(value_dbvrms) / 20.0)
        self.store.set("volt.range", Level(vpk, current.unit), (channel,))
