"""``viscorig bench check``: a one-minute self-test of the station before a campaign;
``viscorig bench serve``: the bench page (:mod:`viscorig.bench`).

    viscorig bench check --station lab.toml     # the rig in the lab
    viscorig bench check                        # the embedded simulated rig (soft specimens)
    viscorig bench serve --port 0 --no-browser  # prints http://127.0.0.1:PORT/?token=TOKEN

One line per check, each with its verdict and, when it fails, what to do; exit status 0 only
when every check passes (1 otherwise; 2 for bad input, 3 when the analyser cannot be reached).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
from collections.abc import Iterator
from typing import Any

from viscorig.acquisition import Wiring
from viscorig.bench import BenchService
from viscorig.benchcheck import assess, measure
from viscorig.benchcheck.checks import RigFacts
from viscorig.cli import summary_of
from viscorig.cli.arguments import port_number, sim_pace
from viscorig.cli.watch import open_in_browser
from viscorig.errors import InputError, InstrumentError
from viscorig.sequences import PromptStep, Sequence, load_station
from viscorig.sequences.station import BenchSettings, TableParameters
from viscorig.stations.opening import check_presets, lab_station, simulated_station

#: The bench page's port a technician can bookmark.
DEFAULT_SERVE_PORT = 8766
#: Rig mounted on the embedded simulated rig unless --preset says otherwise: the bench check
#: expects transducers on all four inputs, so specimens are mounted.
DEFAULT_PRESET = "soft-0"


def register(subparsers: Any) -> None:
    """Add ``bench check`` to the command line."""
    bench = subparsers.add_parser("bench", help=summary_of("bench"),
                                  description="Checks of the test station.")
    commands = bench.add_subparsers(title="commands", dest="bench_command", required=True)
    check = commands.add_parser(
        "check", help="one-minute self-test of the station",
        description="Identity and options of the analyser; each input's range and noise with "
        "the source off; a low-level sine at 10, 25 and 45 Hz where each transducer must "
        "answer as its role implies; the level loop; overloads. One line per check.")
    check.add_argument("--station", metavar="STATION.toml", default=None,
                       help="the lab's station file (default: the embedded simulated rig)")
    check.add_argument("--preset", metavar="NAME", default=None,
                       help=f"simulated rig preset without --station (default {DEFAULT_PRESET})")
    check.set_defaults(handler=check_command)
    serve = commands.add_parser(
        "serve", help="the bench page: queue, run, pause, answer prompts, watch, take notes",
        description="Serve the bench page on 127.0.0.1 and open it in the browser: queue "
        "sequences (each checked and planned before anything moves), start, answer the "
        "operator prompts, pause, resume, abort, watch the live view and store notes in the "
        "campaign file. The first line printed is the address with its token; the page is a "
        "client of a JSON API any script can use with 'Authorization: Bearer TOKEN' "
        "(docs/bench.md). Ctrl-C stops the server (a run in progress is aborted, its data "
        "kept).")
    serve.add_argument("--station", metavar="STATION.toml", default=None,
                       help="the lab's station file (default: the embedded simulated rig); its "
                       "[bench] table sets the address and the automatic holds")
    serve.add_argument("--port", type=port_number, default=DEFAULT_SERVE_PORT,
                       help=f"TCP port (default {DEFAULT_SERVE_PORT}; 0: any free one)")
    serve.add_argument("--no-browser", action="store_true",
                       help="only serve and print the address; open no browser")
    serve.add_argument("--sim-pace", type=sim_pace, default=None, metavar="X",
                       help="embedded simulated rig only: simulated seconds per wall-clock "
                       "second (default: as fast as the computer allows)")
    serve.add_argument("--hold-resume", choices=("auto", "technician"), default=None,
                       help="after an automatic hold: go on by itself when the condition "
                       "clears, or wait for the technician (default: the station's [bench] "
                       "hold_resume; the embedded rig's: technician)")
    serve.set_defaults(handler=serve_command)


@contextlib.contextmanager
def _opened(args: argparse.Namespace) -> Iterator[Any]:
    """The station to check: the lab's, or the embedded simulated rig with its table filled in
    from the preset (a station file gives its own [table])."""
    if args.station is not None:
        if args.preset is not None:
            raise InputError("only for the embedded simulated rig (no --station)", "--preset")
        with lab_station(load_station(args.station)) as opened:
            yield opened
        return
    preset = args.preset or DEFAULT_PRESET
    sequence = Sequence("bench check", "", (PromptStep("", simulated_rig=preset),),
                        source="--preset")
    check_presets(sequence)
    from rigsim.rigfile import load_preset

    rig = load_preset(preset)
    table = rig.table
    with simulated_station(sequence) as opened:
        opened.mount(rig)  # the embedded rig starts bare; the check needs every transducer
        opened.station = dataclasses.replace(opened.station, table=TableParameters(
            table.mass_kg, table.stiffness_n_per_m, table.damping_ns_per_m))
        yield opened


def check_command(args: argparse.Namespace) -> int:
    """Measure, assess, print one line per check."""
    with _opened(args) as opened:
        station = opened.station
        print(f"bench check of {station.source or station.resource} "
              f"(analyser {opened.analyser.resource})", flush=True)
        wiring = Wiring.from_station(station)
        gain = station.shaker_gain_n_per_v
        source_limit = station.source_limit_v
        if gain:
            source_limit = min(source_limit, station.shaker_force_limit_n / gain)
        try:
            readings = measure(opened.analyser, wiring, source_limit,
                               station.shaker_force_limit_n)
        except opened.instrument_errors as error:
            raise InstrumentError(f"{opened.analyser.resource}: {error}") from None
    table = station.table
    rig = RigFacts(None if table is None else (table.mass_kg, table.stiffness_n_per_m,
                                          table.damping_ns_per_m), gain)
    verdicts = assess(readings, wiring, rig)
    for verdict in verdicts:
        print(verdict.line())
    failed = [v for v in verdicts if not v.passed]
    print(f"bench check: {len(verdicts) - len(failed)} of {len(verdicts)} checks passed"
          + ("" if not failed else "; fix the failures before the campaign"))
    return 0 if not failed else 1


def served(args: argparse.Namespace) -> tuple[BenchService, str]:
    """The service ``bench serve`` runs and the address it listens on, from its arguments."""
    address, bench = "127.0.0.1", BenchSettings()
    if args.station is not None:
        if args.sim_pace is not None:
            raise InputError("only for the embedded simulated rig (no --station)", "--sim-pace")
        bench = load_station(args.station).bench
        address = bench.address
    override = None
    if args.hold_resume is not None:
        override = dataclasses.replace(bench, hold_resume=args.hold_resume)
    return BenchService(args.station, bench=override, sim_pace=args.sim_pace), address


def serve_command(args: argparse.Namespace) -> int:
    """``viscorig bench serve``: print the address with its token first, serve until Ctrl-C."""
    # keeps the command's start fast: the web server loads only for serve
    from viscorig.bench.app import BenchServer

    service, address = served(args)
    try:
        server = BenchServer(service, args.port, address)
    except OSError as error:
        raise InputError(f"cannot serve on {address}:{args.port} ({error.strerror or error}); "
                         "choose another --port, or --port 0 for any free one",
                         "--port") from None

    def announce() -> None:
        print(server.url, flush=True)
        if address != "127.0.0.1":
            print(f"WARNING: served on {address} as the station's [bench] address allows: "
                  "other machines reach it (with the token)", flush=True)
        if not args.no_browser and not open_in_browser(server.url):
            print("no browser could be opened here: open the address above in one", flush=True)

    try:  # Ctrl-C is how the server is stopped, whenever it comes
        server.run(announce)
    except KeyboardInterrupt:
        pass
    finally:
        service.shutdown()
        server.socket.close()
    print("bench page stopped" + (f"; {service.message}" if service.message else ""),
          flush=True)
    return 0
