"""``viscorig identify FILE --run RUN --model SPEC [--band LO:HI] [--frf WHICH] [--json]``.

Fits a model to one run and stores the fit in the campaign file (``--no-store`` to leave the
file untouched). Without ``--model``, a bare-table run gets ``table`` and a specimen run
``voigt``. Without ``--frf``, every FRF the model predicts and the run has is fitted. Each point
is weighted by its noise (the project's estimate); ``--weights uniform`` weighs every point the
same, as the paper does.

Several runs with ``--model kraus`` (``--run A --run B --run C``): the strain-amplitude
dependence (Payne effect) of one specimen from its runs at several levels
(:func:`viscorig.strain.identify_payne`), stored under ``/fits/<id>`` beside ``/runs`` unless
``--no-store``.
"""

from __future__ import annotations

import argparse
import math

from viscorig import jsontext
from viscorig.cli import summary_of
from viscorig.cli.arguments import parse_band
from viscorig.errors import InputError
from viscorig.fitting import FitResult
from viscorig.identify import (
    TableSource,
    identify_run,
    is_bare_table,
    store_fit,
    table_parameters,
)
from viscorig.numbers import with_uncertainty
from viscorig.storage import CampaignFile
from viscorig.strain import identify_payne, store_payne_fit

FRF_CHOICES = {"table": ("table",), "support": ("support",), "both": ("table", "support")}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``identify`` command."""
    parser = subparsers.add_parser("identify", help=summary_of("identify"))
    parser.add_argument("file", help="campaign file (.h5)")
    parser.add_argument("--run", required=True, action="append",
                        help="run name, e.g. soft-0; several runs of one specimen at one "
                        "temperature and different levels with --model kraus: the "
                        "strain-amplitude dependence (Payne effect) from their differences")
    parser.add_argument(
        "--model",
        default=None,
        help="model spec, e.g. voigt, maxwell, maxwell(3), fractional "
        "(default: table for a bare-table run, voigt otherwise)",
    )
    parser.add_argument("--band", default=None, help="band fitted, LO:HI in Hz (default: all)")
    parser.add_argument(
        "--frf",
        choices=sorted(FRF_CHOICES),
        default=None,
        help="FRFs fitted: table (X_s/F_e), support (X_v/F_v) or both (default: all available)",
    )
    parser.add_argument(
        "--table-model",
        default="table",
        help="model of the bare-table run whose M_s, K_s, C_s (and covariance) a specimen fit "
        "inherits, e.g. 'table+frame(2000)' for a 2000 kg frame under the table "
        "(default: table)",
    )
    parser.add_argument(
        "--weights",
        choices=("noise", "uniform"),
        default="noise",
        help="each point weighted by its noise (default: the project's estimate) or every point "
        "the same (the paper's method)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--no-store", action="store_true", help="do not store the fit")
    parser.set_defaults(handler=handler)


def handler(args: argparse.Namespace) -> int:
    """Run ``identify``."""
    band = parse_band(args.band)
    if len(args.run) > 1:
        return _strain(args, band)
    args.run = args.run[0]
    frfs = FRF_CHOICES[args.frf] if args.frf else None
    mode = "r" if args.no_store else "a"
    with CampaignFile.open(args.file, mode) as campaign:
        table = None
        if not is_bare_table(campaign.run_metadata(args.run)):
            table = table_parameters(campaign, args.table_model)
        result, table = identify_run(campaign, args.run, args.model, band_hz=band, frfs=frfs,
                                     table=table, weighting=args.weights)
        fit_id = None if args.no_store else store_fit(campaign, args.run, result)
    if args.json:
        print(jsontext.dumps(result.to_json(args.run)))
    else:
        print(format_result(args.run, result, table, fit_id))
    return 0


def format_result(
    run: str, result: FitResult, table: TableSource | None, fit_id: str | None
) -> str:
    """Human-readable report of one fit: every number with its ±, and what the ± include."""
    ratio = result.rms_error / result.noise_floor
    lines = [
        f"run {run}: model {result.spec}, {result.band_hz[0]:g}-{result.band_hz[1]:g} Hz, "
        f"{result.points} points, FRFs {', '.join(result.frfs)}, "
        + ("each point weighted by its noise" if result.weighting == "noise"
           else "every point weighted the same (the paper's method)"),
        f"rms_error {result.rms_error:.3e}   noise_floor {result.noise_floor:.3e}"
        f"   ({ratio:.2f} x floor)",
    ]
    if result.noise is not None:
        lines += [f"noise: {text}" for text in result.noise.describe()]
    if table is not None:
        inherited = " (with its uncertainty)" if result.inherited else " (exact, as given)"
        lines.append(f"table parameters fixed at the values from {table.source}{inherited}")
    width = max(len(name) for name in result.parameters)
    for name, estimate in result.parameters.items():
        if name in result.free:
            shown = with_uncertainty(estimate.value, estimate.stderr)
        elif name in result.inherited:
            shown = f"{with_uncertainty(estimate.value, estimate.stderr)} (inherited)"
        else:
            shown = f"{with_uncertainty(estimate.value, math.nan)} fixed"
        lines.append(f"  {name:<{width}} = {shown:<36} {estimate.unit}".rstrip())
    if result.fits_noise:
        text = "± are standard uncertainties: the noise (white and drift"
        text += ", the table's uncertainty" if result.inherited else ""
        lines.append(text + "), the model fitting to the noise")
    else:
        lines.append(
            f"the model does not fit to the noise ({ratio:.1f} x floor): the ± are those of the "
            "model's band-average (the noise's, scaled by the misfit, or the residuals' own "
            "sandwich, whichever is larger), not measurement uncertainties of the specimen"
        )
    lines += [f"not in the ±: {text}" for text in result.excludes]
    if result.candidates:
        lines.append(
            "order chosen by BIC among: "
            + ", ".join(f"{spec} ({bic:.1f})" for spec, bic, _ in result.candidates)
        )
    lines += [f"warning: {text}" for text in result.warnings]
    if fit_id is not None:
        lines.append(f"stored as fit {fit_id}")
    return "\n".join(lines)


def _strain(args: argparse.Namespace, band: tuple[float, float] | None) -> int:
    """``identify --run A --run B ... --model kraus``: :func:`viscorig.strain.identify_payne`."""
    if args.model != "kraus":
        raise InputError("several runs are fitted together only for the strain-amplitude "
                         "dependence: add --model kraus (or give one --run)", "--run")
    with CampaignFile.open(args.file, "r" if args.no_store else "a") as campaign:
        fit = identify_payne(campaign, args.run, band_hz=band)
        fit_id = None if args.no_store else store_payne_fit(campaign, fit)
    if args.json:
        print(jsontext.dumps(fit.to_json()))
        return 0
    low, high = fit.displacement_range_m
    lines = [f"runs {', '.join(fit.runs)}: Kraus model of the Payne effect from the differences "
             f"of K* (Eq. 5) between levels, {fit.points} points, displacement "
             f"{low * 1e6:.3g}-{high * 1e6:.3g} µm, reduced chi-square "
             f"{fit.reduced_chi_square:.2f}"]
    for name, parameter in fit.parameters.items():
        lines.append(f"  {name:<4} = {parameter.text()}")
    lines.append("not stored (--no-store)" if fit_id is None else f"stored as fit /fits/{fit_id}")
    print("\n".join(lines))
    return 0
