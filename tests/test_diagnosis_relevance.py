"""A significant finding must also matter: it removes a real share of the excess error."""

from __future__ import annotations

from viscorig.diagnosis.findings import MIN_EXCESS_FRACTION, removes_enough


def test_a_sliver_of_the_excess_is_not_enough() -> None:
    # 1.29x the floor, improved by 0.4 %: the spurious drift step seen on a hard rubber
    assert not removes_enough(1.833e-4, 1.825e-4, 1.425e-4)


def test_a_real_effect_removes_most_of_the_excess() -> None:
    assert removes_enough(8.356e-2, 2.349e-2, 1.425e-4)


def test_nothing_is_left_to_remove_at_the_floor() -> None:
    assert not removes_enough(1.0e-3, 0.5e-3, 1.0e-3)


def test_threshold_is_a_share_of_the_excess_variance() -> None:
    floor, before = 1.0, 2.0  # excess variance 3
    just_enough = (before**2 - MIN_EXCESS_FRACTION * 3.0) ** 0.5
    assert removes_enough(before, just_enough * 0.999, floor)
    assert not removes_enough(before, just_enough * 1.001, floor)
