"""UWB two-way ranging between the swarm's nodes with round-robin (TDMA) scheduling.

Node i (scenario order, ctx.vehicle_ids) transmits in slot i; a cycle is N slots of
slot_time_s. At each slot every other node measures its range to the transmitter, so the
sensor runs at 1 / slot_time_s and returns a UwbRange (peer_id = transmitter) or None when this
vehicle transmits, the peer is out of range (max_range_m) or absent. Each ordered pair is thus
measured once per cycle, at 1 / (N slot_time_s).

A link is NLOS when terrain (world.terrain_height_m) or an obstacle box (world.obstacles or
params.obstacles) cuts the segment between the antennas, or with nlos_probability. Both
antennas sit at lever_arm_b_m in their body axes (the swarm shares one installation).
Channel physics: `uwb_channel`.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, model_validator

from testbench.config.schema import ObstacleBox
from testbench.core.errors import InputError
from testbench.core.interfaces import BuildContext, WorldView
from testbench.core.messages import TruthState, UwbRange
from testbench.core.obstacles import segment_below_terrain
from testbench.core.registry import ParamsModel, register
from testbench.core.rotations import quat_to_dcm
from testbench.sensors.base import CachedSensor, check_rate
from testbench.sensors.uwb_channel import ChannelSpec, measure_ranges


class UwbParams(ParamsModel):
    """rate_hz, if given, must equal 1 / slot_time_s. t1_ns: median rms delay spread at 1 km;
    epsilon in [0.5, 1]; sigma_ln_xi: std of ln xi (natural log); path loss in dB."""

    slot_time_s: float = Field(0.01, gt=0)
    rate_hz: float | None = Field(None, gt=0)
    range_sigma_m: float = Field(0.10, ge=0)
    max_range_m: float = Field(200.0, gt=0)
    t1_ns: float = Field(19.0, ge=0)
    epsilon: float = Field(0.5, ge=0.5, le=1.0)
    sigma_ln_xi: float = Field(0.5, ge=0)
    tx_power_dbm: float = -14.3
    pl0_db: float = 40.0
    d0_m: float = Field(1.0, gt=0)
    path_loss_exponent: float = Field(2.0, gt=0)
    shadowing_db: float = Field(2.0, ge=0)
    nlos_loss_db: float = Field(10.0, ge=0)
    nlos_probability: float = Field(0.0, ge=0, le=1)
    terrain_step_m: float = Field(10.0, gt=0)
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    obstacles: list[ObstacleBox] = []  # the radio's own, beside world.obstacles

    @model_validator(mode="after")
    def _rate_matches_slot(self):
        if self.rate_hz is not None and abs(self.rate_hz * self.slot_time_s - 1.0) > 1e-9:
            raise ValueError(f"rate_hz {self.rate_hz} must be 1 / slot_time_s = {1 / self.slot_time_s}")
        return self

    def channel(self) -> ChannelSpec:
        return ChannelSpec(
            sigma_m=self.range_sigma_m, t1_s=self.t1_ns * 1e-9, eps=self.epsilon, sigma_ln_xi=self.sigma_ln_xi,
            tx_power_dbm=self.tx_power_dbm, pl0_db=self.pl0_db, d0_m=self.d0_m, n_p=self.path_loss_exponent,
            shadowing_db=self.shadowing_db, nlos_loss_db=self.nlos_loss_db, nlos_probability=self.nlos_probability,
        )


def antenna_ned_m(truth: TruthState, lever_arm_b_m: np.ndarray) -> np.ndarray:
    """Antenna position in NED: CG position plus the body lever arm rotated by R_nb."""
    pos = np.asarray(truth.pos_ned_m, float)
    if not lever_arm_b_m.any():
        return pos
    return pos + quat_to_dcm(truth.q_nb_wxyz) @ lever_arm_b_m


@register("sensor", "uwb")
class Uwb(CachedSensor):
    """Returns UwbRange to the slot's transmitter, or None (see module doc)."""

    Params = UwbParams

    def __init__(self, params: UwbParams, *, ctx: BuildContext):
        super().__init__()
        self.params = params
        self.name = "uwb"
        self.rate_hz = check_rate(1.0 / params.slot_time_s, ctx, "uwb")
        self.ids = tuple(ctx.vehicle_ids)
        if ctx.vehicle_id not in self.ids:
            raise InputError(f"uwb: vehicle {ctx.vehicle_id!r} is not in the scenario's vehicles {self.ids}")
        self.self_id = ctx.vehicle_id
        self.spec = params.channel()
        self.lever = np.asarray(params.lever_arm_b_m, float)
        self.obstacles = [o.obstacle(f"uwb obstacle {i}") for i, o in enumerate(params.obstacles, start=1)]
        self.last_nlos: bool | None = None  # truth of the last link, for diagnostics only

    def transmitter(self, t_s: float) -> str:
        """The node transmitting in the slot that contains t_s."""
        return self.ids[int(round(t_s / self.params.slot_time_s)) % len(self.ids)]

    def blocked(self, p0: np.ndarray, p1: np.ndarray, world: WorldView) -> bool:
        """Whether terrain or an obstacle cuts the segment between two antennas (NED, m)."""
        for ob in list(getattr(world, "obstacles", ()) or ()) + self.obstacles:
            if ob.hits_segment(p0, p1):
                return True
        terrain = getattr(world, "terrain_height_m", None)
        return terrain is not None and segment_below_terrain(p0, p1, terrain, self.params.terrain_step_m)

    def _sample(self, truth: TruthState, world: WorldView, rng: np.random.Generator) -> UwbRange | None:
        tx = self.transmitter(truth.t_s)
        self.last_nlos = None
        if tx == self.self_id or tx not in world.vehicles:
            return None
        p_self = antenna_ned_m(truth, self.lever)
        p_tx = antenna_ned_m(world.vehicles[tx], self.lever)
        d = float(np.linalg.norm(p_tx - p_self))
        if d > self.params.max_range_m:
            return None
        r, rss, nlos = measure_ranges(np.array([d]), np.array([self.blocked(p_self, p_tx, world)]), self.spec, rng)
        self.last_nlos = bool(nlos[0])
        return UwbRange(truth.t_s, tx, float(r[0]), float(rss[0]))
