"""The scenario schema: typed, validated, unknown keys are errors.

A scenario YAML maps onto `Scenario`. Components (sensors, navigation, control, mission) are
`{type: NAME, params: {...}}` blocks (`ComponentSpec`); their params are validated against the
named class's own `Params` model when the scenario is loaded (see loader.validate_components).
Units are in key names: `_m`, `_s`, `_hz`, `_deg`, `_mps`.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import pydantic
from pydantic import Field, field_validator, model_validator

from testbench.core.obstacles import Obstacle

_CFG = pydantic.ConfigDict(extra="forbid", frozen=True)


class ComponentSpec(pydantic.BaseModel):
    """A swappable part: registry name or "package.module:Class", and its params."""

    model_config = _CFG
    type: str
    params: dict[str, Any] = Field(default_factory=dict)


class SensorSpec(ComponentSpec):
    """A sensor on a vehicle; `name` (default: the type) must be unique on the vehicle."""

    name: str | None = None

    @property
    def sensor_name(self) -> str:
        return self.name or self.type.rsplit(":", 1)[-1]


class Origin(pydantic.BaseModel):
    """Origin of the local NED frame: WGS-84 latitude/longitude (deg), altitude (m, ellipsoid
    taken as MSL). The ground at the origin is at alt_m."""

    model_config = _CFG
    lat_deg: float = Field(ge=-89.0, le=89.0)
    lon_deg: float = Field(ge=-180.0, le=180.0)
    alt_m: float = 0.0


class Turbulence(pydantic.BaseModel):
    """Atmospheric turbulence, JSBSim's Dryden-spectrum models (FGWinds; MIL-F-8785C scale
    lengths and intensities, Yeager 1998, NASA CR-206937): `milspec` (MIL-STD-1797A difference
    equations, JSBSim turb-type 3) or `tustin` (Tustin-discretised, turb-type 4).

    severity: the milspec's probability-of-exceedance curve above 2000 ft (MIL-F-8785C fig. 7):
    light (JSBSim index 3; 2.0-2.3 m/s RMS at 500-3750 ft), moderate (4; 2.6-3.2 m/s), severe
    (6; 4.8-7.0 m/s). windspeed_at_6m_mps: the wind at 20 ft above the ground that sets the
    intensity below 1000 ft (0.1 of it vertically, up to twice that along the wind); None: the
    mean wind's speed. JSBSim takes the height for these from the altitude above sea level, and
    its filters run on the vehicle's airspeed, so a vehicle hovering in still air sees none."""

    model_config = _CFG
    model: Literal["milspec", "tustin"] = "milspec"
    severity: Literal["light", "moderate", "severe"] = "light"
    windspeed_at_6m_mps: float | None = Field(default=None, ge=0.0, le=60.0)


class Wind(pydantic.BaseModel):
    """The air mass: a steady horizontal wind, the same everywhere and at every height, plus
    optional turbulence (each vehicle draws its own, seeded from the scenario seed).

    speed_mps: mean wind speed; from_deg: the true bearing the wind blows from (meteorological:
    270 is a westerly, moving the air east), clockwise from north."""

    model_config = _CFG
    speed_mps: float = Field(ge=0.0, le=60.0)
    from_deg: float = Field(ge=0.0, lt=360.0)
    turbulence: Turbulence | None = None

    def velocity_ned_mps(self) -> tuple[float, float, float]:
        """The steady wind as the air's velocity over the ground, NED (m/s): it moves towards
        from_deg + 180."""
        to_rad = math.radians(self.from_deg + 180.0)
        return (self.speed_mps * math.cos(to_rad), self.speed_mps * math.sin(to_rad), 0.0)


class MagneticAnomaly(pydantic.BaseModel):
    """The crust's field over the Earth's main field (world/magnetic.py): what a magnetometer
    senses beyond the WMM that the vehicles carry. A seeded random potential field of sources
    at source_depth_m below the origin's altitude (correlation length about twice that),
    whose vertical anomaly and horizontal anomaly magnitude have RMS rms_nT at the origin's
    altitude and rms_nT / (1 + h / source_depth_m) at a height h above it.

    seed: the field's own seed (the same field in every run); None draws it from the run's
    seed, so each run of a Monte Carlo batch meets another field. waves: plane waves summed."""

    model_config = _CFG
    rms_nT: float = Field(ge=0.0, le=100_000.0)
    source_depth_m: float = Field(gt=0.0, le=100_000.0)
    seed: int | None = Field(default=None, ge=0)
    waves: int = Field(default=256, ge=16, le=4096)


class DemError(pydantic.BaseModel):
    """The onboard DEM's error against the world's terrain (world/dem_error.py): a smooth
    random field of RMS rms_m whose correlation falls to exp(-1/2) at correlation_m (a Gaussian
    correlation function's length, as the tan aid assumes in dem_correlation_m), added to
    what the vehicles carry (world.reference_elevation, else world.elevation), never to the
    ground the sensors see. seed: the field's own seed (the same onboard DEM in every run);
    None draws it from the run's seed."""

    model_config = _CFG
    rms_m: float = Field(ge=0.0, le=1000.0)
    correlation_m: float = Field(gt=0.0, le=100_000.0)
    seed: int | None = Field(default=None, ge=0)


class MapError(pydantic.BaseModel):
    """The carried reference map's georeference error (world/map_error.py): ground that truly
    lies at g appears in the map at g + d(g), d = shift_ne_m (north, east, m: a datum or
    control error the whole map shares) plus a smooth random field of sigma_m per axis whose
    correlation falls to exp(-1/2) at correlation_m (an orthophoto's local misplacement from
    its DEM and tie points). Applied to what the vehicles carry (world.reference_map, else
    world.imagery), never to what cameras render. seed: the field's own seed (the same map in
    every run); None draws it from the run's seed."""

    model_config = _CFG
    shift_ne_m: tuple[float, float] = (0.0, 0.0)
    sigma_m: float = Field(default=0.0, ge=0.0, le=100.0)
    correlation_m: float = Field(default=1000.0, gt=0.0, le=100_000.0)
    seed: int | None = Field(default=None, ge=0)

    @model_validator(mode="after")
    def _small_gradient(self):
        if self.sigma_m > 0.02 * self.correlation_m:
            raise ValueError(f"sigma_m {self.sigma_m} m over correlation_m {self.correlation_m} m folds the map "
                             "(expected sigma_m at most 2 % of correlation_m)")
        if not all(math.isfinite(x) for x in self.shift_ne_m):
            raise ValueError(f"shift_ne_m {self.shift_ne_m} is not finite (expected [north, east], m)")
        return self


class CloudCoverage(pydantic.BaseModel):
    """Another coverage of the cloud layer for a while: `coverage` (0-1) over [start_s, end_s)."""

    model_config = _CFG
    start_s: float = Field(ge=0.0)
    end_s: float = math.inf
    coverage: float = Field(ge=0.0, le=1.0)

    @model_validator(mode="after")
    def _ordered(self):
        if not self.end_s > self.start_s:
            raise ValueError(f"end_s {self.end_s} is not after start_s {self.start_s} (expected a window of time, s)")
        return self


class Clouds(pydantic.BaseModel):
    """A broken cloud layer (world/clouds.py): a thin sheet at base_m above the origin's
    altitude, which the cameras see instead of what lies beyond it. coverage: the share of the
    sky under cloud (0 clear, 1 overcast), and `windows` another coverage for a while (an
    overcast spell: `[{start_s: 120, end_s: 240, coverage: 1.0}]`); cell_m: the clouds' typical
    size; opacity: how much light an optically thick cloud takes (0-1); drift_ne_mps: the
    clouds' velocity over the ground, north and east (None: the world's steady wind, calm:
    still). seed: the field's own seed (the same clouds in every run); None draws it from the
    run's seed, so each run of a Monte Carlo batch meets other clouds.
    shadow_light: the share of the ground's light (linear radiance) left in a thick cloud's
    shadow, the diffuse skylight (1: no shadows); sun_azimuth_deg (from north, clockwise) and
    sun_elevation_deg (above the horizon): the sun that casts them, both or neither (neither:
    a procedural imagery's own sun, a real map's at local solar noon on the epoch's date)."""

    model_config = _CFG
    base_m: float = Field(gt=0.0, le=20_000.0)
    coverage: float = Field(default=0.5, ge=0.0, le=1.0)
    windows: list[CloudCoverage] = Field(default_factory=list)
    cell_m: float = Field(default=300.0, gt=1.0, le=50_000.0)
    opacity: float = Field(default=1.0, ge=0.0, le=1.0)
    drift_ne_mps: tuple[float, float] | None = None
    seed: int | None = Field(default=None, ge=0)
    shadow_light: float = Field(default=0.35, ge=0.0, le=1.0)
    sun_azimuth_deg: float | None = Field(default=None, ge=-360.0, le=360.0)
    sun_elevation_deg: float | None = Field(default=None, gt=0.0, le=90.0)

    @model_validator(mode="after")
    def _sun_whole(self):
        if (self.sun_azimuth_deg is None) != (self.sun_elevation_deg is None):
            raise ValueError("give both sun_azimuth_deg and sun_elevation_deg, or neither (expected the sun's "
                             "direction whole, or the imagery's own sun)")
        return self

    @model_validator(mode="after")
    def _windows_apart(self):
        spans = sorted((w.start_s, w.end_s) for w in self.windows)
        for (s0, e0), (s1, _) in zip(spans, spans[1:]):
            if s1 < e0:
                raise ValueError(f"cloud coverage windows overlap: one from {s0} s runs to {e0} s, past the next's "
                                 f"start at {s1} s (expected windows one after another)")
        return self


class ObstacleBox(pydantic.BaseModel):
    """A box-shaped obstacle (building, tower, mast): axis-aligned in the local NED frame,
    min_ned_m and max_ned_m its corners [north, east, down] in metres from the origin (down
    from the origin's altitude: a 40 m building on ground at the origin's altitude runs from
    down -40 to 0). It blocks UWB links (NLOS), is drawn by the cameras and hides what stands
    behind it, and a vehicle that enters it ends the run (a collision). name: how messages
    call it (default "obstacle N", N its place in the list from 1)."""

    model_config = _CFG
    name: str | None = None
    min_ned_m: tuple[float, float, float]
    max_ned_m: tuple[float, float, float]

    def obstacle(self, default_name: str) -> Obstacle:
        """The box as the geometry every part uses (core.obstacles.Obstacle), named
        default_name when the scenario gives it no name."""
        return Obstacle(tuple(self.min_ned_m), tuple(self.max_ned_m), self.name or default_name)

    @model_validator(mode="after")
    def _min_below_max(self):
        for axis, lo, hi in zip(("north", "east", "down"), self.min_ned_m, self.max_ned_m):
            if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
                raise ValueError(f"min_ned_m must lie below max_ned_m on every axis; {axis}: {lo} is not below {hi} "
                                 "(expected [north, east, down] of the box's two opposite corners, m)")
        return self


class World(pydantic.BaseModel):
    """The world: origin, what cameras render (imagery), what vehicles carry (reference_map),
    the carried map's georeference error (reference_map_error: MapError; None: the map is placed exactly),
    terrain (elevation), the terrain model vehicles carry (reference_elevation, default the terrain; its error
    reference_elevation_error: DemError, None: none), obstacles (boxes: ObstacleBox), the air mass (wind; None: calm
    air), the crust's magnetic anomaly (None: the magnetometers sense the WMM the vehicles carry, exactly), a cloud layer
    between the cameras and the ground (clouds: Clouds; None: clear sky). Maps are
    GeoTIFF paths (with ${VAR} expansion) or `procedural:` specs; None means no imagery / flat ground. The
    elevation keys also take 'flat' or 'flat:HEIGHT_M' (flat ground that far above the origin's altitude), e.g.
    reference_elevation: flat for a vehicle that carries no terrain model over relief.
    imagery_credit: the imagery's attribution, printed in the run's report, which shows the imagery (a CC BY
    licence asks for it wherever the data is shown)."""

    model_config = _CFG
    origin: Origin
    imagery: str | None = None
    imagery_credit: str | None = None
    reference_map: str | None = None
    reference_map_error: MapError | None = None
    elevation: str | None = None
    reference_elevation: str | None = None
    reference_elevation_error: DemError | None = None
    obstacles: list[ObstacleBox] = Field(default_factory=list)
    wind: Wind | None = None
    magnetic_anomaly: MagneticAnomaly | None = None
    clouds: Clouds | None = None


class InitialState(pydantic.BaseModel):
    """Initial position (local metres or lat/lon), altitude above the origin's ground,
    heading and airspeed. Exactly one of (north_m, east_m) and (lat_deg, lon_deg).

    airspeed_mps: a fixed wing flies at it through the air along its heading (its ground
    velocity adds the wind); a multirotor moves at it over the ground along its heading
    (0: hovering over its start point, whatever the wind)."""

    model_config = _CFG
    north_m: float | None = None
    east_m: float | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    altitude_m: float = Field(description="height above the origin altitude (m)")
    heading_deg: float = 0.0
    airspeed_mps: float = Field(default=0.0, ge=0.0)

    @model_validator(mode="after")
    def _one_position(self) -> "InitialState":
        local = self.north_m is not None or self.east_m is not None
        geo = self.lat_deg is not None or self.lon_deg is not None
        if local == geo:
            raise ValueError("give either north_m/east_m or lat_deg/lon_deg")
        return self


class Rates(pydantic.BaseModel):
    """Rates of the vehicle's loops (Hz); each must divide the physics rate."""

    model_config = _CFG
    control_hz: float = Field(default=50.0, gt=0.0)


class Vehicle(pydantic.BaseModel):
    """One vehicle: its JSBSim model, start, mission, sensors, navigator and controller.

    aids: navigation aids that turn raw sensor output into navigator measurements using the
    current estimate (e.g. `ismn`: camera frame + INS -> position fix).
    """

    model_config = _CFG
    id: str = Field(pattern=r"^[A-Za-z][A-Za-z0-9_-]*$")
    aircraft: str
    initial: InitialState
    mission: ComponentSpec | None = None
    sensors: list[SensorSpec] = Field(default_factory=list)
    navigation: ComponentSpec = Field(default_factory=lambda: ComponentSpec(type="truth_passthrough"))
    aids: list[ComponentSpec] = Field(default_factory=list)
    control: ComponentSpec
    rates: Rates = Field(default_factory=Rates)
    colour_rgb: tuple[int, int, int] = Field(default=(60, 60, 66), description="body colour seen by other vehicles' cameras")
    led_rate_hz: float = Field(default=10.0, gt=0, description="chip rate of the LED ID code")

    @field_validator("sensors")
    @classmethod
    def _unique_sensor_names(cls, sensors: list[SensorSpec]) -> list[SensorSpec]:
        seen: set[str] = set()
        for s in sensors:
            if s.sensor_name in seen:
                raise ValueError(f"two sensors named {s.sensor_name!r}; give each a unique name")
            seen.add(s.sensor_name)
        return sensors


class Threshold(pydantic.BaseModel):
    """A regression gate on one metric: min and/or max."""

    model_config = _CFG
    min: float | None = None
    max: float | None = None

    @model_validator(mode="after")
    def _some_bound(self) -> "Threshold":
        if self.min is None and self.max is None:
            raise ValueError("give min and/or max")
        return self


class Phases(pydantic.BaseModel):
    """How scoring splits flight into smooth and turning phases (truth bank and turn rate)."""

    model_config = _CFG
    turn_bank_deg: float = 10.0
    turn_rate_deg_s: float = 3.0


class Formation(pydantic.BaseModel):
    """The formation geometry, for scoring: each vehicle's slot (forward_m, right_m, down_m) in
    the formation frame (forward along the leader's course). Followers' controllers carry the
    same slots in their own params (a YAML anchor avoids writing them twice).

    kind rigid: the slots turn with the leader's ground course (an arrowhead, a V);
    column: a follower's place is on the leader's own path, its slot's forward difference
    (arc length) behind the leader, offset by the slots' right/down difference (a column along
    a corridor or a canyon, flown by column_follower controllers)."""

    model_config = _CFG
    leader: str
    slots: dict[str, tuple[float, float, float]]
    kind: Literal["rigid", "column"] = "rigid"

    @model_validator(mode="after")
    def _leader_has_slot(self) -> "Formation":
        if self.leader not in self.slots:
            raise ValueError(f"the leader {self.leader!r} needs a slot")
        return self


class Scenario(pydantic.BaseModel):
    """A whole scenario file."""

    model_config = _CFG
    name: str
    description: str = ""
    seed: int = Field(default=0, ge=0)
    duration_s: float = Field(gt=0.0)
    physics_rate_hz: float = Field(default=120.0, gt=0.0)
    record_rate_hz: float = Field(default=10.0, gt=0.0)
    epoch_year: float = Field(default=2025.5, ge=2025.0, le=2030.0, description="decimal year (magnetic model)")
    world: World
    vehicles: list[Vehicle] = Field(min_length=1)
    formation: Formation | None = None
    phases: Phases = Field(default_factory=Phases)
    thresholds: dict[str, Threshold] = Field(default_factory=dict)

    @field_validator("vehicles")
    @classmethod
    def _unique_ids(cls, vehicles: list[Vehicle]) -> list[Vehicle]:
        ids = [v.id for v in vehicles]
        dup = {i for i in ids if ids.count(i) > 1}
        if dup:
            raise ValueError(f"duplicate vehicle ids: {sorted(dup)}")
        return vehicles

    @model_validator(mode="after")
    def _formation_ids(self) -> "Scenario":
        if self.formation is not None:
            ids = {v.id for v in self.vehicles}
            unknown = sorted(set(self.formation.slots) - ids)
            if unknown:
                raise ValueError(f"formation.slots names vehicles that do not exist: {unknown}")
        return self

    def vehicle(self, vehicle_id: str) -> Vehicle:
        for v in self.vehicles:
            if v.id == vehicle_id:
                return v
        raise KeyError(vehicle_id)
