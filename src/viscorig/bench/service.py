"""The bench's queue and its runs: what the page and the JSON API drive.

One sequence runs at a time, on one worker thread, through :class:`viscorig.acquisition.Runner`
(the run engine of ``viscorig run``, with the page's console and the station's automatic holds).
Each queued sequence is checked and planned when it is queued, so its problems and its
predicted test time show before anything moves; :meth:`BenchService.start` runs the queue from
its first item and goes on to the next while each ends complete. Every method is safe to call
from any thread.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from viscorig.acquisition import Outcome, Runner, format_forecast
from viscorig.acquisition.console import ConsoleView, PageConsole, single_line
from viscorig.acquisition.engine import EngineState
from viscorig.acquisition.notebox import NoteCarrier
from viscorig.errors import InputError, ViscorigError
from viscorig.sequences.sequence import read_text
from viscorig.sequences.station import BenchSettings
from viscorig.stations.checking import check_files
from viscorig.stations.forecasting import sequence_forecast, simulated_floors
from viscorig.stations.opening import open_station, runner_options, station_holds
from viscorig.storage import CampaignFile
from viscorig.storage.journal import MAX_TEXT
from viscorig.storage.text import first_control

__all__ = ["API_STATES", "BenchError", "BenchService", "QueueItem"]

#: Every value of ``state`` in ``GET /api/state``.
API_STATES = ("idle", "checking", "waiting_for_operator", "measuring", "pausing", "paused",
              "held", "stopped", "complete", "failed")
#: Sequences the queue may hold.
MAX_QUEUE = 50
_ENGINE_STATES = {EngineState.PAUSING: "pausing", EngineState.PAUSED: "paused",
                  EngineState.HELD: "held"}


class BenchError(Exception):
    """A request the bench cannot take now or at all; ``status`` is the HTTP status."""

    def __init__(self, message: str, status: int = 409) -> None:
        super().__init__(message)
        self.status = status


@dataclass
class QueueItem:
    """A sequence waiting to run, checked and planned when queued."""

    id: str
    sequence: str
    out: str
    problems: list[str] = field(default_factory=list)
    plan_s: float | None = None
    """Predicted test time of the sequence (its lower bound where a step has no upper one)."""
    plan_text: str = ""

    def to_json(self) -> dict[str, Any]:
        return {"id": self.id, "sequence": self.sequence, "out": self.out,
                "problems": list(self.problems), "plan_s": self.plan_s,
                "plan_text": self.plan_text}


class BenchService:
    """The bench: a queue, the run in progress, and the requests of the page.

    Parameters
    ----------
    station_path
        The station file; None for the embedded simulated rig.
    bench
        The hold settings; default: the station's ``[bench]`` (the defaults without one).
    sim_pace
        Embedded simulated rig only: simulated seconds per wall-clock second (None: as fast as
        the computer allows).
    root
        Relative sequence and campaign paths are taken from here (the server's folder).
    """

    def __init__(self, station_path: str | None = None, *, bench: BenchSettings | None = None,
                 sim_pace: float | None = None, root: Path | None = None) -> None:
        self.station_path = station_path
        self.bench_override = bench
        self.sim_pace = sim_pace
        self.root = Path.cwd() if root is None else Path(root)
        self.file_lock = threading.RLock()
        self._lock = threading.RLock()
        self._ids = itertools.count(1)
        self.queue: list[QueueItem] = []
        self.console: PageConsole | None = None
        self.runner: Any = None
        self.opened: Any = None
        """The open station of the run in progress (its ``server`` on the embedded rig)."""
        self.campaign_path: Path | None = None
        self.current: QueueItem | None = None
        self.ended = "idle"
        self.message = ""
        self.problems: list[str] = []
        self._thread: threading.Thread | None = None
        self._checking = False

    # -- the queue --------------------------------------------------------------------------
    def _path(self, text: object, what: str, *, inside: bool = False) -> Path:
        """The path ``text`` names (relative to the bench's folder); with ``inside``, one in
        that folder or below it."""
        if not isinstance(text, str) or not text.strip() or len(text) > 1000 or "\0" in text:
            raise BenchError(f"{what}: a file path (text, at most 1000 characters)", 400)
        path = Path(text.strip())
        path = path if path.is_absolute() else self.root / path
        if not inside:
            return path
        folder = self.root.resolve()
        try:
            within = path.resolve().is_relative_to(folder)
        except (OSError, RuntimeError) as error:  # a name too long, a symbolic-link loop
            raise BenchError(f"{what} {text.strip()}: {getattr(error, 'strerror', None) or error}",
                             400) from None
        if not within:
            raise BenchError(f"{what} {text.strip()}: not in the bench's folder {folder}; the "
                             "bench writes campaign files there and below only", 400)
        return path

    def add(self, sequence: object, out: object) -> QueueItem:
        """Queue a sequence and the campaign file to create; check and plan it now.

        Raises
        ------
        BenchError
            Not a readable sequence, a campaign file that exists or is queued already, a full
            queue.
        """
        sequence_path = self._path(sequence, "sequence")
        out_path = self._path(out, "out", inside=True)
        try:
            if sequence_path.is_dir():
                raise BenchError(f"sequence {sequence_path}: a folder, not a sequence file", 400)
            if not sequence_path.is_file():
                raise BenchError(f"sequence {sequence_path}: no such file", 400)
            if out_path.suffix != ".h5":
                raise BenchError(f"out {out_path}: a campaign file ends with .h5", 400)
            if not out_path.parent.is_dir():
                raise BenchError(f"out {out_path}: folder does not exist", 400)
            exists = out_path.exists()
        except OSError as error:  # a name longer than the file system takes, say
            raise BenchError(f"{error.filename or out_path}: {error.strerror}", 400) from None
        if exists:
            self._continuable(sequence_path, out_path)
        with self._lock:
            taken = [item.out for item in self.queue]
            if self.current is not None:
                taken.append(self.current.out)
            if str(out_path) in taken:
                raise BenchError(f"out {out_path}: already queued", 409)
            if len(self.queue) >= MAX_QUEUE:
                raise BenchError(f"the queue holds {MAX_QUEUE} sequences, the most it may", 409)
        item = QueueItem(str(next(self._ids)), str(sequence_path), str(out_path))
        item.problems, item.plan_s, item.plan_text = self._check(sequence_path)
        with self._lock:
            self.queue.append(item)
        return item

    def _continuable(self, sequence_path: Path, out_path: Path) -> None:
        """An existing campaign file is continued (as ``viscorig resume`` does) when it holds
        this very sequence and was measured on this kind of station.

        Raises
        ------
        BenchError
            It cannot be read, holds another sequence, or was measured elsewhere.
        """
        try:
            with CampaignFile.open(out_path) as campaign:
                stored, station = campaign.sequence_text, campaign.station_text
            given = read_text(sequence_path)
        except InputError as error:
            raise BenchError(single_line(str(error)), 400) from None
        if stored != given:
            raise BenchError(f"out {out_path}: exists and holds another sequence than "
                             f"{sequence_path}; a campaign file is never overwritten", 409)
        if (station is None) != (self.station_path is None):
            where = "the embedded simulated rig" if station is None else "a station file"
            raise BenchError(f"out {out_path}: was measured on {where}; continue it with "
                             f"'viscorig resume {out_path}'", 409)

    def _check(self, sequence_path: Path) -> tuple[list[str], float | None, str]:
        """``check``'s problems and ``plan``'s time of a sequence (nothing touches the rig)."""
        try:
            checked = check_files(str(sequence_path), self.station_path)
        except InputError as error:
            return [single_line(str(error))], None, ""
        if not checked.ok:
            return [single_line(str(problem)) for problem in checked.problems], None, ""
        try:
            forecasts = sequence_forecast(checked.passed(), checked.station)
        except ViscorigError as error:
            return [single_line(str(error))], None, ""
        low = sum(item.low_s for item in forecasts)
        return [], (low if math.isfinite(low) else None), format_forecast(
            forecasts, "predicted test time:")

    def remove(self, item_id: str) -> None:
        """Take a sequence off the queue before it starts.

        Raises
        ------
        BenchError
            No queued item has that id (404).
        """
        with self._lock:
            for index, item in enumerate(self.queue):
                if item.id == item_id:
                    del self.queue[index]
                    return
        raise BenchError(f"queue item {item_id}: not queued", 404)

    def move(self, item_id: str, position: object) -> None:
        """Move a queued sequence to ``position`` (0 is next).

        Raises
        ------
        BenchError
            No queued item has that id (404), or the position is not a whole number.
        """
        if isinstance(position, bool) or not isinstance(position, int):
            raise BenchError("position: a whole number", 400)
        with self._lock:
            for index, item in enumerate(self.queue):
                if item.id == item_id:
                    del self.queue[index]
                    self.queue.insert(max(0, min(position, len(self.queue))), item)
                    return
        raise BenchError(f"queue item {item_id}: not queued", 404)

    # -- running ----------------------------------------------------------------------------
    @property
    def busy(self) -> bool:
        """Is a sequence running (or being prepared)?"""
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Run the queue from its first item.

        Raises
        ------
        BenchError
            Running already, nothing queued, or the first item has problems.
        """
        with self._lock:
            if self.busy:
                raise BenchError("a sequence is running already")
            if not self.queue:
                raise BenchError("nothing is queued: queue a sequence first")
            if self.queue[0].problems:
                raise BenchError(f"{self.queue[0].sequence} has {len(self.queue[0].problems)} "
                                 "problem(s): fix them and queue it again")
            self._checking = True
            self._thread = threading.Thread(target=self._work, name="viscorig-bench",
                                            daemon=True)
            self._thread.start()

    def _work(self) -> None:
        while True:
            with self._lock:
                if not self.queue or self.queue[0].problems:
                    self._checking = False
                    return
                item = self.queue.pop(0)
                self.current = item
                self._checking = True
                self.problems = []
                self.message = ""
            try:
                ended = self._run(item)
            except BenchError as error:
                ended, self.message = "failed", str(error)
            except Exception as error:  # never a traceback on the page: one line
                ended = "failed"
                self.message = single_line(f"{type(error).__name__}: {error}"
                                           if not isinstance(error, ViscorigError)
                                           else str(error))
            with self._lock:
                self.ended = ended
                self.current = None
                self._checking = False
                if ended != "complete":
                    return

    def _run(self, item: QueueItem) -> str:
        checked = check_files(item.sequence, self.station_path)
        if not checked.ok:
            self.problems = [single_line(str(problem)) for problem in checked.problems]
            self.message = "the sequence has problems; nothing was measured"
            return "failed"
        sequence = checked.passed()
        out = Path(item.out)
        if out.exists():
            self._continuable(Path(item.sequence), out)  # continued from its first missing point
        with open_station(sequence, checked.station, self.sim_pace) as opened:
            station = opened.station
            bench = self.bench_override or station.bench
            if out.exists():
                campaign = CampaignFile.open(out, "a")
            else:
                campaign = CampaignFile.create(
                    out, sequence_text=checked.sequence_text, sequence_file=item.sequence,
                    station_text=checked.station_text, station_file=self.station_path or "",
                    rig=station.rig_attributes())
            console = PageConsole()
            holds = station_holds(opened, bench)
            floors = {}
            if opened.simulated:
                floors = simulated_floors(sequence)
            runner = Runner(campaign, sequence, station, opened.analyser, console,
                            runner_options(opened, None), floors=floors, holds=holds,
                            hold_resume=bench.hold_resume, file_lock=self.file_lock)
            console.stop_asked = runner.engine.stop.asked
            with self._lock:
                self.opened, self.console, self.runner = opened, console, runner
                self.campaign_path = out
                self._checking = False
            engine = runner.engine

            def store(text: str) -> object:  # a note from 'viscorig note FILE.h5 TEXT'
                with self.file_lock:
                    return campaign.add_journal_entry("note", text, engine.current_run)

            try:
                with NoteCarrier(out, store, console.warn):
                    result = runner.run()
            finally:
                with self._lock:
                    self.opened = None
                with contextlib.suppress(Exception):
                    campaign.close()
        self.message = result.message
        return {Outcome.COMPLETE: "complete", Outcome.INTERRUPTED: "stopped"}.get(
            result.outcome, "failed")

    def shutdown(self, timeout_s: float = 30.0) -> None:
        """The server stops: abort a run in progress (its data kept) and wait for it."""
        runner, thread = self.runner, self._thread
        with self._lock:
            self.queue.clear()
        if thread is None or not thread.is_alive():
            return
        if runner is not None:
            runner.engine.request_stop("the bench server stopped")
        if self.console is not None:
            self.console.wake()
        thread.join(timeout_s)

    # -- requests while running -----------------------------------------------------------
    def _engine(self):
        runner = self.runner
        if self.busy and self._checking:
            raise BenchError("the sequence is being checked and the rig opened: nothing runs "
                             "yet, ask again in a moment")
        if not self.busy or runner is None:
            raise BenchError("no sequence is running")
        return runner.engine

    def pause(self) -> None:
        """Pause at the point being measured (committed with those before it, the source off)."""
        if not self._engine().request_pause():
            raise BenchError(f"cannot pause: the run is {self.state()['state']}")

    def resume(self) -> None:
        """Go on after a pause or a hold."""
        if not self._engine().request_resume():
            raise BenchError(f"cannot resume: the run is {self.state()['state']}")

    def abort(self) -> None:
        """Stop the run: the segment in flight is dropped, committed points are kept and the
        file can be continued with ``viscorig resume``."""
        engine = self._engine()
        if self.console is not None:
            self.console.say("aborting: committed points are kept")
        engine.request_stop("aborted from the bench page")
        if self.console is not None:
            self.console.wake()

    def answer(self, prompt_id: object, answer: object) -> None:
        """Answer the open operator prompt."""
        console = self.console
        if not self.busy or console is None:
            raise BenchError("no sequence is running")
        if isinstance(prompt_id, bool) or not isinstance(prompt_id, int):
            raise BenchError("prompt_id: a whole number", 400)
        wrong = console.answer(prompt_id, answer if isinstance(answer, str) else "")
        if wrong is not None:
            raise BenchError(wrong, 400 if "answer" in wrong else 409)

    def note(self, text: object) -> dict[str, str]:
        """Store a note with its time in the campaign file of the run in progress (or of the
        last one run)."""
        if not isinstance(text, str) or not text.strip():
            raise BenchError("text: the note, not empty", 400)
        if len(text) > MAX_TEXT:
            raise BenchError(f"text: {len(text)} characters; at most {MAX_TEXT}", 400)
        control = first_control(text)
        if control is not None:
            raise BenchError(f"text: holds the control character {control!r}; a note holds "
                             "text, line breaks and tabs", 400)
        path = self.campaign_path
        if path is None or not path.exists():
            raise BenchError("no campaign file yet: a note is stored in the file of a run")
        engine = self.runner.engine if self.runner is not None and self.busy else None
        with self.file_lock:
            if engine is not None:
                entry = engine.campaign.add_journal_entry("note", text, engine.current_run)
            else:
                with CampaignFile.open(path, "a") as campaign:
                    entry = campaign.add_journal_entry("note", text)
        return {"time_utc": entry.time_utc, "run": entry.run, "text": entry.text}

    # -- what the page shows -----------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """``GET /api/state`` (the keys of the contract, then what the page adds)."""
        with self._lock:
            console, runner = self.console, self.runner
            busy = self.busy
            view: ConsoleView = console.snapshot() if console is not None else {}
            engine = runner.engine if runner is not None else None
            if busy and (self._checking or engine is None):
                state = "checking"
            elif busy and engine is not None:  # the branch above took busy without an engine
                state = _ENGINE_STATES.get(engine.state, "measuring")
                if view.get("prompt") is not None and state == "measuring":
                    state = "waiting_for_operator"
            else:
                state = self.ended
            points_done = int(view.get("points_done", 0))
            if engine is not None and engine.committed[0] == view.get("run"):
                points_done = max(points_done, engine.committed[1])
            queue = [item.to_json() for item in self.queue]
            problems = list(self.problems) or (list(self.queue[0].problems) if self.queue
                                               and not busy else [])
            return {
                "state": state,
                "campaign": None if self.campaign_path is None else str(self.campaign_path),
                "run": view.get("run") or None,
                "points_done": points_done,
                "points_total": int(view.get("points_total", 0)),
                "prompt": view.get("prompt") if busy else None,
                "held_because": engine.held_because if busy and engine is not None else None,
                "queue": queue,
                "problems": problems,
                "message": self.message,
                "frequency_hz": view.get("frequency_hz"),
                "run_left_s": view.get("run_left_s"),
                "flagged": view.get("flagged", 0),
                "messages": view.get("messages", []),
                "sequence": None if self.current is None else self.current.sequence,
            }
