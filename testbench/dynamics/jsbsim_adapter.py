"""JSBSim behind the `Dynamics` interface: SI `TruthState` in, feet/slugs/properties hidden.

One `JSBSimDynamics` owns one FGFDMExec (one vehicle). The adapter:
- loads the project's own models from `aircraft/` or any model bundled with jsbsim;
- sets the initial condition from local NED position, heading and airspeed, and trims a
  fixed-wing model for level flight (JSBSim's own trim);
- maps `SurfaceCommand` / `RotorCommand` onto JSBSim's fcs/*-cmd-norm properties;
- reads the truth back through cached property nodes (fast), converting to SI;
- ends the run with `SimulationAborted` on ground/terrain contact, NaN or a runaway state.

Terrain: JSBSim's own ground is the flat ellipsoid at the origin altitude; relief comes from the
world's elevation model through `terrain_height_fn` (m above the origin altitude, up positive),
which defines `height_agl_m` and terrain impact.

Wind: JSBSim's own air mass (FGWinds) carries the steady wind and the Dryden turbulence
(`AirMass`), so the aerodynamics (the wing's lift and drag, the rotors' drag) see the
air-relative velocity, and the truth reports the wind the vehicle meets.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Callable, Sequence

import os

# Silence JSBSim's start-up banner on stdout (library code does not print).
os.environ.setdefault("JSBSIM_DEBUG", "0")

import jsbsim  # noqa: E402
import numpy as np  # noqa: E402

from testbench.core.errors import InputError, SimulationAborted
from testbench.core.geodesy import LocalTangentFrame, ned_to_geodetic
from testbench.core.interfaces import Dynamics, GeodeticOrigin
from testbench.core.messages import RotorCommand, SurfaceCommand, TruthState
from testbench.core.obstacles import Obstacle
from testbench.core.rotations import dcm_to_euler
from testbench.core.units import (
    FT_TO_M,
    KT_TO_MPS,
    M_TO_FT,
    MPS_TO_KT,
    PSF_TO_PA,
    RANKINE_TO_KELVIN,
    STANDARD_GRAVITY_MPS2,
)
from testbench.dynamics.catalog import aircraft_dir, aircraft_meta

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class InitialCondition:
    """Where and how a vehicle starts.

    pos_ned_m (3,): local NED at the scenario origin (down = -altitude above the origin);
    heading_rad: true heading; airspeed_mps: true airspeed along the heading (0 to hover);
    trim: trim a fixed-wing model for level flight at that speed with JSBSim's trim.
    """

    pos_ned_m: tuple[float, float, float]
    heading_rad: float = 0.0
    airspeed_mps: float = 0.0
    trim: bool = True


@dataclass(frozen=True)
class AirMass:
    """The air one vehicle flies through (JSBSim's FGWinds).

    wind_ned_mps (3,): the steady wind, the air's velocity over the ground, NED m/s;
    turbulence_type: JSBSim atmosphere/turb-type (0 none, 3 milspec, 4 tustin: Dryden spectra
    after MIL-F-8785C); severity_index: the milspec's probability-of-exceedance curve (0-7: 3
    light, 4 moderate, 6 severe); windspeed_at_20ft_mps: the wind 20 ft above the ground that
    sets the intensity below 1000 ft; seed: the turbulence generator's seed (atmosphere/randomseed,
    its own generator, so a run's turbulence depends only on it).
    """

    wind_ned_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence_type: int = 0
    severity_index: int = 0
    windspeed_at_20ft_mps: float = 0.0
    seed: int = 0

    @property
    def calm(self) -> bool:
        return self.turbulence_type == 0 and not any(self.wind_ned_mps)


_WIND_READ = ("atmosphere/total-wind-north-fps", "atmosphere/total-wind-east-fps", "atmosphere/total-wind-down-fps")
_CALM_NED = np.zeros(3)
_CALM_NED.flags.writeable = False  # shared by every calm-air truth: nobody may write into it

# Property names read every time the truth is sampled, in TruthState order.
_READ = (
    "position/lat-geod-rad",
    "position/long-gc-rad",
    "position/geod-alt-ft",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "velocities/pi-rad_sec",
    "velocities/qi-rad_sec",
    "velocities/ri-rad_sec",
    "accelerations/Nx",
    "accelerations/Ny",
    "accelerations/Nz",
    "velocities/vtrue-fps",
    "atmosphere/P-psf",
    "atmosphere/T-R",
    "simulation/sim-time-sec",
)

_MAX_SPEED_MPS = 250.0
# JSBSim's flat ground when the adapter owns terrain contact: below the Dead Sea shore (-430 m).
_JSBSIM_GROUND_BELOW_ALL_M = -1000.0
_MAX_RATE_RPS = 30.0


class JSBSimDynamics(Dynamics):
    """One vehicle flown by JSBSim.

    aircraft: model name (project `aircraft/` or jsbsim-bundled); origin: local NED origin;
    physics_rate_hz: JSBSim integration rate; terrain_height_fn(north_m, east_m) -> m above the
    origin altitude (None: flat ground at the origin altitude); allow_ground_contact: keep
    running on the ground (take-off studies) instead of aborting; air: wind and turbulence
    (None: calm air); obstacles: boxes of the world (core.obstacles.Obstacle) whose inside
    ends the run as a collision, checked with the ground contact wherever the truth is read.
    """

    def __init__(
        self,
        aircraft: str,
        origin: GeodeticOrigin,
        physics_rate_hz: float,
        *,
        terrain_height_fn: Callable[[float, float], float] | None = None,
        allow_ground_contact: bool = False,
        vehicle_id: str = "",
        air: AirMass | None = None,
        obstacles: Sequence[Obstacle] = (),
    ):
        self.aircraft = aircraft
        self.origin = origin
        self.vehicle_id = vehicle_id
        self.aircraft_meta = aircraft_meta(aircraft)
        self.kind = self.aircraft_meta.get("kind", "fixed_wing")
        self._terrain = terrain_height_fn
        self._allow_ground = allow_ground_contact
        self._obstacles = tuple(obstacles)
        self._dt_s = 1.0 / float(physics_rate_hz)

        self.fdm = jsbsim.FGFDMExec(None)  # root = the jsbsim package (engines, systems)
        self.fdm.set_debug_level(0)
        self.fdm.set_dt(self._dt_s)  # before loading: JSBSim filters fix their coefficients at load
        self.fdm.set_aircraft_path(str(aircraft_dir(aircraft)))
        own_engines = aircraft_dir(aircraft) / aircraft / "Engines"
        if own_engines.is_dir():
            self.fdm.set_engine_path(str(own_engines))
        if not self.fdm.load_model(aircraft):
            raise InputError(f"aircraft {aircraft!r}: JSBSim could not load its model")
        self.fdm.disable_output()  # bundled models may declare CSV outputs: never write files
        pm = self.fdm.get_property_manager()
        self._nodes = [pm.get_node(name, False) for name in _READ]
        if any(n is None for n in self._nodes):
            missing = [name for name, n in zip(_READ, self._nodes) if n is None]
            raise InputError(f"aircraft {aircraft!r}: JSBSim model lacks properties {missing}")
        self._n_motors = len(self.aircraft_meta.get("motors", ())) if self.kind == "multirotor" else 0
        self._frame = LocalTangentFrame(origin.lat_rad, origin.lon_rad, origin.alt_m)
        self._air = None if air is None or air.calm else air
        self._wind_nodes = None if self._air is None else [pm.get_node(name, False) for name in _WIND_READ]
        self._truth: TruthState | None = None
        self._applied: SurfaceCommand | RotorCommand | None = None

    # -- Dynamics interface -------------------------------------------------------------

    def reset(self, initial: InitialCondition) -> TruthState:
        """Set the initial condition (and trim a fixed-wing model); returns the truth at t=0."""
        o = self.origin
        lat, lon, alt = ned_to_geodetic(np.asarray(initial.pos_ned_m, float), o.lat_rad, o.lon_rad, o.alt_m)
        fdm = self.fdm
        ground_m = o.alt_m + self._terrain_at(initial.pos_ned_m[0], initial.pos_ned_m[1])
        # JSBSim has its own flat ground, used only by its gear contact model. The adapter owns
        # terrain contact (against the elevation model), so by default JSBSim's ground goes
        # below the lowest land on Earth where it can never act (a canyon floor below the origin
        # would otherwise be "underground" for JSBSim). Take-off studies keep it at the terrain
        # under the start point so that the gear meets the ground there.
        jsbsim_ground_m = ground_m if self._allow_ground else _JSBSIM_GROUND_BELOW_ALL_M
        fdm["ic/terrain-elevation-ft"] = jsbsim_ground_m * M_TO_FT
        fdm["ic/lat-geod-rad"] = float(lat)
        fdm["ic/long-gc-rad"] = float(lon)
        fdm["ic/h-sl-ft"] = float(alt) * M_TO_FT
        fdm["ic/psi-true-rad"] = float(initial.heading_rad)
        hover_cmd = float(self.aircraft_meta.get("hover_throttle_norm", 0.5)) if self.kind == "multirotor" else 0.0
        if self._air is None:
            fdm["ic/vt-kts"] = float(initial.airspeed_mps) * MPS_TO_KT
        else:
            v_ground_ned = self._set_initial_velocity_in_wind(initial)
            if self.kind == "multirotor":
                hover_cmd = self._trim_multirotor_in_wind(v_ground_ned - np.asarray(self._air.wind_ned_mps, float),
                                                          float(initial.heading_rad))
        fdm["ic/gamma-deg"] = 0.0
        if self.kind == "multirotor":
            # Before run_ic: its pass at t = 0 is where the model's motor lag starts at the
            # command (tb_quad.xml). Written after it, the motors started from zero thrust and
            # the quad fell freely for its first 50 ms (0.25 m/s down; in wind its rotor drag
            # was 43-93 % of the trimmed drag over those steps, which misled the drag aiding's
            # first wind estimate by 12 %).
            self._apply(RotorCommand(motors=(hover_cmd,) * self._n_motors))
        if not fdm.run_ic():
            raise InputError(f"aircraft {self.aircraft!r}: JSBSim rejected the initial condition")
        if self._air is not None:
            self._set_turbulence()
        fdm["propulsion/set-running"] = -1
        if self.kind != "multirotor" and initial.trim and initial.airspeed_mps > 0.0:
            try:
                fdm["simulation/do_simple_trim"] = 1  # full longitudinal trim in level flight
            except jsbsim.TrimFailureError as exc:
                log.warning("%s: JSBSim trim failed (%s); starting untrimmed", self.aircraft, exc)
            # SurfaceCommand is absolute: JSBSim's trim leaves offsets in the *-trim-cmd-norm
            # properties that the model adds to every command; the controller's first command
            # (issued before the first step) carries the trim instead.
            for name in ("fcs/pitch-trim-cmd-norm", "fcs/roll-trim-cmd-norm", "fcs/yaw-trim-cmd-norm"):
                if self.fdm.get_property_manager().hasNode(name):
                    fdm[name] = 0.0
        if alt - ground_m < 0.0:
            raise InputError(
                f"vehicle {self.vehicle_id}: initial altitude {alt - o.alt_m:.1f} m is below the terrain "
                f"({ground_m - o.alt_m:.1f} m above the origin)"
            )
        inside = next((ob for ob in self._obstacles if ob.contains(initial.pos_ned_m)), None)
        if inside is not None:
            n_m, e_m, d_m = (float(x) for x in initial.pos_ned_m)
            raise InputError(
                f"vehicle {self.vehicle_id}: initial position (north {n_m:.1f} m, east {e_m:.1f} m, {-d_m:.1f} m above "
                f"the origin) lies inside obstacle {inside.name!r}; expected a start outside every world.obstacles box"
            )
        self._truth = self._read_truth()
        return self._truth

    def step(self, command: SurfaceCommand | RotorCommand, dt_s: float) -> TruthState:
        """Hold `command` for dt_s (a whole number of physics steps); returns the new truth."""
        self.advance(command, max(1, int(round(dt_s / self._dt_s))))
        return self.truth()

    # -- engine fast path ---------------------------------------------------------------

    def advance(self, command: SurfaceCommand | RotorCommand | None, n_steps: int) -> None:
        """Run n_steps physics steps holding `command` (None: keep the last one) without
        building a TruthState; cheap checks every step, full checks in `truth()`."""
        if command is not None and command is not self._applied:
            self._apply(command)
            self._applied = command  # commands are frozen: the same object needs no rewrite
        run = self.fdm.run
        alt_node = self._nodes[2]
        for _ in range(n_steps):
            if not run():
                raise SimulationAborted("JSBSim stopped the simulation", t_s=self._sim_time(), vehicle_id=self.vehicle_id)
        if not math.isfinite(alt_node.get_double_value()):
            raise SimulationAborted("NaN in the flight dynamics state", t_s=self._sim_time(), vehicle_id=self.vehicle_id)
        self._truth = None

    def truth(self) -> TruthState:
        """The truth at the current time (built once per time, then cached)."""
        if self._truth is None:
            self._truth = self._read_truth()
        return self._truth

    # -- internals ----------------------------------------------------------------------

    def _set_initial_velocity_in_wind(self, initial: InitialCondition) -> np.ndarray:
        """The wind through JSBSim's initial condition (run_ic hands it to FGWinds), then the
        ground velocity: a fixed wing's airspeed is through the air along its heading (no
        sideslip, the wind added over the ground), a multirotor's over the ground. Setting
        ic/vt-kts after the wind would scale the initial relative wind instead (JSBSim keeps
        the ground velocity when the wind changes), giving a sideslipping start. Returns the
        ground velocity set (3,), NED m/s."""
        fdm = self.fdm
        w_n, w_e, w_d = (float(x) for x in self._air.wind_ned_mps)
        w_h = math.hypot(w_n, w_e)
        fdm["ic/vw-mag-fps"] = w_h * M_TO_FT
        # ic/vw-dir-deg is the direction the air moves towards (measured: 270 gives a wind
        # moving west), not the meteorological "from".
        fdm["ic/vw-dir-deg"] = math.degrees(math.atan2(w_e, w_n)) % 360.0 if w_h > 0.0 else 0.0
        psi = float(initial.heading_rad)
        v = float(initial.airspeed_mps)
        v_n, v_e, v_d = v * math.cos(psi), v * math.sin(psi), 0.0
        if self.kind != "multirotor":
            v_n, v_e, v_d = v_n + w_n, v_e + w_e, v_d + w_d
        fdm["ic/vn-fps"] = v_n * M_TO_FT
        fdm["ic/ve-fps"] = v_e * M_TO_FT
        fdm["ic/vd-fps"] = v_d * M_TO_FT
        return np.array([v_n, v_e, v_d])

    def _trim_multirotor_in_wind(self, v_air_ned_mps: np.ndarray, heading_rad: float) -> float:
        """Tilt a multirotor into the relative wind so that it starts in equilibrium, as JSBSim's
        trim starts a fixed wing: the thrust balances weight and the rotors' drag,
        -c omega_i v_perp per rotor (the sidecar's rotor_drag_coefficient; v_perp the air
        velocity in the rotor plane), with T = k_T omega^2 per rotor. A few fixed-point steps
        (the drag depends on the rotor speed and on the tilt, and both on the drag). Sets the
        initial roll and pitch (heading kept); returns the motors' normalised command (thrust /
        max thrust, the same for all: the drag acts at the centre of gravity)."""
        meta = self.aircraft_meta
        m, c, k_t = float(meta["mass_kg"]), float(meta["rotor_drag_coefficient"]), float(meta["motor_thrust_constant"])
        n, t_max = self._n_motors, float(meta["max_thrust_per_motor_n"])
        g0 = STANDARD_GRAVITY_MPS2
        v_air = np.asarray(v_air_ned_mps, float)
        z_b = np.array([0.0, 0.0, 1.0])  # body down axis in NED
        thrust_n = m * g0
        for _ in range(8):
            omega_sum = n * math.sqrt(thrust_n / n / k_t)
            v_perp = v_air - (v_air @ z_b) * z_b
            drag_n = -c * omega_sum * v_perp
            f_thrust = -(m * np.array([0.0, 0.0, g0]) + drag_n)  # thrust balances weight and drag
            thrust_n = float(np.linalg.norm(f_thrust))
            z_b = -f_thrust / thrust_n
        x_c = np.array([math.cos(heading_rad), math.sin(heading_rad), 0.0])
        y_b = np.cross(z_b, x_c)
        y_b /= np.linalg.norm(y_b)
        x_b = np.cross(y_b, z_b)
        roll, pitch, _ = dcm_to_euler(np.column_stack([x_b, y_b, z_b]))
        self.fdm["ic/phi-rad"] = float(roll)
        self.fdm["ic/theta-rad"] = float(pitch)
        return _clip(thrust_n / n / t_max, 0.0, 1.0)

    def _set_turbulence(self) -> None:
        """Turbulence model, intensity and its own seeded generator (after run_ic, which
        re-initialises FGWinds)."""
        air, fdm = self._air, self.fdm
        fdm["atmosphere/wind-down-fps"] = float(air.wind_ned_mps[2]) * M_TO_FT
        if air.turbulence_type == 0:
            return
        fdm["atmosphere/randomseed"] = int(air.seed)
        fdm["atmosphere/turb-type"] = int(air.turbulence_type)
        fdm["atmosphere/turbulence/milspec/severity"] = int(air.severity_index)
        fdm["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = float(air.windspeed_at_20ft_mps) * M_TO_FT

    def _terrain_at(self, north_m: float, east_m: float) -> float:
        if self._terrain is None:
            return 0.0
        return float(self._terrain(north_m, east_m))

    def _sim_time(self) -> float:
        return self._nodes[-1].get_double_value()

    def _apply(self, command: SurfaceCommand | RotorCommand) -> None:
        fdm = self.fdm
        if isinstance(command, SurfaceCommand):
            fdm["fcs/aileron-cmd-norm"] = _clip(command.aileron, -1.0, 1.0)
            fdm["fcs/elevator-cmd-norm"] = _clip(command.elevator, -1.0, 1.0)
            fdm["fcs/rudder-cmd-norm"] = _clip(command.rudder, -1.0, 1.0)
            fdm["fcs/throttle-cmd-norm"] = _clip(command.throttle, 0.0, 1.0)
        elif isinstance(command, RotorCommand):
            if len(command.motors) != self._n_motors:
                raise InputError(
                    f"vehicle {self.vehicle_id}: {len(command.motors)} motor commands for "
                    f"{self._n_motors} motors of {self.aircraft}"
                )
            for i, u in enumerate(command.motors):
                fdm[f"fcs/throttle-cmd-norm[{i}]"] = _clip(u, 0.0, 1.0)
        else:
            raise TypeError(f"unsupported command type {type(command).__name__}")

    def _read_truth(self) -> TruthState:
        v = [n.get_double_value() for n in self._nodes]
        (lat, lon, alt_ft, vn, ve, vd, phi, theta, psi, p, q, r, pi, qi, ri, nx, ny, nz, vt, p_psf, t_r, t_s) = v
        t_s = round(t_s, 9)
        if not math.isfinite(sum(v)):  # any NaN or inf makes the sum non-finite
            raise SimulationAborted("NaN in the flight dynamics state", t_s=t_s, vehicle_id=self.vehicle_id)
        alt = alt_ft * FT_TO_M
        n_m, e_m, d_m = self._frame.geodetic_to_ned(lat, lon, alt)
        vel = np.array([vn * FT_TO_M, ve * FT_TO_M, vd * FT_TO_M])
        height_agl = -d_m - self._terrain_at(n_m, e_m)
        omega_eb = np.array([p, q, r])
        if not self._allow_ground and height_agl <= 0.0:
            raise SimulationAborted(
                f"ground contact (height above terrain {height_agl:.2f} m, vertical speed {vel[2]:.1f} m/s down)",
                t_s=t_s,
                vehicle_id=self.vehicle_id,
            )
        for ob in self._obstacles:
            if ob.contains((n_m, e_m, d_m)):
                raise SimulationAborted(
                    f"collision with obstacle {ob.name!r} at north {n_m:.1f} m, east {e_m:.1f} m, "
                    f"height {-d_m:.1f} m above the origin",
                    t_s=t_s,
                    vehicle_id=self.vehicle_id,
                )
        speed = math.sqrt(vn * vn + ve * ve + vd * vd) * FT_TO_M
        rate = max(abs(p), abs(q), abs(r))
        if speed > _MAX_SPEED_MPS or rate > _MAX_RATE_RPS:
            raise SimulationAborted(
                f"runaway state (speed {speed:.0f} m/s, body rate {rate:.1f} rad/s)",
                t_s=t_s,
                vehicle_id=self.vehicle_id,
            )
        # JSBSim's load factors: Nx, Ny along body x, y; Nz is positive UP (-z body), all in
        # units of standard gravity; specific force in FRD = g0 * (Nx, Ny, -Nz).
        g0 = STANDARD_GRAVITY_MPS2
        f_b = np.array([g0 * nx, g0 * ny, -g0 * nz])
        return TruthState(
            t_s=t_s,
            lat_rad=lat,
            lon_rad=lon,
            alt_m=alt,
            pos_ned_m=np.array([n_m, e_m, d_m]),
            vel_ned_mps=vel,
            q_nb_wxyz=_euler_to_quat_scalar(phi, theta, psi),
            rpy_rad=np.array([phi, theta, psi]),
            omega_eb_b_rps=omega_eb,
            omega_ib_b_rps=np.array([pi, qi, ri]),
            f_b_mps2=f_b,
            airspeed_mps=vt * FT_TO_M,
            height_agl_m=height_agl,
            pressure_pa=p_psf * PSF_TO_PA,
            temperature_k=t_r * RANKINE_TO_KELVIN,
            wind_ned_mps=_CALM_NED if self._wind_nodes is None
            else np.array([n.get_double_value() * FT_TO_M for n in self._wind_nodes]),
        )


def _euler_to_quat_scalar(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Z-Y-X Euler -> q_nb (w, x, y, z), w >= 0; scalar twin of rotations.euler_to_quat."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    w = cr * cp * cy + sr * sp * sy
    q = (w, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)
    return -np.array(q) if w < 0.0 else np.array(q)


def _clip(x: float, lo: float, hi: float) -> float:
    if not math.isfinite(x):
        raise SimulationAborted(f"non-finite actuator command {x!r}")
    return lo if x < lo else hi if x > hi else float(x)


__all__ = ["AirMass", "InitialCondition", "JSBSimDynamics", "KT_TO_MPS"]
