"""The engine's loop with the vehicles split over processes (`testbench run --processes N`).

Why it can be split: a vehicle's dynamics, sensors, navigation aids, navigator and controller
read nothing of another vehicle but the truth its sensors sample (no data link between
vehicles, and no vehicle's flight dynamics depend on another's), so at each tick the vehicles
of different groups are independent given every vehicle's truth at that tick.

How: after `Engine.start()` the main process forks the workers, so each starts with the same
built and initialised vehicles, world and random streams as the main process has. Vehicle i
belongs to process i % N (the main process is process 0); each process steps the JSBSim
models of its own vehicles and, at each tick where anything runs, runs their sensing and
control exactly as `Engine.run` does. The only exchange is the tick's truths: each worker
sends its own vehicles' truths to the main process, which answers with every other vehicle's
(its own and the other workers'); everyone else's dynamics are stand-ins holding what was
sent. The recorder stays in the main process. A process logs its recorder calls, and a worker
hands them, with its new commands and at a record tick the estimate, guidance status and GNSS
flag of each telemetry row, to the main process with its next truths; the main process then
replays the tick's calls vehicle by vehicle in scenario order (the order `Engine.run` makes them
in), then the telemetry rows and the formation's errors. So the record is byte for byte a
single-process run's where the rendered imagery does not depend on which vehicles' cameras
asked for it first (maps read whole: every procedural world and map up to RunWorld's window
limit), and each process waits only for the truths of the tick, not for the others' records.

Limits: fork start only (Linux; not inside a daemonic Monte Carlo worker); no frame sink. A
run that ends in a flight abort keeps what a single-process run keeps when the dynamics fail
(a vehicle on the ground, NaN: the record up to that tick); when sensing or control fails (a
diverging filter) it keeps the record up to the tick before, where a single-process run also
keeps what the vehicles before the failing one recorded in that tick. After the run, every
vehicle's `dynamics.truth()` in the main process is its truth at the last tick.
"""

from __future__ import annotations

import multiprocessing as mp
import traceback
from typing import Any

from testbench.core.errors import InputError, SimulationAborted
from testbench.sim.world_runtime import _LazyTruths


class _TruthFeed:
    """Stands in for another process's vehicle's dynamics: truth() is what was last sent;
    anything else (aircraft_meta, ...) is the vehicle's own adapter's, which this process
    does not step."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.current = None

    def truth(self):
        return self.current

    def advance(self, *args, **kwargs):
        raise RuntimeError("a vehicle of another process's group was stepped here")

    def __getattr__(self, name: str):
        return getattr(self.inner, name)


def _install_feeds(engine, own_ids: set[str]) -> dict[str, _TruthFeed]:
    """Replace the dynamics of every vehicle not in own_ids by a _TruthFeed; returns them."""
    feeds = {}
    for v in engine.vehicles:
        if v.id not in own_ids:
            feeds[v.id] = v.dynamics = _TruthFeed(v.dynamics)
    return feeds


class _CallLog:
    """Stands in for the Recorder while a group runs its tick: its calls, kept in order until
    the main process replays them."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple, dict]] = []

    def correction(self, *args, **kwargs) -> None:
        self.calls.append(("correction", args, kwargs))

    def event(self, *args, **kwargs) -> None:
        self.calls.append(("event", args, kwargs))

    def artifact(self, *args, **kwargs) -> None:
        self.calls.append(("artifact", args, kwargs))


def _tick_group(engine, group: list, k: int, t_s: float, truths, record_due: bool, log: _CallLog) -> dict[str, list]:
    """Tick k of Engine.run for the vehicles of `group` (sensing, then control), their
    recorder calls into `log`: vehicle id -> [calls, the new command or None, at a record tick
    (estimate, guidance status, GNSS flag) of the telemetry row or None]."""
    out: dict[str, list] = {}
    for v in group:
        log.calls = []
        engine._sense(v, k, t_s, truths)
        out[v.id] = [log.calls, None, None]
    for v in group:
        if engine._control(v, k, t_s):
            out[v.id][1] = v.command
    if record_due:
        for v in group:
            out[v.id][2] = (v.navigator.estimate(), v.controller.status(), engine._gnss_available(v, t_s))
    return out


def _abort_info(exc: SimulationAborted) -> tuple:
    return (exc.reason, exc.t_s, exc.vehicle_id)


def _worker(conn, engine, ids: list[str]) -> None:
    """A worker's loop. Out: ("ok", its truths at this tick, its previous tick's results), or
    ("done", None, the last tick's results), ("aborted", (reason, t_s, vehicle id), the tick's
    results or None), ("error", traceback). In: (k, t_s, record_due, the other vehicles'
    truths), or None to stop."""
    feeds = _install_feeds(engine, set(ids))
    log = _CallLog()
    engine.recorder = log
    truths = _LazyTruths(engine._truth_getters())
    mine = [engine.by_id[i] for i in ids]
    previous = None
    try:
        while True:
            conn.send(("ok", {v.id: v.dynamics.truth() for v in mine}, previous))
            msg = conn.recv()
            if msg is None:
                return
            k, t_s, record_due, others = msg
            for vid, tr in others.items():
                feeds[vid].current = tr
            out = None
            try:
                out = _tick_group(engine, mine, k, t_s, truths, record_due, log)
                if k >= engine.n_ticks:
                    conn.send(("done", None, out))
                    conn.recv()  # the main process's None
                    return
                engine._advance(k, mine)
            except SimulationAborted as exc:
                conn.send(("aborted", _abort_info(exc), out))
                conn.recv()
                return
            previous = out
    except BaseException:  # noqa: BLE001 -- handed to the main process, which raises it
        try:
            conn.send(("error", traceback.format_exc()))
        except (BrokenPipeError, OSError):
            pass


class WorkerError(RuntimeError):
    """A worker process failed with an exception that is not a flight outcome (its traceback)."""


class _Workers:
    """The main process's end of the worker processes (process, connection, vehicle ids)."""

    def __init__(self) -> None:
        self.items: list[tuple[Any, Any, set[str]]] = []

    def receive(self, tick_s: float) -> tuple[list[dict], list, SimulationAborted | None]:
        """Every worker's next message: (their truths, their results of the tick before, the
        first flight abort a worker reports or None); raises WorkerError for a failed worker."""
        truths, results, aborted = [], [], None
        for p, conn, _ in self.items:
            try:
                msg = conn.recv()
            except EOFError:
                raise WorkerError(f"a vehicle worker process ended (exit code {p.exitcode})") from None
            if msg[0] == "error":
                raise WorkerError(f"a vehicle worker process failed:\n{msg[1]}")
            status, payload, out = msg
            if status == "aborted" and aborted is None:
                reason, at_s, vid = payload
                aborted = SimulationAborted(reason, t_s=at_s if at_s is not None else tick_s, vehicle_id=vid)
            if status == "ok":
                truths.append(payload)
            results.append(out)
        return truths, results, aborted

    def stop(self) -> None:
        for p, conn, _ in self.items:
            try:
                conn.send(None)
            except (BrokenPipeError, OSError):
                pass
            conn.close()
        for p, _, _ in self.items:
            p.join(timeout=5.0)
            if p.is_alive():
                p.terminate()


def _replay(engine, rec, tick: tuple, worker_results: list) -> None:
    """Write a tick's record: every vehicle's recorder calls in scenario order, then (at a
    record tick) the telemetry rows and the formation's errors, from that tick's truths.
    tick = (t_s, record_due, the main group's results, every vehicle's truth)."""
    t_s, record_due, out, truths = tick
    out = dict(out)
    for r in worker_results:
        if r is None:
            return  # a worker failed in this tick's sensing or control: the tick is not kept
        out.update(r)
    for v in engine.vehicles:  # scenario order: the record's order
        calls, command, _ = out[v.id]
        for name, args, kwargs in calls:
            getattr(rec, name)(*args, **kwargs)
        if command is not None:
            v.command = command
    if record_due:
        engine._record_tick(t_s, ((v, truths[v.id], *out[v.id][2]) for v in engine.vehicles), truths)


def run_parallel(engine, processes: int):
    """Engine.run's loop with the vehicles in `processes` processes: the main one and
    processes - 1 workers (see the module docstring); returns the EngineResult. Vehicles go to
    the processes in turn (vehicle i to process i % processes, the main process first)."""
    from testbench.sim.engine import Pacer

    if "fork" not in mp.get_all_start_methods():
        raise InputError("--processes: worker processes need the fork start method (Linux); expected --processes 1 here")
    ctx = mp.get_context("fork")
    rec = engine.recorder
    pacer = Pacer(engine)
    k = 0
    aborted: BaseException | None = None
    workers = _Workers()
    log = _CallLog()
    try:
        engine.start()
        n = max(1, min(int(processes), len(engine.vehicles)))
        groups = [[v.id for i, v in enumerate(engine.vehicles) if i % n == w] for w in range(n)]
        for ids in groups[1:]:
            parent, child = ctx.Pipe()
            p = ctx.Process(target=_worker, args=(child, engine, ids), daemon=True)
            p.start()
            child.close()
            workers.items.append((p, parent, set(ids)))
        feeds = _install_feeds(engine, set(groups[0]))  # after the fork: the workers keep theirs
        main_group = [engine.by_id[i] for i in groups[0]]
        truths = _LazyTruths(engine._truth_getters())
        waiting, k_waiting = None, k  # the last tick whose record waits for the workers' results
        while True:
            t_s = k * engine.dt_s
            record_due = k % engine.record_every == 0
            tick_truths = {v.id: v.dynamics.truth() for v in main_group}  # before the wait: off the workers' path
            theirs, results, worker_abort = workers.receive(t_s)
            if worker_abort is not None:
                # It failed in the last tick (its sensing, control or dynamics); so the run ends
                # at that tick, as a single-process run would.
                if waiting is not None:
                    _replay(engine, rec, waiting, results)
                    k = k_waiting
                raise worker_abort
            for t in theirs:
                tick_truths.update(t)
            for p, conn, ids in workers.items:
                conn.send((k, t_s, record_due, {vid: tr for vid, tr in tick_truths.items() if vid not in ids}))
            for vid, feed in feeds.items():
                feed.current = tick_truths[vid]
            if waiting is not None:  # while the workers run this tick
                _replay(engine, rec, waiting, results)
            engine.recorder = log  # the main group's calls too wait for their turn in the record
            try:
                out = _tick_group(engine, main_group, k, t_s, truths, record_due, log)
            finally:
                engine.recorder = rec
            waiting, k_waiting = (t_s, record_due, out, tick_truths), k
            if k >= engine.n_ticks:
                _, results, worker_abort = workers.receive(t_s)  # "done": the last tick's results
                _replay(engine, rec, waiting, results)
                if worker_abort is not None:
                    raise worker_abort
                break
            try:
                k_next = engine._advance(k, main_group)
            except SimulationAborted as own_abort:
                # The tick is kept as a single-process run keeps it: wait for the workers' part.
                _, results, worker_abort = workers.receive(t_s)
                _replay(engine, rec, waiting, results)
                raise _first_in_scenario(engine, own_abort, worker_abort) from None
            k = k_next
            pacer.after(k)
    except Exception as exc:  # noqa: BLE001 -- classified by the runner
        aborted = exc
    finally:
        workers.stop()
    return pacer.result(k, aborted)


def _first_in_scenario(engine, a: SimulationAborted, b: SimulationAborted | None) -> SimulationAborted:
    """Of two dynamics aborts in one tick, the one a single-process run meets first (its
    vehicles step in scenario order)."""
    if b is None:
        return a
    order = {v.id: i for i, v in enumerate(engine.vehicles)}
    return a if order.get(a.vehicle_id, 0) <= order.get(b.vehicle_id, 0) else b
