"""The deterministic multi-rate engine.

Time advances in physics ticks of 1/physics_rate_hz. Every loop (each sensor, each vehicle's
control, the recorder) runs every N ticks (N an integer: rates that do not divide the physics
rate are rejected when the vehicle is built). At a tick where anything runs, for every vehicle
in scenario order:
  1. sensors sample the truth at the tick (IMU first, so the navigator predicts before it
     corrects); navigation aids turn raw outputs into navigator measurements;
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
from typing import Any, Callable

from testbench.core.messages import GnssFix, ImuSample
from testbench.sim.recorder import Recorder
from testbench.sim.vehicle import VehicleRuntime, initial_estimate
from testbench.sim.world_runtime import RunWorld, TickWorldView, _LazyTruths

log = logging.getLogger(__name__)


@dataclass
class EngineResult:
    """How the loop ended: simulated and wall time, pacing lag, and the abort if any."""

    sim_time_s: float
    wall_time_s: float
    ticks: int
    max_realtime_lag_s: float
    aborted: BaseException | None = None


class Engine:
    """Runs vehicles for duration_s at physics_rate_hz and records them at record_rate_hz.

    on_progress(t_s) is called about once per simulated second; realtime paces the loop to
    the wall clock (max lag reported); frame_sink(vehicle_id, sensor_name, frame) receives
    every camera-like measurement (for --save-frames).
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
    ):
        self.vehicles = vehicles
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
        truths = _LazyTruths(self._truth_getters())
        rec = self.recorder
        t_wall0 = time.perf_counter()
        max_lag = 0.0
        next_progress = 1.0
        k = 0
        aborted: BaseException | None = None
        try:
            self.start()
            while True:
                t_s = k * self.dt_s
                for v in self.vehicles:
                    self._sense(v, k, t_s, truths)
                for v in self.vehicles:
                    if k % v.control_every == 0:
                        v.command = v.controller.update(t_s, v.navigator.estimate())
                if k % self.record_every == 0:
                    for v in self.vehicles:
                        truth = v.dynamics.truth()
                        rec.record(
                            v.id, truth, v.navigator.estimate(), v.command_values(), v.controller.status(),
                            gnss_available=(t_s - v.last_gnss_t_s) <= v.gnss_timeout_s,
                        )
                if k >= self.n_ticks:
                    break
                step = min(self._gcd - (k % self._gcd), self.n_ticks - k)
                for v in self.vehicles:
                    v.dynamics.advance(v.command, step)
                k += step
                if self.on_progress is not None and k * self.dt_s >= next_progress:
                    self.on_progress(k * self.dt_s)
                    next_progress = math.floor(k * self.dt_s) + 1.0
                if self.realtime:
                    lag = (time.perf_counter() - t_wall0) - k * self.dt_s
                    if lag < 0.0:
                        time.sleep(-lag)
                    else:
                        max_lag = max(max_lag, lag)
        except Exception as exc:  # noqa: BLE001 -- classified by the runner
            aborted = exc
        wall = time.perf_counter() - t_wall0
        return EngineResult(sim_time_s=k * self.dt_s, wall_time_s=wall, ticks=k, max_realtime_lag_s=max_lag, aborted=aborted)

    def _sense(self, v: VehicleRuntime, k: int, t_s: float, truths: _LazyTruths) -> None:
        view = None
        for slot in v.sensors:
            if k % slot.every:
                continue
            truth = v.dynamics.truth()
            if view is None:
                view = TickWorldView(self.world, t_s, v.id, truths)
            m = slot.sensor.measure(truth, view, slot.rng)
            if m is None:
                continue
            if isinstance(m, ImuSample):
                v.navigator.predict(m)
                continue
            if self.frame_sink is not None and hasattr(m, "image"):
                self.frame_sink(v.id, slot.name, m)
            self._deliver(v, m)

    def _deliver(self, v: VehicleRuntime, m: Any) -> None:
        """Give a measurement to the aids that want it, then to the navigator."""
        outputs = [m]
        for aid in v.aids:
            if aid.accepts(m):
                produced, diag = aid.process(m, v.navigator.estimate())
                outputs.extend(produced)
                if diag is not None:
                    for table, row in diag.event_rows(v.id):
                        self.recorder.event(table, **row)
        for out in outputs:
            if isinstance(out, GnssFix):
                v.last_gnss_t_s = out.t_s
            info = v.navigator.correct(out)
            if info is not None:
                self.recorder.correction(v.id, info)
