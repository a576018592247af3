"""``viscorig export`` and ``viscorig import``: FRFs to and from other tools.

``export FILE.h5 --run RUN --format uff|csv --out PATH`` writes a run's two accelerances
(ẍ_s/F_e and ẍ_v/F_v, m/s²/N): a universal file with one dataset 58 per FRF (binary 58 by
default, so values survive to the last bit; ``--uff-ascii`` for plain ASCII), or a CSV with the
units in the column names and the point flags, which spreadsheets and pandas.read_csv open as
it is, with its metadata beside it in NAME.csv-metadata.json (CSV on the Web). With ``--material
abaqus|ansys|lsdyna`` instead of ``--format``, it writes the master curve of a DMA run (or of rig
runs of one specimen) as an FE material card: the Prony series and the shift function, with a
comment block naming data, units, reference temperature and the fit's error.

``import FILE.h5 --run NAME (--uff PATH | --csv PATH | --sdf PATH [--sdf PATH2])
[--station STATION.toml]`` adds a new, complete run to a campaign file (created when missing):
from a universal file's FRF records, from a CSV written by ``export``, or from SDF files that an
analyser of the 35665A/35670A family saved to its disk (frequency responses from a swept sine
or from FFT mode; the first is ẍ_s/F_e, the second ẍ_v/F_v, or one file holding both; with
--station, the channel roles decide). Units and frequency axis are those the file declares,
converted to Hz and m/s²/N; volt-over-volt SDF responses are converted with the station's
channel roles and sensitivities, and refused without one; other units than acceleration over
force are refused. One FRF alone gives a run whose ẍ_v/F_v is missing. What the files do not
say (specimen, preload, hardness) is given with options. Everything is read and checked before
the campaign file is touched, an existing run is never overwritten, and a truncated or
inconsistent file is refused whole: an import is never partial. ``--dma PATH`` stores a DMA
temperature/frequency sweep (CSV) as a DMA run instead (``/dma/NAME``, read by ``viscorig
master``).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from viscorig.cli import summary_of
from viscorig.cli.arguments import add_vertical_shift
from viscorig.errors import InputError
from viscorig.exchange import (
    ImportSettings,
    import_run,
    read_csv,
    read_sdf_frfs,
    read_uff,
    write_csv,
    write_uff,
)
from viscorig.materials.dmafile import read_dma_file
from viscorig.materials.dmastore import import_dma
from viscorig.sequences import load_station
from viscorig.sequences.schema import SWEEP, TEMPERATURE
from viscorig.storage import CampaignFile, layout


def _paragraph(index: int) -> str:
    """One paragraph of the module text, for a command's ``--help``."""
    return (__doc__ or "").split("\n\n")[index].replace("``", "")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``export`` and ``import`` commands."""
    export = subparsers.add_parser(
        "export", help=summary_of("export"),
        description=_paragraph(1), formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    export.add_argument("file", help="campaign file (.h5)")
    export.add_argument("--run", required=True, action="append",
                        help="run name, e.g. soft-0 (with --material: a DMA run, or give once "
                        "per rig run of one specimen)")
    what = export.add_mutually_exclusive_group(required=True)
    what.add_argument("--format", choices=("uff", "csv"),
                      help="uff: dataset 58 records, one per FRF; csv: one row per point")
    what.add_argument("--material", choices=("abaqus", "ansys", "lsdyna"),
                      help="the master curve's Prony series and shift function as an FE "
                      "material card (see 'viscorig master')")
    export.add_argument("--reference-temperature", type=float, default=None, metavar="C",
                        help="with --material: temperature of the master curve, °C")
    export.add_argument("--poisson-ratio", type=float, default=0.49,
                        help="with --material: constant Poisson's ratio relating shear, bulk "
                        "and Young's moduli (default 0.49)")
    export.add_argument("--disc-mass", type=float, default=None, metavar="KG",
                        help="with --material and rig runs: disc mass M_v")
    export.add_argument("--kstar", choices=("support", "fit"), default="support",
                        help="with --material and rig runs: K* from the support FRF (Eq. 5) "
                        "or from the newest stored fit")
    add_vertical_shift(export, "with --material: ")
    export.add_argument("--out", required=True, help="file to write (replaced if it exists)")
    export.add_argument("--uff-ascii", action="store_true",
                        help="plain ASCII dataset 58 (12 significant digits, frequencies 6) "
                        "instead of binary 58 (exact doubles)")
    export.set_defaults(handler=export_handler)

    imports = subparsers.add_parser(
        "import", help=summary_of("import"),
        description=_paragraph(2),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    imports.add_argument("file", help="campaign file (.h5); created if missing")
    imports.add_argument("--run", required=True, help="name of the new run, e.g. soft-0")
    source = imports.add_mutually_exclusive_group(required=True)
    source.add_argument("--uff", metavar="PATH", help="universal file with dataset 58 FRFs")
    source.add_argument("--csv", metavar="PATH", help="CSV written by 'viscorig export'")
    source.add_argument("--sdf", metavar="PATH", action="append",
                        help="SDF file of a 35665A/35670A-family analyser (give twice: "
                        "ẍ_s/F_e, then ẍ_v/F_v)")
    source.add_argument("--dma", metavar="PATH",
                        help="DMA temperature/frequency sweep (CSV, a TA TRIOS text export, or an "
                        "Excel workbook such as Eplexor's export), stored as a DMA run")
    imports.add_argument("--modulus", choices=("E", "G"), default=None,
                         help="with --dma: tensile (E) or shear (G) modulus (default: told "
                         "from the column names)")
    imports.add_argument("--station", metavar="STATION.toml",
                         help="station file: its [channels] and [sensitivity] convert "
                         "volt-over-volt SDF responses and say which FRF is which")
    imports.add_argument("--specimen", default="unknown",
                         help="specimen name; 'none' for a bare-table run (default: unknown); "
                         "with --dma, the DMA runs of one specimen make one master curve in "
                         "the report")
    imports.add_argument("--hardness", type=float, default=math.nan, help="Shore A hardness")
    imports.add_argument("--preload-strain", type=float, default=0.0,
                         help="static strain of the specimens (0.104 for 10 %%; default 0)")
    imports.add_argument("--temperature", type=float, default=math.nan, help="°C")
    imports.add_argument("--level", type=float, default=math.nan,
                         help="reference acceleration amplitude held, m/s^2 (peak)")
    imports.set_defaults(handler=import_handler)


def export_handler(args: argparse.Namespace) -> int:
    """Run ``export``."""
    path = Path(args.file)
    out = Path(args.out)
    if out.resolve() == path.resolve():
        raise InputError("would overwrite the campaign file", "--out")
    if args.material:
        return _export_material(args, out)
    if len(args.run) != 1:
        raise InputError(f"{len(args.run)} runs; --format exports one", "--run")
    run = CampaignFile.open(path).run(args.run[0])
    if args.format == "uff":
        count = write_uff(run, out, path.name, binary=not args.uff_ascii)
        kind = "ASCII" if args.uff_ascii else "binary"
        print(f"{out}: {count} FRF record(s) (dataset 58, {kind}) of run {run.name}, "
              f"{run.points} points")
    else:
        sidecar = write_csv(run, out, path.name)
        print(f"{out}: run {run.name}, {run.points} points; metadata in {sidecar}")
    return 0


def _export_material(args: argparse.Namespace, out: Path) -> int:
    """``export --material``: build the master curve, write its card."""
    # keeps the command's start fast: scipy loads only for a material card
    from viscorig.cli.master import master_of
    from viscorig.materials.fecards import card_error, write_card

    master = master_of(args.file, args.run, args.reference_temperature, args.disc_mass,
                       args.kstar, args.vertical_shift, args.thermal_expansion)
    name = "VISCORIG_" + "_".join(args.run).upper().replace("-", "_").replace(".", "_")
    series = write_card(master, args.material, out, name[:80], args.poisson_ratio)
    # what the card holds: LS-DYNA's six cards take a refitted, shorter series
    function = master.shift_function
    shifted = not (args.material == "lsdyna" and function is not None
                   and function.kind != "wlf")
    storage, loss = card_error(master, series, shifted)
    refitted = (f" (the master's {master.prony.terms}-term series refitted)"
                if series.terms != master.prony.terms else "")
    print(f"{out}: {args.material} material card of {', '.join(args.run)}: "
          f"{series.terms}-term Prony series{refitted}, reference "
          f"{master.reference_temperature_c:.2f} °C, rms ln error of the card storage "
          f"{storage:.3f}, loss {loss:.3f}")
    return 0


def import_handler(args: argparse.Namespace) -> int:
    """Run ``import``."""
    if args.modulus is not None and not args.dma:
        raise InputError("only with --dma", "--modulus")
    if args.station and not args.sdf:
        raise InputError("a station converts SDF files only; the other formats carry "
                         "their units", "--station")
    for given in (args.dma, args.uff, args.csv, args.station, *(args.sdf or ())):
        if given is not None and not Path(given).is_file():
            raise InputError("not a file" if Path(given).exists() else "no such file", given)
    if args.dma:
        table = read_dma_file(Path(args.dma), args.modulus)
        specimen = None if args.specimen == "unknown" else args.specimen
        points = import_dma(Path(args.file), args.run, table, specimen)
        print(f"{args.file}: DMA run {args.run} imported from {table.source}: {points} points, "
              f"{table.sets.size} temperature{'s' if table.sets.size != 1 else ''}, "
              f"modulus {table.modulus}")
        return 0
    _check_run_options(args)
    if args.uff:
        frfs = read_uff(Path(args.uff))
    elif args.csv:
        frfs = read_csv(Path(args.csv))
    else:
        if len(args.sdf) > 2:
            raise InputError(f"{len(args.sdf)} files; give one or two", "--sdf")
        if len(args.sdf) == 2 and Path(args.sdf[0]).resolve() == Path(args.sdf[1]).resolve():
            raise InputError(f"{args.sdf[0]} given twice; the two files hold the two FRFs",
                             "--sdf")
        station = load_station(args.station) if args.station else None
        frfs = read_sdf_frfs([Path(p) for p in args.sdf], station)
    settings = ImportSettings(
        specimen=args.specimen, hardness_shore_a=args.hardness,
        preload_strain=args.preload_strain, temperature_c=args.temperature,
        level_m_per_s2=args.level,
    )
    points = import_run(Path(args.file), args.run, frfs, settings)
    present = "two FRFs" if np.any(np.isfinite(frfs.accelerance_support)) else "ẍ_s/F_e only"
    print(f"{args.file}: run {args.run} imported from {frfs.source}: {points} points, {present}")
    return 0


def _check_run_options(args: argparse.Namespace) -> None:
    """The run's options within the bounds a sequence holds a run's to (a sweep step's
    hardness and preload, a temperature step's set point: a run measured in a chamber records
    that), NaN where an option is not given (unknown), before any file is read."""
    level = layout.RUN_NUMBERS["level_m_per_s2"]  # the bounds the campaign file keeps
    if not level.holds(args.level):
        most = "" if args.level <= 0 else f", at most {level.high:g} m/s^2"
        raise InputError(f"{args.level} must be a positive number{most}", "--level")
    if math.isnan(args.preload_strain):  # (0 when not given)
        raise InputError("nan is not a number", "--preload-strain")
    for option, value, field in (
            ("--hardness", args.hardness, SWEEP.field("hardness_shore_a")),
            ("--preload-strain", args.preload_strain, SWEEP.field("preload_strain")),
            ("--temperature", args.temperature, TEMPERATURE.field("set_point_c"))):
        if not math.isnan(value) and not field.low <= value <= field.high:
            unit = f" {field.unit}" if field.unit else ""
            raise InputError(f"{value:g} is outside {field.low:g}..{field.high:g}{unit}", option)
