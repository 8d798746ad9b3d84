"""The engine's loop with the vehicles' own stacks in worker processes (`testbench run
--processes N`).

Why it can be split: a vehicle's sensors, navigation aids, navigator and controller read
nothing of another vehicle but the truth its sensors sample (no data link between vehicles),
so at each tick the stacks of different vehicles are independent given every vehicle's truth.
The main process keeps the dynamics (JSBSim), the recorder, the formation score, pacing and
progress, and flies the stacks of one group of vehicles; each worker process those of another.

How: after `Engine.start()` the main process forks the workers, so each starts with the same
built and initialised stacks, world and random streams as the main process has. At each tick
where anything runs, the main process reads every vehicle's truth and sends it to every worker,
then runs its own group. Each group runs the tick's sensing and control exactly as
`Engine.run` does (in a worker the dynamics are replaced by the truths it was sent), with its
recorder calls logged, and gives back, per vehicle, those calls in the order they were made,
the new command, and at a record tick the estimate, guidance status and GNSS flag of the
telemetry row. The main process replays the calls vehicle by vehicle in scenario order (the
order `Engine.run` makes them in), so the record is byte for byte the same as a single-process run's where the
rendered imagery does not depend on which vehicles' cameras asked for it first (maps read
whole: every procedural world and map up to RunWorld's window limit).

Limits: fork start only (Linux; not inside a daemonic Monte Carlo worker); no frame sink. A
run that ends in an abort (a vehicle on the ground, a diverging filter) keeps the record up to
the tick before the one it failed in; a single-process run also keeps what the vehicles before
the failing one recorded in that tick.
"""

from __future__ import annotations

import multiprocessing as mp
import traceback
from typing import Any

from testbench.core.errors import InputError, SimulationAborted
from testbench.sim.world_runtime import _LazyTruths


class _TruthFeed:
    """Stands in for a vehicle's dynamics in a worker: truth() is what the main process sent."""

    def __init__(self) -> None:
        self.current = None

    def truth(self):
        return self.current


class _CallLog:
    """Stands in for the Recorder in a worker: its calls, kept in order for the main process."""

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


def _worker(conn, engine, ids: list[str]) -> None:
    """A worker's loop: (k, t_s, truths, record_due) in, per vehicle (calls, command, row) out."""
    feeds = {v.id: _TruthFeed() for v in engine.vehicles}
    for v in engine.vehicles:  # every vehicle: another's truth is what a camera or UWB samples
        v.dynamics = feeds[v.id]
    log = _CallLog()
    engine.recorder = log
    truths = _LazyTruths({vid: f.truth for vid, f in feeds.items()})
    mine = [engine.by_id[i] for i in ids]
    while True:
        msg = conn.recv()
        if msg is None:
            return
        k, t_s, tick_truths, record_due = msg
        for vid, tr in tick_truths.items():
            feeds[vid].current = tr
        try:
            out = _tick_group(engine, mine, k, t_s, truths, record_due, log)
        except SimulationAborted as exc:
            conn.send(("aborted", (exc.reason, exc.t_s, exc.vehicle_id)))
            return
        except BaseException:  # noqa: BLE001 -- handed to the main process, which raises it
            conn.send(("error", traceback.format_exc()))
            return
        conn.send(("ok", out))


class WorkerError(RuntimeError):
    """A worker process failed with an exception that is not a flight outcome (its traceback)."""


def run_parallel(engine, processes: int):
    """Engine.run's loop with the vehicles' stacks in `processes` processes: the main one and
    processes - 1 workers (see the module docstring); returns the EngineResult. Vehicles go to
    the processes in turn (vehicle i to process i % processes, the main process first), and
    the main process flies its group while the workers fly theirs."""
    from testbench.sim.engine import Pacer

    if "fork" not in mp.get_all_start_methods():
        raise InputError("--processes: worker processes need the fork start method (Linux); expected --processes 1 here")
    ctx = mp.get_context("fork")
    rec = engine.recorder
    pacer = Pacer(engine)
    k = 0
    aborted: BaseException | None = None
    workers: list[tuple[Any, Any]] = []
    log = _CallLog()
    try:
        engine.start()
        n = max(1, min(int(processes), len(engine.vehicles)))
        groups = [[v.id for i, v in enumerate(engine.vehicles) if i % n == w] for w in range(n)]
        main_group = [engine.by_id[i] for i in groups[0]]
        for ids in groups[1:]:
            parent, child = ctx.Pipe()
            p = ctx.Process(target=_worker, args=(child, engine, ids), daemon=True)
            p.start()
            child.close()
            workers.append((p, parent))
        while True:
            t_s = k * engine.dt_s
            record_due = k % engine.record_every == 0
            truths = {v.id: v.dynamics.truth() for v in engine.vehicles}
            for _, conn in workers:
                conn.send((k, t_s, truths, record_due))
            engine.recorder = log  # the main group's calls too wait for their turn in the record
            try:
                out = _tick_group(engine, main_group, k, t_s, truths, record_due, log)
            finally:
                engine.recorder = rec
            for p, conn in workers:
                try:
                    status, payload = conn.recv()
                except EOFError:
                    raise WorkerError(f"a vehicle worker process ended (exit code {p.exitcode})") from None
                if status == "aborted":
                    msg, at_s, vid = payload
                    raise SimulationAborted(msg, t_s=at_s if at_s is not None else t_s, vehicle_id=vid)
                if status == "error":
                    raise WorkerError(f"a vehicle worker process failed:\n{payload}")
                out.update(payload)
            for v in engine.vehicles:  # scenario order: the record's order
                calls, command, _ = out[v.id]
                for name, args, kwargs in calls:
                    getattr(rec, name)(*args, **kwargs)
                if command is not None:
                    v.command = command
            if record_due:
                engine._record_tick(t_s, ((v, truths[v.id], *out[v.id][2]) for v in engine.vehicles))
            if k >= engine.n_ticks:
                break
            k = engine._advance(k)
            pacer.after(k)
    except Exception as exc:  # noqa: BLE001 -- classified by the runner
        aborted = exc
    finally:
        for p, conn in workers:
            try:
                conn.send(None)
            except (BrokenPipeError, OSError):
                pass
            conn.close()
        for p, _ in workers:
            p.join(timeout=5.0)
            if p.is_alive():
                p.terminate()
    return pacer.result(k, aborted)
