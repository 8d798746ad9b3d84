"""Assembly of one vehicle from its scenario block: dynamics, sensors (each with its own seeded
stream), navigator, navigation aids, mission and controller, with the decimation of each loop
relative to the physics rate."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from testbench.config.schema import Scenario, Vehicle, Wind
from testbench.core import registry
from testbench.core.errors import InputError
from testbench.core.geodesy import geodetic_to_ned
from testbench.core.interfaces import BuildContext, GeodeticOrigin
from testbench.core.messages import NavEstimate, RotorCommand, SurfaceCommand
from testbench.core.rng import RngStreams
from testbench.core.rotations import euler_to_quat
from testbench.dynamics.jsbsim_adapter import AirMass, InitialCondition, JSBSimDynamics
from testbench.sim.world_runtime import RunWorld


def decimation(rate_hz: float, physics_rate_hz: float, where: str) -> int:
    """Physics steps per tick of a loop at rate_hz; the rate must divide the physics rate."""
    if rate_hz <= 0 or not math.isfinite(rate_hz):
        raise InputError(f"{where}: rate {rate_hz!r} Hz must be a positive number")
    ratio = physics_rate_hz / rate_hz
    n = int(round(ratio))
    if n < 1 or abs(ratio - n) > 1e-9 * ratio:
        raise InputError(
            f"{where}: rate {rate_hz:g} Hz does not divide physics_rate_hz={physics_rate_hz:g} evenly "
            f"(expected a rate of {physics_rate_hz:g}/N Hz)"
        )
    return n


@dataclass
class SensorSlot:
    """A sensor with its stream and decimation."""

    name: str
    sensor: Any
    rng: np.random.Generator
    every: int
    event_rows: Any = None  # sensor.event_rows(vehicle_id) -> [(table, row)], for sensors that record


@dataclass
class VehicleRuntime:
    """Everything that flies and thinks for one vehicle during a run."""

    id: str
    spec: Vehicle
    kind: str
    dynamics: JSBSimDynamics
    sensors: list[SensorSlot]
    navigator: Any
    aids: list[Any]
    controller: Any
    mission: Any
    control_every: int
    command: SurfaceCommand | RotorCommand | None = None
    last_gnss_t_s: float = -math.inf
    gnss_timeout_s: float = math.inf
    extras: dict = field(default_factory=dict)
    in_flight: list = field(default_factory=list)
    """Aid outputs made late, not yet given to the navigator: (due time s, outputs, their event
    rows) in order of due time (Engine._hold)."""

    def command_values(self) -> tuple[float, ...]:
        c = self.command
        if isinstance(c, SurfaceCommand):
            return (c.aileron, c.elevator, c.rudder, c.throttle)
        if isinstance(c, RotorCommand):
            return tuple(c.motors)
        return ()


def initial_condition(v: Vehicle, origin: GeodeticOrigin) -> InitialCondition:
    """The vehicle's start in local NED from its `initial:` block."""
    i = v.initial
    if i.lat_deg is not None:
        n, e, _ = geodetic_to_ned(math.radians(i.lat_deg), math.radians(i.lon_deg or 0.0), origin.alt_m, origin.lat_rad, origin.lon_rad, origin.alt_m)
    else:
        n, e = i.north_m or 0.0, i.east_m or 0.0
    return InitialCondition(pos_ned_m=(float(n), float(e), -float(i.altitude_m)), heading_rad=math.radians(i.heading_deg), airspeed_mps=i.airspeed_mps)


# JSBSim's turb-type and MIL-F-8785C probability-of-exceedance indices (FGWinds).
_TURBULENCE_TYPE = {"milspec": 3, "tustin": 4}
_SEVERITY_INDEX = {"light": 3, "moderate": 4, "severe": 6}


def air_mass(wind: Wind | None, streams: RngStreams, vehicle_id: str) -> AirMass | None:
    """The scenario's wind as one vehicle's JSBSim air mass (None: calm air). Each vehicle's
    turbulence has its own seed, drawn from the run's streams by the vehicle's id."""
    if wind is None:
        return None
    t = wind.turbulence
    if t is None:
        return AirMass(wind_ned_mps=wind.velocity_ned_mps())
    seed = int(streams.generator("vehicle", vehicle_id, "turbulence").integers(1, 2**31 - 1))
    w20 = wind.speed_mps if t.windspeed_at_6m_mps is None else t.windspeed_at_6m_mps
    return AirMass(wind_ned_mps=wind.velocity_ned_mps(), turbulence_type=_TURBULENCE_TYPE[t.model],
                   severity_index=_SEVERITY_INDEX[t.severity], windspeed_at_20ft_mps=float(w20), seed=seed)


def build_vehicle(scn: Scenario, v: Vehicle, world: RunWorld, streams: RngStreams, scenario_dir: str) -> VehicleRuntime:
    """Construct one vehicle's components (params were validated when the scenario loaded)."""
    origin = world.origin
    ids = tuple(x.id for x in scn.vehicles)
    P = scn.physics_rate_hz
    base = f"vehicles[{v.id}]"
    ctx_sensor = BuildContext(v.id, ids, origin, scn.epoch_year, P, scenario_dir, world)
    ctx_onboard = BuildContext(v.id, ids, origin, scn.epoch_year, P, scenario_dir, None)

    dyn = JSBSimDynamics(v.aircraft, origin, P, terrain_height_fn=world.terrain_fn(), vehicle_id=v.id,
                         air=air_mass(scn.world.wind, streams, v.id), obstacles=world.obstacles)
    sensors = []
    for s in v.sensors:
        name = s.sensor_name
        sensor = registry.build("sensor", s.type, s.params, f"{base}.sensors[{name}]", ctx=ctx_sensor)
        sensor.name = name
        draw = getattr(sensor, "draw_constant_errors", None)
        if draw is not None:  # the run's constant errors (a camera's boresight), from their own stream
            draw(streams.generator("vehicle", v.id, "sensor", name, "constant_errors"))
        every = decimation(float(sensor.rate_hz), P, f"{base}.sensors[{name}].rate_hz")
        sensors.append(SensorSlot(name, sensor, streams.generator("vehicle", v.id, "sensor", name), every,
                                  getattr(sensor, "event_rows", None)))
    # IMUs first at a tick, so the navigator predicts to the tick before it corrects.
    sensors.sort(key=lambda s: 0 if type(s.sensor).__name__.lower().startswith("imu") else 1)

    navigator = registry.build("navigator", v.navigation.type, v.navigation.params, f"{base}.navigation",
                               ctx=ctx_onboard, aircraft=dyn.aircraft_meta,
                               rng=streams.generator("vehicle", v.id, "navigation", "alignment"))
    by_name = {s.name: s.sensor for s in sensors}
    check = getattr(navigator, "check_sensors", None)
    if check is not None:  # the navigator's aiding may need sensors of a kind (bad input: exit 2)
        check(by_name, f"{base}.navigation")
    onboard = {"reference_map": world.reference_map, "reference_elevation": world.reference_elevation, "same_raster": world.same_raster}
    aids = [
        registry.build(
            "aid", a.type, a.params, f"{base}.aids[{i}]", ctx=ctx_onboard, sensors=by_name, onboard=onboard,
            rng=streams.generator("vehicle", v.id, "aid", str(i), a.type),
        )
        for i, a in enumerate(v.aids)
    ]
    check = getattr(navigator, "check_aids", None)
    if check is not None:  # the navigator's states may need what an aid offers (bad input: exit 2)
        check(aids, f"{base}.navigation")
    mission = None
    if v.mission is not None:
        mission = registry.build("mission", v.mission.type, v.mission.params, f"{base}.mission", ctx=ctx_onboard)
    controller = registry.build(
        "controller", v.control.type, v.control.params, f"{base}.control",
        ctx=ctx_onboard, mission=mission, aircraft=dyn.aircraft_meta,
    )
    control_every = decimation(v.rates.control_hz, P, f"{base}.rates.control_hz")
    rt = VehicleRuntime(v.id, v, dyn.kind, dyn, sensors, navigator, aids, controller, mission, control_every)
    gnss = [s for s in sensors if type(s.sensor).__name__.lower().startswith("gnss")]
    if gnss:
        rt.gnss_timeout_s = 1.5 / float(gnss[0].sensor.rate_hz)
    return rt


def initial_estimate(truth, t_s: float = 0.0) -> NavEstimate:
    """The estimate a navigator starts from: the pre-flight alignment, modelled as the true
    initial state (GNSS and ground alignment are available before the mission starts); the
    navigator's own initial sigmas say how uncertain that alignment is."""
    z = np.zeros((3, 3))
    return NavEstimate(
        t_s=t_s, pos_ned_m=truth.pos_ned_m.copy(), vel_ned_mps=truth.vel_ned_mps.copy(),
        q_nb_wxyz=euler_to_quat(truth.rpy_rad), rpy_rad=truth.rpy_rad.copy(),
        omega_b_rps=truth.omega_eb_b_rps.copy(), cov_pos_ned_m2=z, cov_vel_ned_m2s2=z, cov_att_rad2=z,
        airspeed_mps=truth.airspeed_mps,
    )
