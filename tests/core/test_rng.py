"""Seeded streams: same name path -> same stream, independent of build order."""

import numpy as np

from testbench.core.rng import RngStreams, run_seed_sequences


def test_same_path_same_stream_and_order_independence():
    a = RngStreams(5)
    x1 = a.generator("vehicle", "uav0", "sensor", "imu").normal(size=4)
    a.generator("vehicle", "uav1", "sensor", "gnss").normal(size=100)
    x2 = a.generator("vehicle", "uav0", "sensor", "imu").normal(size=4)
    np.testing.assert_array_equal(x1, x2)
    y = RngStreams(5).generator("vehicle", "uav0", "sensor", "gnss").normal(size=4)
    assert not np.allclose(x1, y)
    assert not np.allclose(x1, RngStreams(6).generator("vehicle", "uav0", "sensor", "imu").normal(size=4))


def test_monte_carlo_children_differ_and_repeat():
    seqs = run_seed_sequences(11, 3)
    a = [RngStreams(s).generator("x").integers(1 << 30) for s in seqs]
    b = [RngStreams(s).generator("x").integers(1 << 30) for s in run_seed_sequences(11, 3)]
    assert a == b and len(set(a)) == 3
