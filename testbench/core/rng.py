"""Seeded random streams: all randomness flows from the scenario seed (DESIGN.md).

A run owns one `RngStreams`; each consumer asks for a generator by a stable name path
(e.g. ("vehicle", "uav0", "sensor", "imu")). The name path becomes the SeedSequence spawn key
(CRC-32 of each name), so a stream depends only on the seed and its name, never on the order in
which components are built. Adding a sensor therefore leaves every other stream unchanged.
"""

from __future__ import annotations

import zlib

import numpy as np


def _key(name: str | int) -> int:
    if isinstance(name, int):
        return name
    return zlib.crc32(name.encode("utf-8"))


class RngStreams:
    """Factory of independent numpy Generators keyed by name, from one SeedSequence.

    seed: an int (the scenario seed) or a SeedSequence (a Monte Carlo run's child sequence).
    """

    def __init__(self, seed: int | np.random.SeedSequence):
        if isinstance(seed, np.random.SeedSequence):
            self._entropy = seed.entropy
            self._base_key = tuple(seed.spawn_key)
        else:
            self._entropy = int(seed)
            self._base_key = ()

    def seed_sequence(self, *names: str | int) -> np.random.SeedSequence:
        """The SeedSequence of the stream at this name path."""
        return np.random.SeedSequence(
            entropy=self._entropy, spawn_key=self._base_key + tuple(_key(n) for n in names)
        )

    def generator(self, *names: str | int) -> np.random.Generator:
        """A fresh PCG64 Generator for the name path; the same path gives the same stream."""
        return np.random.Generator(np.random.PCG64(self.seed_sequence(*names)))


def run_seed_sequences(seed: int, runs: int) -> list[np.random.SeedSequence]:
    """The per-run seed sequences of a Monte Carlo batch: SeedSequence(seed).spawn(runs)."""
    return np.random.SeedSequence(int(seed)).spawn(int(runs))
