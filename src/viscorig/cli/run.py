"""``viscorig run SEQUENCE.toml`` and ``viscorig resume FILE.h5``: run a test sequence.

::

    viscorig run sequences/paper.toml --yes --out paper.h5     # the embedded simulated rig
    viscorig run my-test.toml --station lab.toml                # the rig in the lab
    viscorig run a.toml b.toml --station lab.toml --holds       # a queue, automatic holds
    viscorig resume paper.h5 --yes                              # after Ctrl-C, a fault, a crash

While it measures: Ctrl-Z pauses at the point being measured and Ctrl-Z again resumes (or
``kill -USR1``/``-USR2``, :mod:`viscorig.acquisition.terminal`); ``viscorig note FILE.h5 TEXT``
from another terminal stores a note in the campaign's journal. ``--holds`` holds the run by
itself under the station's ``[bench]`` conditions, as the bench page does.

Several sequences are a queue: every one is checked before the first starts, each into its own
file (``<sequence name>.h5`` here), one after another as long as each ends complete.

Exit status: 0 complete; 2 bad input (nothing written) or a sweep refused because its
predicted force exceeds the shaker limit (``over_limit = "refuse"`` in the sequence, the
default, unless ``--over-limit reduce`` is given: the command line overrides the sequence);
3 instrument fault (data kept); 130 interrupted by Ctrl-C (data kept). After 3 or 130 (or a
crash), ``viscorig resume FILE.h5`` continues the interrupted run from its first missing point
and then the rest of the sequence.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import textwrap
from pathlib import Path

from viscorig.acquisition import (
    OVER_LIMIT_CHOICES,
    Console,
    NoAnswer,
    Outcome,
    Runner,
    forecast_sequence,
    format_forecast,
)
from viscorig.acquisition.notebox import NoteCarrier
from viscorig.acquisition.terminal import PauseSignals, signal_help
from viscorig.cli import summary_of
from viscorig.cli.arguments import seed, sim_pace
from viscorig.cli.check import refuse
from viscorig.cli.watch import live_view
from viscorig.errors import InputError, InstrumentError
from viscorig.sequences import IdentifyTableStep, Sequence
from viscorig.sequences.schema import STEP_TYPES
from viscorig.stations.checking import Checked, check_files, check_texts
from viscorig.stations.forecasting import simulated_floors
from viscorig.stations.opening import open_station, runner_options, station_holds
from viscorig.storage import CampaignFile


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--yes", action="store_true",
                        help="answer every operator prompt (CI, demos)")
    parser.add_argument("--over-limit", choices=OVER_LIMIT_CHOICES, default=None,
                        help="a sweep whose predicted shaker force exceeds the limit: refuse it "
                        "or reduce its level below the limit. Given here, it applies to every "
                        "sweep and overrides the sequence; otherwise each sweep's over_limit "
                        "(its step, else [defaults]) applies, and 'refuse' when the sequence "
                        "says nothing")
    parser.add_argument("--live", action="store_true",
                        help="serve a live view of the campaign on 127.0.0.1 while it runs "
                        "(as 'viscorig watch' does) and open it in the browser")
    parser.add_argument("--no-browser", action="store_true",
                        help="with --live: only print the live view's address")
    parser.add_argument("--sim-pace", type=sim_pace, default=None, metavar="X",
                        help="embedded simulated rig only: simulated seconds per wall-clock "
                        "second (default: as fast as the computer allows)")
    parser.add_argument("--sim-seed", type=seed, default=None, metavar="N",
                        help="embedded simulated rig only: seed of its noise, for a campaign "
                        "that repeats exactly (default: fresh noise every run)")
    parser.add_argument("--holds", action="store_true",
                        help="automatic holds, as on the bench page: the run pauses by itself "
                        "when the level is not held, an input keeps overloading, the force nears "
                        "the shaker limit, the analyser stops answering or the specimen leaves "
                        "its temperature band (the station's [bench] settings); it goes on when "
                        "the condition clears (hold_resume = \"auto\") or at Ctrl-Z")
    parser.add_argument("--hold-resume", choices=("auto", "technician"), default=None,
                        help="with automatic holds (implies --holds): go on by itself when the "
                        "condition clears, or wait for the technician (default: the station's "
                        "[bench] hold_resume; the embedded rig's: technician)")


def _fields_epilog() -> str:
    lines = ["sequence steps and their fields (reference: sequences/README.md, or",
             "'viscorig check --fields'):"]
    for name, schema in STEP_TYPES.items():
        lines.append(textwrap.fill(f"{name}: {', '.join(schema.names)}", 78,
                                   initial_indent="  ", subsequent_indent="    "))
    lines.append("  [defaults]: any sweep field but run")
    return "\n".join(lines)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``run`` and ``resume`` commands."""
    run = subparsers.add_parser(
        "run", help=summary_of("run"),
        description="Run a test sequence (TOML) and record every sweep into a new campaign "
        "file. Without --station, the embedded simulated rig and analyser are used. The "
        "sequence (and station) are checked whole before the first prompt, as 'viscorig "
        "check' does.",
        epilog=_fields_epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("sequence", metavar="SEQUENCE.toml", nargs="+",
                     help="test sequence; several are a queue, run in order")
    run.add_argument("--station", metavar="STATION.toml", default=None,
                     help="the lab's station file (analyser resource, transducers, shaker)")
    run.add_argument("--out", metavar="FILE.h5", default=None,
                     help="campaign file to create (default: <sequence name>.h5 here; an "
                     "existing file is never overwritten); one sequence only")
    _common(run)
    run.set_defaults(handler=run_command)

    resume = subparsers.add_parser(
        "resume", help=summary_of("resume"),
        description="Continue the sequence stored in a campaign file: the interrupted run "
        "from its first missing point, then the remaining steps.")
    resume.add_argument("file", metavar="FILE.h5", help="campaign file")
    _common(resume)
    resume.set_defaults(handler=resume_command)


def run_command(args: argparse.Namespace) -> int:
    """``viscorig run``: check everything, create the file, run the sequence (or each sequence
    of a queue, in order, while each ends complete)."""
    for given, option in ((args.sim_pace, "--sim-pace"), (args.sim_seed, "--sim-seed")):
        if args.station is not None and given is not None:
            raise InputError("only for the embedded simulated rig (no --station)", option)
    sequences = list(args.sequence)
    if args.out and len(sequences) > 1:
        raise InputError("one campaign file for one sequence; a queue writes each to "
                         "<sequence name>.h5 here", "--out")
    queue: list[tuple[str, Checked, Path]] = []
    for text in sequences:  # everything checked before anything moves
        checked = check_files(text, args.station)
        if not checked.ok:
            option = f" --station {args.station}" if args.station else ""
            refuse(checked, f"viscorig check {text}{option}")
        out = Path(args.out) if args.out else Path.cwd() / f"{Path(text).stem}.h5"
        if out.is_dir():
            raise InputError("is a folder; --out names the campaign file to write "
                             f"(for example {out / (Path(text).stem + '.h5')})", str(out))
        if out.exists():
            raise InputError(
                f"exists; a campaign file is never overwritten. Continue it with "
                f"'viscorig resume {out}', or choose another --out", str(out))
        if not out.parent.is_dir():
            raise InputError("folder does not exist", str(out))
        if any(out == other for _, _, other in queue):
            raise InputError(f"two sequences of the queue would write {out.name}: rename one",
                             text)
        queue.append((text, checked, out))
    for number, (text, checked, out) in enumerate(queue):
        if len(queue) > 1:
            print(f"queue {number + 1}/{len(queue)}: {text}", flush=True)
        status = _run_new(text, checked, out, args)
        if status != 0:
            left = [name for name, _, _ in queue[number + 1:]]
            if left:
                print(f"viscorig: the queue stopped; not started: {', '.join(left)}",
                      file=sys.stderr)
            return status
    return 0


def _run_new(text: str, checked, out: Path, args: argparse.Namespace) -> int:
    """Create ``out`` and run one checked sequence into it."""
    sequence, station = checked.passed(), checked.station
    with open_station(sequence, station, args.sim_pace, args.sim_seed) as opened:
        campaign = CampaignFile.create(
            out, sequence_text=checked.sequence_text, sequence_file=str(text),
            station_text=checked.station_text, station_file=args.station or "",
            rig=opened.station.rig_attributes(),
        )
        print(f"campaign file: {out}  ({_where(opened)})", flush=True)
        try:
            return _run(campaign, sequence, opened, args)
        except InstrumentError:
            if len(args.sequence) > 1:
                print(f"viscorig: continue this file with 'viscorig resume {out}'",
                      file=sys.stderr)
            raise


def resume_command(args: argparse.Namespace) -> int:
    """``viscorig resume``: the file holds the sequence and station texts."""
    campaign = CampaignFile.open(args.file, "a")
    sequence_text = campaign.sequence_text
    if sequence_text is None:
        raise InputError("holds no sequence (/setup/sequence_toml); it was not written by "
                         "'viscorig run'", args.file)
    station_text = campaign.station_text
    for given, option in ((args.sim_pace, "--sim-pace"), (args.sim_seed, "--sim-seed")):
        if station_text is not None and given is not None:
            raise InputError("only for the embedded simulated rig; this campaign used a "
                             "station file", option)
    checked = check_texts(sequence_text, f"{args.file}: /setup/sequence_toml", station_text,
                          f"{args.file}: /setup/station_toml")
    if not checked.ok:
        refuse(checked, "")
    sequence, station = checked.passed(), checked.station
    statuses = {name: campaign.run_metadata(name).status for name in campaign.run_names}
    if all(statuses.get(name) == "complete" for name in sequence.run_names) and _identified(
        campaign, sequence
    ):
        print(f"{args.file}: every run of sequence '{sequence.name}' is complete; "
              "nothing to do")
        return 0
    with open_station(sequence, station, args.sim_pace, args.sim_seed) as opened:
        print(f"continuing {args.file}  ({_where(opened)})", flush=True)
        return _run(campaign, sequence, opened, args)


def _forecast(campaign: CampaignFile, sequence: Sequence, opened) -> dict:
    """Print the predicted test time of the steps left (as ``viscorig plan`` does); return the
    floors of the adaptive steps, for the time left."""
    statuses = {name: campaign.run_metadata(name).status for name in campaign.run_names}
    floors = simulated_floors(sequence) if opened.simulated else {}
    station = opened.station
    chamber = station.chamber
    thermal = {} if chamber is None else chamber.soak_forecast()
    forecasts = forecast_sequence(
        sequence, table_known=station.table is not None, floors=floors,
        force_limit_n=station.shaker_force_limit_n, status=statuses.get, **thermal,
    )  # fmt: skip
    left = [item for item in forecasts
            if not (item.kind.endswith("sweep") and statuses.get(item.name) == "complete")]
    print(format_forecast(left, "predicted test time:"), flush=True)
    return floors


def _identified(campaign: CampaignFile, sequence: Sequence) -> bool:
    return all(
        any(fit.model == "table" for fit in campaign.fits(step.run))
        for step in sequence.steps if isinstance(step, IdentifyTableStep)
    )


def _where(opened) -> str:
    what = "embedded simulated rig" if opened.simulated else "station"
    return f"{what}, analyser {opened.analyser.resource}"


def _run(campaign: CampaignFile, sequence: Sequence, opened, args: argparse.Namespace) -> int:
    fast = opened.simulated and args.sim_pace is None
    options = runner_options(opened, args.over_limit)
    console = Console(yes=args.yes)
    floors = _forecast(campaign, sequence, opened)
    holds, hold_resume = [], "technician"
    if args.holds or args.hold_resume is not None:
        holds = station_holds(opened)
        hold_resume = args.hold_resume or opened.station.bench.hold_resume
    runner = Runner(campaign, sequence, opened.station, opened.analyser, console, options,
                    floors=floors, holds=holds, hold_resume=hold_resume)
    engine = runner.engine
    live: contextlib.AbstractContextManager[str | None] = contextlib.nullcontext()
    if args.live:
        live = live_view(campaign.path, open_browser=not args.no_browser, say=console.say)
    console.say(signal_help() + f"; notes: viscorig note {campaign.path} TEXT")

    def store(text: str) -> object:
        with engine.file_lock:
            return campaign.add_journal_entry("note", text, engine.current_run)

    try:
        with live, PauseSignals(engine, console.say).installed(), NoteCarrier(
                campaign.path, store, console.warn):
            result = runner.run()
    except NoAnswer:
        print(f"viscorig: a prompt needs an answer and the input is closed; run with --yes, "
              f"then continue with: viscorig resume {campaign.path}", file=sys.stderr)
        return 2
    if result.outcome is Outcome.COMPLETE:
        print(f"{result.message}" + (" (simulated rig, as fast as possible)" if fast else ""))
        print(f"campaign file: {campaign.path}")
        return 0
    if result.outcome is Outcome.FAULT:
        raise InstrumentError(result.message)
    print(f"viscorig: {result.message}", file=sys.stderr)
    return result.outcome.exit_status
