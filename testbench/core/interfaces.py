"""The small abstract interfaces of the swappable parts (DESIGN.md, Interfaces).

Each has a reference implementation in its package and a conformance check in
`testbench.testing` that users run on their own classes.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import Any, Mapping, Protocol

import numpy as np

from testbench.core.messages import CorrectionInfo, GuidanceStatus, NavEstimate, TruthState


@dataclass(frozen=True, slots=True)
class GeodeticOrigin:
    """Scenario origin of the local NED frame (WGS-84 geodetic, alt above the ellipsoid)."""

    lat_rad: float
    lon_rad: float
    alt_m: float


@dataclass(frozen=True)
class BuildContext:
    """What a component learns about its place when the scenario is assembled.

    vehicle_id: its own vehicle; vehicle_ids: every vehicle in the scenario, in scenario order
    (UWB TDMA slots follow it); origin: the local NED origin; epoch_utc_year: decimal year of the
    scenario date (magnetic model); physics_rate_hz; scenario_dir: folder of the scenario file
    (relative paths resolve from it); world: the world object (maps, elevation) for sensors, None
    for navigation and control, which never see the truth world.
    """

    vehicle_id: str
    vehicle_ids: tuple[str, ...]
    origin: GeodeticOrigin
    epoch_utc_year: float = 2025.0
    physics_rate_hz: float = 100.0
    scenario_dir: str = "."
    world: Any = None


class WorldView(Protocol):
    """What a sensor may look at when it samples: truth of the world at this tick.

    Only sensors and scoring get a WorldView; navigation and control never do.
    """

    t_s: float
    origin: GeodeticOrigin
    self_id: str
    vehicles: Mapping[str, TruthState]

    def terrain_height_m(self, north_m: np.ndarray, east_m: np.ndarray) -> np.ndarray:
        """Terrain height above the origin's altitude (up positive, m) at NED north/east."""
        ...

    def magnetic_anomaly_ned_T(self, truth: TruthState) -> np.ndarray | None:
        """The crust's magnetic field over the WMM at the vehicle (3,) NED tesla, or None
        where the world has none (the WMM alone)."""
        ...


class Dynamics(abc.ABC):
    """Flight dynamics of one vehicle."""

    @abc.abstractmethod
    def reset(self, initial: Any) -> TruthState:
        """Put the vehicle in its initial condition; returns the truth at t = 0."""

    @abc.abstractmethod
    def step(self, command: Any, dt_s: float) -> TruthState:
        """Hold `command` for dt_s seconds of simulated time; returns the new truth."""


class Sensor(abc.ABC):
    """A sensor samples truth at `rate_hz`.

    Noise state (bias walks, lags) evolves only inside `measure`, once per sample time;
    asking again for the same t_s returns the cached measurement without walking twice.
    """

    rate_hz: float
    name: str

    @abc.abstractmethod
    def measure(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> Any | None:
        """The measurement at truth.t_s, or None when the sensor has nothing (no fix, out of view)."""


class Navigator(abc.ABC):
    """Turns one vehicle's measurements into its state estimate.

    Built as Class(params, ctx=BuildContext, aircraft=dict, rng=np.random.Generator, ...): rng is
    the vehicle's own "navigation/alignment" stream (e.g. for drawing the alignment error);
    accept **kwargs for what a navigator does not use."""

    estimates_wind: bool = False
    """Whether its estimates carry the wind (NavEstimate.wind_ne_mps); the record then has
    the wind columns."""

    @abc.abstractmethod
    def initialize(self, t_s: float, initial: NavEstimate) -> None:
        """Start from an initial estimate (e.g. the GNSS/ground alignment at take-off)."""

    @abc.abstractmethod
    def predict(self, imu: Any) -> None:
        """Propagate with one IMU sample (or to its time, for IMU-less navigators)."""

    @abc.abstractmethod
    def correct(self, measurement: Any) -> CorrectionInfo | tuple[CorrectionInfo, ...] | None:
        """Use one aiding measurement; returns what was done, or None if not applicable. A
        measurement that holds several (a position fix with a heading) may give a tuple of
        corrections, the first the measurement's own (its accepted verdict)."""

    @abc.abstractmethod
    def estimate(self) -> NavEstimate:
        """The current estimate with covariance."""

    def expect(self, t_s: float) -> None:
        """A measurement stamped t_s (the present tick) will reach correct() later, once an
        aid has processed it (its onboard processing time). A navigator that fuses such a
        measurement at its own time keeps what it needs here (ins_ekf: delayed_fixes); by
        default nothing is kept, and the late measurement is taken as it comes."""


class NavigationAid(abc.ABC):
    """Turns raw sensor output into navigator measurements with the help of the current
    estimate (scene matching: camera frame + INS pose -> position fix)."""

    @abc.abstractmethod
    def accepts(self, measurement: Any) -> bool:
        """True if this aid consumes `measurement` (e.g. frames of its own camera)."""

    @abc.abstractmethod
    def process(self, measurement: Any, estimate: NavEstimate) -> tuple[list[Any], Any]:
        """(measurements for the navigator, diagnostics for the recorder or None)."""


class Controller(abc.ABC):
    """Guidance plus autopilot of one vehicle: estimate in, actuator command out."""

    @abc.abstractmethod
    def update(self, t_s: float, estimate: NavEstimate, reference: Any = None) -> Any:
        """Command for the next control interval."""

    def status(self) -> GuidanceStatus | None:
        """What guidance is doing now (active path, commanded altitude), for scoring."""
        return None


class SceneMatcher(abc.ABC):
    """Registers an orthorectified camera frame against a window of the reference map.

    ortho_frame is the (H, W) grey ortho image (its mask in prior.ortho_valid). A matcher whose
    class sets accepts_ortho_frame = True gets the pipeline's OrthoFrame instead (with its own
    mask), which warps only the regions and reduced levels the matcher asks for
    (navigation.ismn.types.OrthoFrame): the area matchers use a tenth of a 2 Mpx grid.
    """

    #: True: match() takes an ismn OrthoFrame (regions warped on demand) as ortho_frame.
    accepts_ortho_frame: bool = False

    @abc.abstractmethod
    def match(self, ortho_frame: np.ndarray, map_window: np.ndarray, prior: Any) -> Any | None:
        """A MatchResult (offset, quality, correspondences) or None when nothing matched."""


class Detector(abc.ABC):
    """Finds other vehicles in a camera image.

    centre_reference: the point of a vehicle a detection's centre_px is the image of:
    "vehicle_centre" (its CG: truth boxes, a CNN trained on CG projections) or "led_centroid"
    (its lit LEDs: a blob detector), which lies off the CG by a target offset the user gives.
    box_shows_extent: whether a detection's box is the vehicle's own outline (truth boxes, a
    CNN), so that its size follows from the vehicle's size and range; False for an LED blob
    detector, whose box is the LEDs' glow (14 x 10 px from 100 m as from 200 m)."""

    centre_reference: str = "vehicle_centre"
    box_shows_extent: bool = True

    @abc.abstractmethod
    def detect(self, image: np.ndarray) -> list[Any]:
        """Detections (pixel boxes with scores) in `image` (H, W, 3) uint8 RGB."""
