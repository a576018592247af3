"""One rule pairs a preloaded run with its base, for the summary and the report alike."""

from __future__ import annotations

import math

from viscorig.identify import preload_pairs

# name, specimen, hardness, direction, preload strain, level m/s^2
RUNS = [
    ("soft-0-up", "soft", 25.0, "up", 0.0, 1.4),
    ("soft-0-down", "soft", 25.0, "down", 0.0, 1.4),
    ("soft-0-low", "soft", 25.0, "down", 0.0, 0.5),
    ("soft-10-down", "soft", 25.0, "down", 0.10, 0.6),
    ("hard-5", "hard", 60.0, "up", 0.05, 1.4),
    ("hard-10", "hard", 60.0, "up", 0.10, 1.4),
    ("other-10", "soft", 33.0, "up", 0.10, 1.4),
    ("unnamed-0", "medium", math.nan, "up", 0.0, 1.4),
    ("unnamed-10", "medium", math.nan, "up", 0.10, 1.4),
]


def test_each_preloaded_run_meets_its_least_preloaded_twin_of_the_same_direction_and_level():
    pairs = preload_pairs(RUNS, lambda r: r[1:])
    named = {other[0]: base[0] for base, other in pairs}
    assert named == {
        "soft-10-down": "soft-0-low",   # same direction, the level nearest its own
        "hard-10": "hard-5",            # least preloaded, not necessarily unloaded
        "unnamed-10": "unnamed-0",      # an unknown hardness matches an unknown hardness
    }                                   # other-10: no run of its hardness without more preload
