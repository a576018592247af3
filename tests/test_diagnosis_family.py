"""Which of two K* terms a diagnosis keeps: an alternative replaces a candidate's term only when
the data clearly prefer it by the Bayesian criterion, a difference of ``χ²`` counted in units of
the misfit ``φ`` as every test of the diagnosis counts it (far from the noise, a raw difference
of a thousand is ten ``φ``)."""

from types import SimpleNamespace

from viscorig.diagnosis.findings import clearly_better

#: 400 complex points of two FRFs, worth 800 independent observations.
DATA = SimpleNamespace(residual_count=1600, effective_points=800.0)
THRESHOLD = 16.0


def fitted(chi2: float, parameters: int) -> SimpleNamespace:
    return SimpleNamespace(chi2=chi2, free=tuple(f"p{i}" for i in range(parameters)))


def test_far_from_the_noise_a_difference_counts_in_units_of_the_misfit():
    first = fitted(160_000.0, 6)  # φ about 100
    assert not clearly_better(fitted(159_000.0, 6), first, THRESHOLD, DATA)  # 10 φ
    assert clearly_better(fitted(157_000.0, 6), first, THRESHOLD, DATA)  # 30 φ


def test_at_the_noise_the_plain_difference_counts():
    first = fitted(1_610.0, 6)  # φ = 1
    assert clearly_better(fitted(1_590.0, 6), first, THRESHOLD, DATA)
    assert not clearly_better(fitted(1_600.0, 6), first, THRESHOLD, DATA)


def test_a_parameter_more_pays_its_log_n():
    first = fitted(1_610.0, 6)
    assert clearly_better(fitted(1_600.0, 7), first, 0.0, DATA)  # 10 > ln 800 = 6.7
    assert not clearly_better(fitted(1_605.0, 7), first, 0.0, DATA)  # 5 < 6.7
