"""``viscorig sim serve``: the simulated rig and virtual 35670A on loopback.

Prints the VISA resource strings to open with pyvisa-py and serves until Ctrl-C::

    viscorig sim serve --preset soft-0 --prologix --pace real
    viscorig sim serve --preset table --pace 60 --fault unplug=3
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from viscorig.cli import summary_of
from viscorig.cli.arguments import port_number, positive_int, positive_number
from viscorig.errors import InputError


def register(subparsers: Any) -> None:
    """Add ``sim serve`` to the command line."""
    sim = subparsers.add_parser(
        "sim", help=summary_of("sim"), description="Simulated rig and virtual 35670A analyser."
    )
    commands = sim.add_subparsers(title="commands", dest="sim_command", required=True)
    serve = commands.add_parser(
        "serve",
        help="serve the virtual 35670A on loopback",
        description="Serve a virtual 35670A measuring a simulated rig, as a raw SCPI socket "
        "(and optionally a Prologix GPIB-Ethernet endpoint and a GPIB-USB pseudo-terminal), "
        "until Ctrl-C.",
    )
    rig = serve.add_mutually_exclusive_group()
    rig.add_argument("--rig", metavar="RIG.toml", help="rig file to simulate")
    rig.add_argument("--preset", metavar="NAME",
                     help="shipped rig preset (table, soft-0, ...; default: table)")
    serve.add_argument("--port", type=port_number, default=0,
                       help="port of the raw SCPI socket (default: a free port)")
    serve.add_argument("--prologix", action="store_true",
                       help="also serve a Prologix GPIB-Ethernet endpoint (analyser at GPIB 11)")
    serve.add_argument("--prologix-port", type=port_number, default=0, metavar="N",
                       help="port of the Prologix endpoint (default: a free port)")
    serve.add_argument("--pty", action="store_true",
                       help="also serve a Prologix GPIB-USB adapter on a pseudo-terminal")
    serve.add_argument("--pace", type=_pace, default=None, metavar="real|X",
                       help="take the instrument's time: 'real' (as the 35670A would) or X "
                       "simulated seconds per wall-clock second (default: as fast as possible)")
    serve.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                       help="address to bind (default: 127.0.0.1, loopback only)")
    serve.add_argument("--seed", type=int, default=None, help="seed of the sensor noise")
    serve.add_argument("--fault", action="append", default=[], metavar="SPEC",
                       help="inject a fault: KIND[=ARG][@MATCH], KIND one of no_reply, drop, "
                       "garble, error=CODE[,TEXT], overload=CH[:POINTS], autocal (once); "
                       "unplug=CH, swap=A,B, gain=CH:K, invert=CH, range=CH:DBVRMS, "
                       "hum=CH:VPK[:HZ] (wiring faults, they last); repeatable")
    serve.add_argument("--max-connections", type=positive_int, default=8, metavar="N",
                       help="clients served at once (default 8); when all are held, a new "
                       "client takes the slot of the one longest without a message")
    serve.add_argument("--idle-timeout", type=positive_number, default=3600.0, metavar="S",
                       help="close a connection silent for S seconds (default 3600)")
    serve.add_argument("--message-timeout", type=positive_number, default=10.0, metavar="S",
                       help="close a connection whose message, begun, has not ended within S "
                       "seconds (default 10)")
    serve.add_argument("--max-message", type=positive_int, default=65536, metavar="BYTES",
                       help="longest program message; longer ones get error -100 and the "
                       "connection is closed (default 65536)")
    serve.add_argument("--read-timeout-floor", type=_seconds, default=None, metavar="S",
                       help="shortest wait of the Prologix ++read (default 1 s; 0: exactly "
                       "++read_tmo_ms)")
    serve.add_argument("--without-option", action="append", default=[], metavar="OPT",
                       choices=("1D2", "AY6"),
                       help="leave an option out of *OPT? (1D2 swept sine, AY6 four channels)")
    serve.add_argument("--chamber", choices=("tcp", "rtu"), default=None,
                       help="also serve the rig's temperature chamber (rig file [chamber]) as a "
                       "Eurotherm 3200 controller (unit 1) and specimen indicator (unit 2) on "
                       "Modbus TCP (loopback) or RTU (a pseudo-terminal)")
    serve.add_argument("--chamber-port", type=port_number, default=0, metavar="N",
                       help="Modbus TCP port of the chamber (default: a free port)")
    serve.add_argument("--chamber-pace", type=positive_number, default=None, metavar="X",
                       help="simulated seconds of the chamber per wall-clock second (default: "
                       "--pace, else 1)")
    serve.set_defaults(handler=serve_command)


def _pace(text: str) -> float:
    if text.strip().lower() == "real":
        return 1.0
    return positive_number(text)


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not 0.0 <= value < 1e6:
        raise argparse.ArgumentTypeError(f"must be 0 or more seconds, got {text}")
    return value


def serve_command(args: argparse.Namespace) -> int:
    """Build the simulated analyser, print its resources, serve until Ctrl-C."""
    from rigsim.analyser import DEFAULT_OPTIONS
    from rigsim.faults import FaultSpecError, parse_fault_spec
    from rigsim.rigfile import RigFileError, load_preset, load_rig
    from rigsim.server import READ_TIMEOUT_FLOOR_S, ServiceLimits, SimulatedAnalyserServer

    try:
        rig = load_rig(args.rig) if args.rig else load_preset(args.preset or "table")
    except RigFileError as error:
        raise InputError(str(error)) from None
    try:
        faults = [parse_fault_spec(spec) for spec in args.fault]
    except FaultSpecError as error:
        raise InputError(str(error), "--fault") from None
    options = tuple(o for o in DEFAULT_OPTIONS if o not in args.without_option)
    limits = ServiceLimits(max_message_bytes=args.max_message,
                           max_connections=args.max_connections,
                           idle_timeout_s=args.idle_timeout,
                           message_timeout_s=args.message_timeout)
    floor = READ_TIMEOUT_FLOOR_S if args.read_timeout_floor is None else args.read_timeout_floor
    server = SimulatedAnalyserServer(
        rig, port=args.port, prologix=args.prologix, prologix_port=args.prologix_port,
        pty=args.pty, pace=args.pace, seed=args.seed, host=args.host, options=options,
        limits=limits, read_timeout_floor_s=floor,
    )
    try:
        server.start()
    except OSError as error:
        server.close()
        raise InputError(f"cannot serve on {args.host}: {error.strerror or error}") from None
    for fault in faults:
        server.faults.add(fault)
    chamber_server = None
    if args.chamber is not None:
        from rigsim.chamber import Chamber
        from rigsim.chamber_server import ChamberServer
        from rigsim.engine import RigSimulator

        chamber = Chamber(rig.chamber)
        simulator = server.analyser.simulator
        assert isinstance(simulator, RigSimulator)  # the server builds the time-domain engine
        simulator.attach_chamber(chamber, advance=False)
        pace = args.chamber_pace or args.pace or 1.0
        chamber_server = ChamberServer(chamber, transport=args.chamber, host=args.host,
                                       port=args.chamber_port, pace=pace)
        try:
            chamber_server.start()
        except (OSError, RuntimeError) as error:
            server.close()
            raise InputError(f"cannot serve the chamber on {args.host}: {error}") from None
    name = rig.name or (args.rig if args.rig else args.preset or "table")
    print(f"virtual 35670A on rig {name}"
          + ("" if args.pace is None else f", {args.pace:g} simulated s per s"))
    for line in server.analyser.front_end.describe():
        print(f"wiring fault: {line}")
    print(f"raw SCPI socket:  {server.socket_resource}")
    if server.prologix_resource:
        print(f"Prologix (TCP):   {server.prologix_resource}  then  {server.gpib_resource}")
    if server.pty_resource:
        print(f"Prologix (USB):   {server.pty_resource}  then  {server.gpib_resource}")
    if chamber_server is not None:
        print(f"chamber (Modbus {args.chamber.upper()}): {chamber_server.address}  controller "
              f"unit 1, specimen unit 2, {chamber_server.pace:g} simulated s per s")
    print("Ctrl-C stops.", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        if chamber_server is not None:
            chamber_server.close()
        server.close()
    print("stopped", file=sys.stderr)
    return 0
