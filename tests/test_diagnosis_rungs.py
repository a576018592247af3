"""Each rung of a ladder is judged from its model's own optimum. A rung that adds the best
finding alone took that finding's fit, in which only the new term's parameters and the broad
ones had moved (the local modes held where the rung before left them): the last rung of every
preset's ladder stood 0.6 to 20.6 in χ² above the optimum of its own model, and the candidates
tested against it could claim that difference as theirs."""

from __future__ import annotations

import numpy as np
import pytest
from ladder_reference import TABLE, measured_run

from viscorig.diagnosis import diagnose
from viscorig.diagnosis.data import combine
from viscorig.diagnosis.weighted import ml_fit


@pytest.mark.parametrize("preset", ["hard-0"])
def test_every_rung_stands_at_the_optimum_of_its_model(preset: str) -> None:
    data = combine([(preset, measured_run(preset))], table=TABLE)
    with np.errstate(all="ignore"):
        ladder = diagnose(data, "voigt").auto()
        assert len(ladder) >= 3
        for rung in ladder[1:]:
            again = ml_fit(rung.likelihood.model, rung.data, rung.likelihood.values)
            assert rung.likelihood.chi2 - again.chi2 < 0.25, rung.model
