"""FE material cards: each card written by ``viscorig export --material`` is read back by a
parser written here (from the tools' documented layouts), evaluated at every measured point,
and compared with the data.

Each reader encodes the vendor's convention as its documentation states it; where the
documentation found does not settle a point, the reader says so and follows the card (the card
and ``docs/materials.md`` list those points as unconfirmed)."""

from __future__ import annotations

import math
import re

import materialdata as gen
import numpy as np
import pytest

from viscorig.cli import main
from viscorig.materials.dmastore import import_dma
from viscorig.materials.table import ModulusTable

TEMPERATURES = np.arange(-30.0, 71.0, 10.0)
FREQUENCIES = np.logspace(-1, 2, 10)
POISSON = 0.45


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    path = tmp_path_factory.mktemp("cards") / "dma.h5"
    data = gen.dma_sweep(TEMPERATURES, FREQUENCIES, seed=7)
    import_dma(path, "rubber", ModulusTable(**data, source="generated.csv"))
    return path, data


def _numbers(line: str) -> list[float]:
    return [float(v) for v in line.replace(",", " ").split()]


def _wlf(t, tref, c1, c2):
    return -c1 * (t - tref) / (c2 + t - tref)


def _abaqus(text: str):
    """Abaqus: one line ``g_i, k_i, tau_i`` per term after ``*VISCOELASTIC, TIME=PRONY``, ratios
    of the instantaneous moduli (Abaqus Keywords Reference, *VISCOELASTIC, TIME=PRONY data
    lines); ``*TRS, DEFINITION=WLF`` line ``theta0, C1, C2`` (Keywords Reference, *TRS) with
    ``log10 A = -C1 (T - theta0)/(C2 + T - theta0)`` and reduced time ``dtau/dt = 1/A`` (Abaqus
    Theory Guide, Viscoelasticity), so the reduced frequency is ``omega A``."""
    lines = [line for line in text.splitlines() if not line.startswith("**")]
    e0, nu = _numbers(lines[lines.index("*ELASTIC, MODULI=INSTANTANEOUS") + 1])
    start = lines.index("*VISCOELASTIC, TIME=PRONY") + 1
    terms = []
    for line in lines[start:]:
        if line.startswith("*"):
            break
        g, k, tau = _numbers(line)
        assert g == k
        terms.append((g, tau))
    tref, c1, c2 = _numbers(lines[lines.index("*TRS, DEFINITION=WLF") + 1])

    def young(f, t):
        w = 2 * np.pi * f * 10 ** _wlf(t, tref, c1, c2)
        return e0 * (1 - sum(g / (1 + 1j * w * tau) for g, tau in terms))
    return young, nu


def _ansys(text: str):
    """ANSYS: ``TB,PRONY,MAT,NTEMP,NPTS,SHEAR`` with NPTS terms (Command Reference, TB), data
    in TBDATA commands of up to six values (Command Reference, TBDATA). Not settled by the
    documentation found: the order ``a_i, tau_i`` of the pairs and the sign of the WLF shift,
    read here as the card writes them (``log10 A = +C1 (T - Tr)/(C2 + T - Tr)``, ``A``
    multiplying the time, so the reduced frequency is ``omega / A``)."""
    lines = [line for line in text.splitlines() if not line.startswith("!")]
    e0 = float(next(line for line in lines if line.startswith("MP,EX")).split(",")[-1])
    nu = float(next(line for line in lines if line.startswith("MP,PRXY")).split(",")[-1])
    shear = lines.index(next(line for line in lines if line.startswith("TB,PRONY")
                             and line.endswith("SHEAR")))
    count = int(lines[shear].split(",")[4])
    values = []
    for line in lines[shear + 1:]:
        if not line.startswith("TBDATA"):
            break
        values += [float(v) for v in line.split(",")[2:]]
    assert len(values) == 2 * count
    shift = lines[lines.index(next(line for line in lines if line.startswith("TB,SHIFT"))) + 1]
    tref, c1, c2 = (float(v) for v in shift.split(",")[2:])
    pairs = list(zip(values[::2], values[1::2], strict=True))

    def young(f, t):
        # ANSYS's shift A = 1/aT: log10 A = C1 (T - Tr)/(C2 + T - Tr)
        a = 10 ** (c1 * (t - tref) / (c2 + t - tref))
        w = 2 * np.pi * f / a
        return e0 * (1 - sum(alpha / (1 + 1j * w * tau) for alpha, tau in pairs))
    return young, nu


def _lsdyna(text: str):
    """LS-DYNA *MAT_GENERAL_VISCOELASTIC: card 1 ``MID RO BULK PCF EF TREF A B``, card 2 the
    relaxation-curve fit (``LCID ...``), then at most six cards ``GI BETAI KI BETAKI`` with
    ``G(t) = sum GI exp(-BETAI t)`` (LS-DYNA Keyword User's Manual, MAT_076, field by field as
    in Ansys's PyDyNA keyword classes). Not settled by the documentation found: the WLF form,
    read here as the card writes it (natural logarithm, ``ln aT = -A (T - TREF)/(B + T - TREF)``).
    """
    cards = [line for line in text.splitlines() if line and not line.startswith(("$", "*"))]
    tref, a, b = _numbers(cards[0])[5:8]
    terms = [_numbers(line) for line in cards[2:]]

    def shear(f, t):
        # WLF written with the natural logarithm: ln aT = -A (T - TREF)/(B + T - TREF)
        at = math.e ** (-a * (t - tref) / (b + t - tref))
        w = 2 * np.pi * f * at
        return sum(g * (1j * w) / (beta + 1j * w) for g, beta, _, _ in terms)
    return shear, terms


def _rms(model, measured):
    return (float(np.sqrt(np.mean(np.log(model.real / measured["storage_pa"]) ** 2))),
            float(np.sqrt(np.mean(np.log(model.imag / measured["loss_pa"]) ** 2))))


def _stated(text: str, which: str = "this card") -> tuple[float, float]:
    line = next(line for line in text.splitlines() if which in line)
    found = re.search(r"storage ([0-9.]+), loss ([0-9.]+)", line)
    return float(found.group(1)), float(found.group(2))


def _export(path, kind, out, capsys):
    assert main(["export", str(path), "--run", "rubber", "--material", kind, "--out", str(out),
                 "--poisson-ratio", str(POISSON), "--reference-temperature", "20"]) == 0
    capsys.readouterr()
    return out.read_text()


@pytest.mark.parametrize("kind", ["abaqus", "ansys"])
def test_abaqus_and_ansys_cards_reproduce_the_data(campaign, tmp_path, capsys, kind):
    path, data = campaign
    text = _export(path, kind, tmp_path / f"card.{kind}", capsys)
    young, nu = (_abaqus if kind == "abaqus" else _ansys)(text)
    assert nu == POISSON
    storage, loss = _rms(young(data["frequency_hz"], data["temperature_c"]), data)
    assert storage <= 0.05 and loss <= 0.12
    stated = _stated(text)
    assert storage == pytest.approx(stated[0], abs=2e-3)
    assert loss == pytest.approx(stated[1], abs=2e-3)
    assert "reference temperature: 20.0000 C" in text


def test_lsdyna_card_reproduces_the_error_it_states(campaign, tmp_path, capsys):
    path, data = campaign
    text = _export(path, "lsdyna", tmp_path / "card.k", capsys)
    shear, terms = _lsdyna(text)
    # MAT_076 reads at most six GI cards: the long-term term (BETAI = 0), then at most five
    assert len(terms) <= 6 and terms[0][1] == 0.0
    assert "UNCONFIRMED: the WLF form" in text
    # shear and bulk series share their relative terms (constant Poisson's ratio)
    ratios = [k / g for g, _, k, _ in terms]
    assert np.allclose(ratios, 2 * (1 + POISSON) / (3 * (1 - 2 * POISSON)))
    young = 2 * (1 + POISSON) * shear(data["frequency_hz"], data["temperature_c"])
    storage, loss = _rms(young, data)
    stated = _stated(text)
    assert storage == pytest.approx(stated[0], abs=2e-3)
    assert loss == pytest.approx(stated[1], abs=2e-3)


def test_export_material_refuses_bad_values_in_one_line(campaign, tmp_path, capsys):
    path, _ = campaign
    out = tmp_path / "x.inp"
    assert main(["export", str(path), "--run", "rubber", "--material", "abaqus", "--out",
                 str(out), "--poisson-ratio", "0.5"]) == 2
    err = capsys.readouterr().err
    assert "--poisson-ratio" in err and err.count("\n") == 1 and not out.exists()


def test_lsdyna_card_refuses_a_reference_temperature_mat076_cannot_take(campaign, tmp_path,
                                                                        capsys):
    path, _ = campaign
    out = tmp_path / "cold.k"
    code = main(["export", str(path), "--run", "rubber", "--material", "lsdyna", "--out",
                 str(out), "--reference-temperature", "-10"])
    err = capsys.readouterr().err
    assert code == 2 and "TREF > 0" in err and "--reference-temperature" in err
    assert err.count("\n") == 1 and not out.exists()


@pytest.mark.parametrize("kind", ["abaqus", "ansys", "lsdyna"])
def test_every_card_names_its_conventions(campaign, tmp_path, capsys, kind):
    path, _ = campaign
    text = _export(path, kind, tmp_path / f"conv.{kind}", capsys)
    conventions = [line for line in text.splitlines() if "convention:" in line]
    assert conventions and all(line[0] in "*!$" for line in conventions)


def _independent_prony(omega, storage, loss, terms, starts=8, seed=3):
    """Best series of ``terms`` Maxwell terms and a long-term modulus for ``ln`` errors of E'
    and E'' weighted alike: a least-squares fit written here from several seeded starts."""
    from scipy.optimize import least_squares

    def model(p):
        q = np.clip(p, -200.0, 200.0)
        iwt = 1j * omega[:, None] * np.exp(q[terms + 1:])
        return np.exp(q[0]) + (np.exp(q[1:terms + 1]) * iwt / (1 + iwt)).sum(axis=1)

    def residual(p):
        value = model(p)
        return np.concatenate([np.log(value.real / storage), np.log(value.imag / loss)])

    rng = np.random.default_rng(seed)
    best = None
    for k in range(starts):
        tau = np.geomspace(1 / omega.max(), 1 / omega.min(), terms) * np.exp(
            rng.normal(0.0, 1.0 if k else 0.0, terms))
        start = np.concatenate([[np.log(storage.min())],
                                np.full(terms, np.log(storage.max() / terms)), np.log(tau)])
        found = least_squares(residual, start, method="lm", max_nfev=400 * start.size)
        if best is None or found.cost < best.cost:
            best = found
    value = model(best.x)
    return (float(np.sqrt(np.mean(np.log(value.real / storage) ** 2))),
            float(np.sqrt(np.mean(np.log(value.imag / loss) ** 2))))


@pytest.mark.slow
def test_lsdyna_card_holds_the_best_series_its_six_cards_allow(campaign, tmp_path, capsys):
    path, data = campaign
    text = _export(path, "lsdyna", tmp_path / "card.k", capsys)
    shear, terms = _lsdyna(text)
    assert len(terms) == 6 and terms[0][1] == 0.0
    young = 2 * (1 + POISSON) * shear(data["frequency_hz"], data["temperature_c"])
    card = _rms(young, data)
    # the same reduced frequencies as the card: its own WLF shift, read back from it
    tref, a, b = _numbers(next(line for line in text.splitlines()
                               if line and not line.startswith(("$", "*"))))[5:8]
    t = data["temperature_c"]
    omega = 2 * np.pi * data["frequency_hz"] * np.exp(-a * (t - tref) / (b + t - tref))
    fresh = _independent_prony(omega, data["storage_pa"], data["loss_pa"], len(terms) - 1)
    # no fresh fit of as many terms beats the card on both moduli, and its combined error
    # is within 10 % of the fresh fit's (which weights E' and E'' alike, the card by scatter)
    assert not (fresh[0] < card[0] - 0.01 and fresh[1] < card[1] - 0.01), (card, fresh)
    assert math.hypot(*card) <= 1.10 * math.hypot(*fresh), (card, fresh)
    # the master's own series is longer than the cards hold; keeping its five largest terms
    # instead of refitting leaves rms ln errors of 1.37 (E') and 3.21 (E'') on this material
    master = [int(v) for v in re.findall(r"Prony series: (\d+) terms", text)]
    assert master and master[0] > 5
    assert card[0] < 0.3 and card[1] < 0.7


def test_a_card_from_reduced_moduli_states_its_error_against_the_measured_ones(tmp_path, capsys):
    """With --vertical-shift ferry the card (which holds no vertical factor) is read back and
    compared with the measured moduli: the error it states is that one, and it says why."""
    path = tmp_path / "entropic.h5"
    data = gen.dma_sweep(TEMPERATURES, FREQUENCIES, seed=8, entropic=True)
    import_dma(path, "rubber", ModulusTable(**data, source="entropic.csv"))
    out = tmp_path / "card.inp"
    assert main(["export", str(path), "--run", "rubber", "--material", "abaqus", "--out",
                 str(out), "--poisson-ratio", str(POISSON), "--reference-temperature", "20",
                 "--vertical-shift", "ferry"]) == 0
    capsys.readouterr()
    text = out.read_text()
    young, _ = _abaqus(text)
    storage, loss = _rms(young(data["frequency_hz"], data["temperature_c"]), data)
    stated = _stated(text)
    assert storage == pytest.approx(stated[0], abs=2e-3)
    assert loss == pytest.approx(stated[1], abs=2e-3)
    assert "this card carries no vertical shift" in text
    # the T/T_ref the card leaves out is in that error: 0.082 in ln at -30 °C, 0.15 at 70 °C
    assert storage > 0.04
