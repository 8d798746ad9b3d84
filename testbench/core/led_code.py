"""The LED blink code that carries each vehicle's identity to its neighbours' cameras.

No data link: a vehicle's ID reaches the others only through the on/off pattern of its LEDs.

Timing assumption (shared clock): every vehicle toggles its LEDs in step with a clock shared by
the swarm (in practice the UWB TDMA schedule synchronises it) at `led_rate_hz`; the chip shown
at time t is chip number `frame_index = floor(t_s * led_rate_hz)` of the vehicle's code word,
repeated cyclically. Cameras sample at >= led_rate_hz (normally equal: the camera frame rate),
so every chip is seen at least once; a decoder that knows the frame index knows the phase of
the code and needs no search (it can still search all cyclic shifts when the clock is not
shared: `IdDecoder(search_phase=True)`).

Code word of vehicle index k (its position in the scenario's vehicle list):
  preamble (1, 1, 1, 0) + Manchester(ID bits of k, MSB first, + even parity bit),
Manchester: bit 1 -> chips (1, 0), bit 0 -> chips (0, 1). Two IDs differ in >= 1 ID bit and
then also in parity, so any two code words differ in >= 4 chips (minimum Hamming distance 4):
one chip error is corrected, and a missed frame is an erasure that costs nothing but time.

LED states: LED 0 (the anchor) is always on so the vehicle stays detectable; LEDs 1..n-1 all
show the current chip, so a camera that cannot resolve single LEDs (a few pixels at 100 m)
still sees the group's brightness switch between "anchor only" and "all on". With one LED
only, it shows the chip itself (the preamble keeps it on 3/4 of the first four frames).
"""

from __future__ import annotations

import math

import numpy as np

ID_BITS = 5  # 32 vehicle indices
PREAMBLE = (1, 1, 1, 0)
MAX_VEHICLES = 1 << ID_BITS
CODE_LENGTH = len(PREAMBLE) + 2 * (ID_BITS + 1)  # 16 chips: 1.6 s at 10 Hz


def code_word(vehicle_index: int) -> tuple[int, ...]:
    """The cyclic chip sequence (0/1, length CODE_LENGTH) of vehicle `vehicle_index`."""
    k = int(vehicle_index)
    if not 0 <= k < MAX_VEHICLES:
        raise ValueError(f"vehicle_index must be in [0, {MAX_VEHICLES}) (got {vehicle_index})")
    bits = [(k >> (ID_BITS - 1 - i)) & 1 for i in range(ID_BITS)]
    bits.append(sum(bits) % 2)  # even parity
    chips: list[int] = list(PREAMBLE)
    for b in bits:
        chips += [1, 0] if b else [0, 1]
    return tuple(chips)


def chip(vehicle_index: int, frame_index: int) -> int:
    """Chip (0/1) shown by vehicle `vehicle_index` at LED frame `frame_index`."""
    return code_word(vehicle_index)[int(frame_index) % CODE_LENGTH]


def frame_index(t_s: float, led_rate_hz: float) -> int:
    """LED frame number at time t_s on the shared clock: floor(t_s * led_rate_hz).

    A small tolerance keeps t_s = k / rate (which floats may store a hair below) in frame k.
    """
    return int(math.floor(t_s * led_rate_hz + 1e-6))


def led_states(vehicle_index: int, frame_index: int, n_leds: int) -> tuple[bool, ...]:
    """On/off state of each of the `n_leds` LEDs of a vehicle at LED frame `frame_index`.

    LED 0 is always on (n_leds >= 2); the others show the chip. The engine calls this with
    frame_index = floor(t_s * led_rate_hz) when it draws the vehicle into a camera frame.
    """
    if n_leds <= 0:
        return ()
    c = bool(chip(vehicle_index, frame_index))
    if n_leds == 1:
        return (c,)
    return (True,) + (c,) * (n_leds - 1)


def codebook(n_vehicles: int) -> np.ndarray:
    """Code words of vehicle indices 0..n_vehicles-1: (n_vehicles, CODE_LENGTH) uint8."""
    if not 0 < n_vehicles <= MAX_VEHICLES:
        raise ValueError(f"n_vehicles must be in [1, {MAX_VEHICLES}] (got {n_vehicles})")
    return np.array([code_word(k) for k in range(n_vehicles)], dtype=np.uint8)


def min_distance(n_vehicles: int) -> int:
    """Minimum Hamming distance between the code words of n_vehicles (>= 4 for n >= 2)."""
    cb = codebook(n_vehicles).astype(int)
    if len(cb) < 2:
        return CODE_LENGTH
    d = (cb[:, None, :] != cb[None, :, :]).sum(axis=2)
    return int(d[~np.eye(len(cb), dtype=bool)].min())
