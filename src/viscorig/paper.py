"""The paper's published numbers (Tables 1 and 2, the table suspension) and their inconsistencies.

Source: Lépore Neto & dos Santos, as restated in ``shared/docs/physics.md``. Keys are the run
names of ``sequences/paper.toml``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

#: The table suspension identified by the paper (``M_s`` kg, ``K_s`` N/m, ``C_s`` N·s/m).
PAPER_TABLE_PARAMETERS = {"M_s": 3.4, "K_s": 50194.0, "C_s": 5.05}

#: Table 1, Voigt fit: run -> (K_v N/m, C_v N·s/m).
PAPER_TABLE_1 = {
    "soft-0": (149986.61, 114.59),
    "soft-10": (163948.13, 124.91),
    "medium-0": (244605.26, 144.48),
    "medium-10": (268906.82, 150.13),
    "hard-0": (980356.04, 107.37),
    "hard-10": (1104445.91, 102.72),
}

#: Table 2: run -> (f_r Hz, ξ, B_r Hz).
PAPER_TABLE_2 = {
    "soft-0": (39.50, 0.074, 5.846),
    "soft-10": (40.75, 0.077, 6.276),
    "medium-0": (47.39, 0.075, 7.109),
    "medium-10": (49.21, 0.075, 7.382),
    "hard-0": (79.47, 0.027, 4.291),
    "hard-10": (81.99, 0.027, 4.427),
}

PAPER_RUNS = ("table", *PAPER_TABLE_1)


def implied_mass_kg(run: str) -> float:
    """Total mass ``(K_s + K_v) / (2π f_r)²`` that the paper's own ``K_v`` and ``f_r`` imply."""
    k_v, _ = PAPER_TABLE_1[run]
    f_r = PAPER_TABLE_2[run][0]
    return (PAPER_TABLE_PARAMETERS["K_s"] + k_v) / (2 * math.pi * f_r) ** 2


def implied_damping_factor(run: str) -> float:
    """``ξ = (C_s + C_v) / (2 √((K_s + K_v) M))`` with the mass implied by ``f_r``."""
    k_v, c_v = PAPER_TABLE_1[run]
    stiffness = PAPER_TABLE_PARAMETERS["K_s"] + k_v
    return (PAPER_TABLE_PARAMETERS["C_s"] + c_v) / (2 * math.sqrt(stiffness * implied_mass_kg(run)))


def paper_values(run: str) -> dict[str, float] | None:
    """The paper's ``K_v, C_v, f_r, xi, B_r`` for a run of its campaign, else ``None``."""
    if run not in PAPER_TABLE_1:
        return None
    k_v, c_v = PAPER_TABLE_1[run]
    f_r, xi, b_r = PAPER_TABLE_2[run]
    return {"K_v": k_v, "C_v": c_v, "f_r": f_r, "xi": xi, "B_r": b_r}


def paper_variation(run: str, base: str) -> dict[str, float] | None:
    """The paper's own change from ``base`` to ``run`` in percent, or ``None``."""
    after, before = paper_values(run), paper_values(base)
    if after is None or before is None:
        return None
    return {name: 100.0 * (after[name] / before[name] - 1.0) for name in after}


def consistency_notes(runs: Iterable[str] | None = None) -> list[str]:
    """What does and does not hold among the paper's printed numbers, one line each.

    ``runs``: only these of the paper's runs are named (default all of them); the statements
    about the tables as a whole are kept.
    """
    named = [run for run in PAPER_TABLE_1 if runs is None or run in set(runs)]
    notes = []
    worst = max(abs(2 * xi * f_r - b_r) / b_r for f_r, xi, b_r in PAPER_TABLE_2.values())
    notes.append(f"B_r = 2·ξ·f_r holds to the printed digits (worst relative gap {worst:.1%}).")
    if named:
        masses = {run: implied_mass_kg(run) for run in named}
        negative = [run for run, mass in masses.items() if mass < PAPER_TABLE_PARAMETERS["M_s"]]
        notes.append(
            "mass implied by f_r and K_v, (K_s+K_v)/(2π f_r)²: "
            + ", ".join(f"{run} {mass:.2f} kg" for run, mass in masses.items())
            + f"; below M_s = {PAPER_TABLE_PARAMETERS['M_s']} kg (so M_v < 0) for "
            + (", ".join(negative) if negative else "none of these")
            + "."
        )
        gaps = [
            f"{run} {implied_damping_factor(run):.3f} vs {PAPER_TABLE_2[run][1]:.3f}"
            for run in named
        ]
        notes.append("ξ recomputed from (C_s+C_v)/(2√((K_s+K_v)M)) vs printed: " + "; ".join(gaps))
    notes.append(
        "Table 1 and Table 2 are therefore not fully self-consistent; "
        "the values printed beside ours are the paper's as published."
    )
    return notes
