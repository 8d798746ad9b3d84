"""The deterministic multi-rate engine.

Time advances in physics ticks of 1/physics_rate_hz. Every loop (each sensor, each vehicle's
control, the recorder) runs every N ticks (N an integer: rates that do not divide the physics
rate are rejected when the vehicle is built). At a tick where anything runs, for every vehicle
in scenario order:
  1. sensors sample the truth at the tick (IMU first, so the navigator predicts before it
     corrects); navigation aids turn raw outputs into navigator measurements; a measurement an
     aid makes late (its onboard processing time: IsmnAid latency_s) is held, and reaches the
     navigator at the first tick at or after it is due, stamped with the time it was taken;
  2. the controller turns the navigator's estimate into the command held until its next tick;
  3. the recorder writes truth and estimate side by side.
Then every vehicle's dynamics advance to the next tick where anything runs (JSBSim steps in a
tight loop in between). All vehicles sample at the same tick before any of them advances, so a
sensor that looks at another vehicle sees it at the same time.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from functools import reduce
from typing import Any, Callable, Mapping

import numpy as np

from testbench.core.errors import InputError
from testbench.core.messages import GnssFix, ImuSample
from testbench.sim.recorder import Recorder
from testbench.sim.vehicle import VehicleRuntime, initial_estimate
from testbench.sim.world_runtime import RunWorld, TickWorldView, _LazyTruths

log = logging.getLogger(__name__)

# Below this leader ground speed the formation-scoring course is held (see _record_formation).
_FORMATION_COURSE_MIN_SPEED_MPS = 1.0


@dataclass
class EngineResult:
    """How the loop ended: simulated and wall time, pacing lag, and the abort if any."""

    sim_time_s: float
    wall_time_s: float
    ticks: int
    max_realtime_lag_s: float
    aborted: BaseException | None = None


class Pacer:
    """The loop's wall clock: progress about once per simulated second, pacing to the wall
    clock with the largest lag kept (engine.realtime), and the EngineResult at the end."""

    def __init__(self, engine: "Engine"):
        self.engine = engine
        self.t_wall0 = time.perf_counter()
        self.max_lag_s = 0.0
        self._next_progress_s = 1.0

    def after(self, k: int) -> None:
        """Called once the dynamics reached tick k."""
        e = self.engine
        t_s = k * e.dt_s
        if e.on_progress is not None and t_s >= self._next_progress_s:
            e.on_progress(t_s)
            self._next_progress_s = math.floor(t_s) + 1.0
        if e.realtime:
            lag = (time.perf_counter() - self.t_wall0) - t_s
            if lag < 0.0:
                time.sleep(-lag)
            else:
                self.max_lag_s = max(self.max_lag_s, lag)

    def result(self, k: int, aborted: BaseException | None) -> EngineResult:
        wall = time.perf_counter() - self.t_wall0
        return EngineResult(sim_time_s=k * self.engine.dt_s, wall_time_s=wall, ticks=k,
                            max_realtime_lag_s=self.max_lag_s, aborted=aborted)


class Engine:
    """Runs vehicles for duration_s at physics_rate_hz and records them at record_rate_hz.

    on_progress(t_s) is called about once per simulated second; realtime paces the loop to
    the wall clock (max lag reported); frame_sink(vehicle_id, sensor_name, frame) receives
    every camera-like measurement (for --save-frames); processes > 1 runs the vehicles' own
    stacks in that many processes, this one and processes - 1 forked workers (sim/parallel.py;
    not with a frame sink).
    """

    def __init__(
        self,
        vehicles: list[VehicleRuntime],
        world: RunWorld,
        physics_rate_hz: float,
        duration_s: float,
        record_every: int,
        recorder: Recorder,
        *,
        realtime: bool = False,
        on_progress: Callable[[float], None] | None = None,
        frame_sink: Callable[[str, str, Any], None] | None = None,
        formation: Any = None,
        processes: int = 1,
    ):
        if processes > 1 and frame_sink is not None:
            raise InputError("--processes: frames cannot be saved (--save-frames) from worker processes; "
                             "expected --processes 1 with --save-frames")
        self.processes = int(processes)
        self.vehicles = vehicles
        self.by_id = {v.id: v for v in vehicles}
        self.formation = formation
        self._formation_course_rad: float | None = None  # scoring's leader course (held at low speed)
        self._leader_trail = None  # scoring's leader path (column formations)
        self.world = world
        self.dt_s = 1.0 / physics_rate_hz
        self.n_ticks = int(round(duration_s * physics_rate_hz))
        self.record_every = record_every
        self.recorder = recorder
        self.realtime = realtime
        self.on_progress = on_progress
        self.frame_sink = frame_sink
        periods = [record_every] + [v.control_every for v in vehicles] + [s.every for v in vehicles for s in v.sensors]
        self._gcd = reduce(math.gcd, periods)

    def _truth_getters(self) -> dict[str, Callable]:
        return {v.id: v.dynamics.truth for v in self.vehicles}

    def start(self) -> None:
        """Reset dynamics to the initial conditions and initialise navigators."""
        from testbench.sim.vehicle import initial_condition

        for v in self.vehicles:
            truth = v.dynamics.reset(initial_condition(v.spec, self.world.origin))
            v.navigator.initialize(0.0, initial_estimate(truth))

    def run(self) -> EngineResult:
        """The loop; a SimulationAborted ends it early and is returned, not raised."""
        if self.processes > 1 and len(self.vehicles) > 1:
            from testbench.sim.parallel import run_parallel

            return run_parallel(self, self.processes)
        truths = _LazyTruths(self._truth_getters())
        pacer = Pacer(self)
        k = 0
        aborted: BaseException | None = None
        try:
            self.start()
            while True:
                t_s = k * self.dt_s
                for v in self.vehicles:
                    self._sense(v, k, t_s, truths)
                for v in self.vehicles:
                    self._control(v, k, t_s)
                if k % self.record_every == 0:
                    self._record_tick(t_s, ((v, v.dynamics.truth(), v.navigator.estimate(), v.controller.status(),
                                             self._gnss_available(v, t_s)) for v in self.vehicles))
                if k >= self.n_ticks:
                    break
                k = self._advance(k)
                pacer.after(k)
        except Exception as exc:  # noqa: BLE001 -- classified by the runner
            aborted = exc
        return pacer.result(k, aborted)

    def _control(self, v: VehicleRuntime, k: int, t_s: float) -> bool:
        """At a tick of v's control rate its controller turns the estimate into the command
        held until the next one (True); otherwise nothing (False)."""
        if k % v.control_every:
            return False
        v.command = v.controller.update(t_s, v.navigator.estimate(), self._reference(v, t_s))
        return True

    def _record_tick(self, t_s: float, rows) -> None:
        """The telemetry rows of a record tick, rows (vehicle, truth, estimate, guidance status,
        GNSS flag) in scenario order, then the formation's slot errors."""
        for v, truth, est, status, gnss_ok in rows:
            self.recorder.record(v.id, truth, est, v.command_values(), status, gnss_available=gnss_ok)
        if self.formation is not None:
            self._record_formation(t_s)

    @staticmethod
    def _gnss_available(v: VehicleRuntime, t_s: float) -> bool:
        """Whether v fused a GNSS fix within its GNSS timeout (telemetry column gnss_available)."""
        return (t_s - v.last_gnss_t_s) <= v.gnss_timeout_s

    def _advance(self, k: int) -> int:
        """Every vehicle's dynamics to the next tick where anything runs; returns that tick."""
        step = min(self._gcd - (k % self._gcd), self.n_ticks - k)
        for v in self.vehicles:
            v.dynamics.advance(v.command, step)
        return k + step

    def _sense(self, v: VehicleRuntime, k: int, t_s: float, truths: Mapping) -> None:
        view = None
        for slot in v.sensors:
            if k % slot.every:
                continue
            truth = v.dynamics.truth()
            if view is None:
                view = TickWorldView(self.world, t_s, v.id, truths, lambda v=v, t_s=t_s: self._render_requests(v, t_s))
            m = slot.sensor.measure(truth, view, slot.rng)
            if slot.event_rows is not None:
                for table, row in slot.event_rows(v.id):
                    self.recorder.event(table, **row)
            if m is None:
                continue
            if isinstance(m, ImuSample):
                v.navigator.predict(m)
                continue
            if self.frame_sink is not None and hasattr(m, "image"):
                self.frame_sink(v.id, slot.name, m)
            self._deliver(v, m)
        if v.in_flight:
            self._land(v, t_s, final=k >= self.n_ticks)

    def _deliver(self, v: VehicleRuntime, m: Any) -> None:
        """Give a measurement to the aids that want it, then everything to the navigator; then
        record what the aids did (with truth filled in here, the only place it meets them).
        What an aid makes late (its attempt's deliver_t_s after the measurement's time) is held
        in v.in_flight instead, its rows filled with the truth of now, when its frame was taken."""
        outputs = [m]
        attempts = []
        for aid in v.aids:
            if aid.accepts(m):
                produced, diag = aid.process(m, v.navigator.estimate())
                due_s = getattr(diag, "deliver_t_s", None)
                if due_s is not None and due_s > float(m.t_s) + 1e-9:
                    self._hold(v, due_s, produced, diag)
                    continue
                if diag is not None and not produced and v.in_flight:
                    # An attempt without output (a frame skipped while another is in
                    # processing) waits behind the one in flight: rows stay in frame order.
                    self._hold(v, v.in_flight[-1][0], [], diag)
                    continue
                outputs.extend(produced)
                attempts.append((diag, produced))
        self._fuse(v, outputs, attempts)

    def _hold(self, v: VehicleRuntime, due_s: float, produced: list, diag: Any) -> None:
        """Keep an aid's late output until due_s: its event rows made now (truth of now), the
        navigator told to keep what it needs to fuse measurements of this time later."""
        rows = []
        for table, row in diag.event_rows(v.id):
            self._fill_truth(row, v)
            rows.append((table, row))
        for name, arrays in getattr(diag, "artifacts", lambda: [])():
            self.recorder.artifact(name, arrays)
        expect = getattr(v.navigator, "expect", None)  # ("module:Class" navigators may lack it)
        for out in produced if expect is not None else ():
            expect(float(out.t_s))
        v.in_flight.append((float(due_s), produced, rows))
        v.in_flight.sort(key=lambda item: item[0])  # stable: equal due times keep their order

    def _land(self, v: VehicleRuntime, t_s: float, final: bool) -> None:
        """Give the navigator the held outputs due by t_s, then record their rows with its
        verdicts. At the run's last tick the rest are recorded as never fused (accepted False,
        delivered_t_s NaN, reason 'in flight at the end of the run')."""
        while v.in_flight and (final or v.in_flight[0][0] <= t_s + 1e-9):
            due_s, produced, rows = v.in_flight.pop(0)
            infos = self._correct_all(v, produced) if due_s <= t_s + 1e-9 else None
            verdicts = None if infos is None else [infos[id(p)].accepted for p in produced if id(p) in infos]
            for table, row in rows:
                _set_verdict(row, verdicts)
                if infos is None and row.get("fix"):
                    row["reason"] = "in flight at the end of the run"
                    if "delivered_t_s" in row:
                        row["delivered_t_s"] = math.nan
                self.recorder.event(table, **row)

    def _fuse(self, v: VehicleRuntime, outputs: list, attempts: list) -> None:
        """outputs to the navigator, then the attempts' rows with its verdicts and truth."""
        infos = self._correct_all(v, outputs)
        for diag, produced in attempts:
            if diag is None:
                continue
            verdicts = [infos[id(p)].accepted for p in produced if id(p) in infos]
            for table, row in diag.event_rows(v.id):
                _set_verdict(row, verdicts)
                self._fill_truth(row, v)
                self.recorder.event(table, **row)
            for name, arrays in getattr(diag, "artifacts", lambda: [])():
                self.recorder.artifact(name, arrays)

    def _correct_all(self, v: VehicleRuntime, outputs: list) -> dict[int, Any]:
        """Each output to the navigator in order, its corrections recorded; id(output) -> the
        first correction (the measurement's own verdict)."""
        infos: dict[int, Any] = {}
        for out in outputs:
            if isinstance(out, GnssFix):
                v.last_gnss_t_s = out.t_s
            info = v.navigator.correct(out)
            if info is None:
                continue
            # Several corrections from one measurement (a fix that also carries a heading): the
            # first is the measurement's own verdict; all are recorded.
            several = info if isinstance(info, tuple) else (info,)
            infos[id(out)] = several[0]
            for one in several:
                self.recorder.correction(v.id, one)
        return infos

    def _fill_truth(self, row: dict[str, Any], v: VehicleRuntime) -> None:
        """Fill an aid's truth placeholders (truth_* columns) from the dynamics at this tick:
        relative truth (peer minus self, NED) for rows with a peer_id, else the vehicle's own."""
        if "truth_north_m" not in row:
            return
        me = v.dynamics.truth()
        peer = self.by_id.get(row.get("peer_id")) if "peer_id" in row else None
        if "peer_id" in row:
            rel = peer.dynamics.truth().pos_ned_m - me.pos_ned_m if peer is not None else (math.nan,) * 3
            row["truth_north_m"], row["truth_east_m"], row["truth_down_m"] = (float(x) for x in rel)
            return
        row["truth_north_m"], row["truth_east_m"], row["truth_down_m"] = (float(x) for x in me.pos_ned_m)
        if "footprint_north_min_m" in row:
            self._fill_map_error(row)
        if "truth_roll_rad" in row:
            row["truth_roll_rad"] = float(me.rpy_rad[0])
        if "truth_height_agl_m" in row:
            row["truth_height_agl_m"] = float(me.height_agl_m)

    def _fill_map_error(self, row: dict[str, Any]) -> None:
        """truth_map_error_{north,east}_m of a scene-matching row when the carried map is off
        its georeference (world.reference_map_error): the map's displacement averaged over the
        footprint the row's fix was matched in (a 5 x 5 grid over its predicted bounds), what the
        fix inherits from the map; NaN without a footprint. No columns without a map error."""
        if self.world.spec.reference_map_error is None:
            return
        n0, n1, e0, e1 = (row[f"footprint_{k}_m"] for k in ("north_min", "north_max", "east_min", "east_max"))
        if not all(math.isfinite(x) for x in (n0, n1, e0, e1)):
            row["truth_map_error_north_m"] = row["truth_map_error_east_m"] = math.nan
            return
        s = np.linspace(0.0, 1.0, 5)
        d = self.world.map_displacement_ne_m(n0 + (n1 - n0) * s[:, None], e0 + (e1 - e0) * s[None, :])
        d_n, d_e = (0.0, 0.0) if d is None else (float(np.mean(d[0])), float(np.mean(d[1])))
        row["truth_map_error_north_m"], row["truth_map_error_east_m"] = d_n, d_e

    @staticmethod
    def _render_requests(v: VehicleRuntime, t_s: float) -> dict[str, list] | None:
        """Regions the vehicle's aids want its cameras to render now (None: no wishes)."""
        merged: dict[str, list] | None = None
        for aid in v.aids:
            fn = getattr(aid, "render_requests", None)
            if fn is not None:
                merged = {**(merged or {}), **fn(t_s)}
        return merged

    @staticmethod
    def _reference(v: VehicleRuntime, t_s: float) -> Any:
        """What the vehicle's aids hand its controller (e.g. the relnav NeighbourTable)."""
        ref = None
        for aid in v.aids:
            fn = getattr(aid, "controller_input", None)
            if fn is not None:
                out = fn(t_s)
                if out is not None:
                    ref = out
        return ref

    def _record_formation(self, t_s: float) -> None:
        """Slot errors from TRUTH: each vehicle minus (leader + R(leader course) (slot - slot_leader));
        for a column (formation.kind), each vehicle minus its place on the leader's true path
        (trail.column_errors).

        The leader's course is its ground-track direction; below 1 m/s ground speed (hover,
        start-up) the track direction is noise, so the last course is held, starting from the
        leader's heading (the followers' controller does the same with its estimates).
        """
        from testbench.control.formation import formation_errors
        from testbench.control.trail import Trail, column_errors

        f = self.formation
        leader = self.by_id[f.leader].dynamics.truth()
        pos = {vid: self.by_id[vid].dynamics.truth().pos_ned_m for vid in f.slots}
        slots = {k: tuple(s) for k, s in f.slots.items()}
        if f.kind == "column":
            # The leader's true path, started as a straight line behind it along its heading.
            if self._leader_trail is None:
                back_m = max(slots[f.leader][0] - s[0] for s in slots.values()) + 100.0
                self._leader_trail = Trail(crumb_m=0.5, keep_m=back_m + 500.0)
                self._leader_trail.seed(leader.pos_ned_m, float(leader.rpy_rad[2]), back_m)
            self._leader_trail.extend(leader.pos_ned_m)
            errors = column_errors(pos, self._leader_trail, slots, f.leader)
        else:
            if math.hypot(leader.vel_ned_mps[0], leader.vel_ned_mps[1]) >= _FORMATION_COURSE_MIN_SPEED_MPS:
                self._formation_course_rad = math.atan2(leader.vel_ned_mps[1], leader.vel_ned_mps[0])
            elif self._formation_course_rad is None:
                self._formation_course_rad = float(leader.rpy_rad[2])
            errors = formation_errors(pos, self._formation_course_rad, slots, f.leader)
        for vid, err in errors.items():
            self.recorder.event(
                "formation", t_s=t_s, vehicle_id=vid,
                slot_error_north_m=float(err[0]), slot_error_east_m=float(err[1]), slot_error_down_m=float(err[2]),
            )


def _set_verdict(row: dict[str, Any], verdicts: list[bool] | None) -> None:
    """An aid's event row left for the navigator's verdict (accepted None) gets it: accepted
    when every output of the attempt was (no outputs, or none fused: False)."""
    if "accepted" in row and row["accepted"] is None:
        row["accepted"] = bool(verdicts) and all(verdicts)
