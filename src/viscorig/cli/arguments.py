"""Parsers of command-line values shared by several commands."""

from __future__ import annotations

import argparse
import math

from viscorig.errors import InputError
from viscorig.executor import default_jobs
from viscorig.materials.vertical import VERTICAL_SHIFTS


def positive_number(text: str) -> float:
    """An ``argparse`` type: a number above zero."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


def _integer(text: str, noun: str = "a whole number") -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {noun}, got {text!r}") from None


def positive_int(text: str) -> int:
    """An ``argparse`` type: a whole number of at least 1."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


#: Simulated seconds per wall-clock second ``--sim-pace`` may ask for: a thousand times slower
#: than real time (a paper campaign would take four months) to as fast as the computer allows.
SIM_PACE_RANGE = (1e-3, 1e9)


def sim_pace(text: str) -> float:
    """An ``argparse`` type: the simulated rig's pace, within :data:`SIM_PACE_RANGE`."""
    value = positive_number(text)
    low, high = SIM_PACE_RANGE
    if not low <= value <= high:
        raise argparse.ArgumentTypeError(f"must be {low:g} to {high:g} simulated seconds per "
                                         f"second, got {text}")
    return value


def seed(text: str) -> int:
    """An ``argparse`` type: a seed of the simulated rig's noise, 0 to 2**63 − 1."""
    value = _integer(text)
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"must be 0 to 2**63 - 1, got {text}")
    return value


#: Worker processes per core that ``--jobs`` may ask for: the fits are CPU-bound, so more run
#: no faster, and local workers are forked all at once (a mistyped 99999 forked for minutes).
JOBS_PER_CORE = 4


def job_count(text: str) -> int:
    """An ``argparse`` type: worker processes, 1 to :data:`JOBS_PER_CORE` per core."""
    value = positive_int(text)
    most = JOBS_PER_CORE * default_jobs()
    if value > most:
        raise argparse.ArgumentTypeError(
            f"at most {most} ({JOBS_PER_CORE} per core of this machine), got {text}")
    return value


def port_number(text: str) -> int:
    """An ``argparse`` type: a TCP port, 0 for any free one."""
    port = _integer(text, "a port number")
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"must be 0-65535, got {port}")
    return port


def parse_band(text: str | None) -> tuple[float, float] | None:
    """``"LO:HI"`` in Hz -> ``(lo, hi)``; :class:`InputError` naming the value when malformed."""
    if text is None:
        return None
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        lo, hi = float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"'{text}' is not LO:HI in Hz (for example 20:120)", "--band") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise InputError(f"'{text}' needs 0 <= LO < HI", "--band")
    return lo, hi


def add_vertical_shift(parser: argparse.ArgumentParser, prefix: str = "") -> None:
    """The ``--vertical-shift`` and ``--thermal-expansion`` options of a master curve
    (``prefix`` opens their help: "with --material: ")."""
    parser.add_argument("--vertical-shift", choices=VERTICAL_SHIFTS, default="none",
                        help=f"{prefix}ferry: reduce the moduli by b_T = T_ref rho_ref/(T rho) "
                        "before shifting, as an entropic network's modulus grows with absolute "
                        "temperature (rubbery plateau, melts); default none")
    parser.add_argument("--thermal-expansion", type=float, default=0.0, metavar="PER_K",
                        help=f"{prefix}with --vertical-shift ferry: volumetric thermal "
                        "expansion of the density in b_T, 1/K (rubbers about 6.6e-4); default 0, "
                        "the density constant")
