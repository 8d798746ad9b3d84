"""CNN detector: network shapes, NMS, packaged weights, evaluation on a small rendered set
(trained model passes, random-init fails), determinism of the rendered dataset."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from testbench.navigation.relative.cnn import dataset  # noqa: E402
from testbench.navigation.relative.cnn.detector import CnnDetector, packaged_weights_path  # noqa: E402
from testbench.navigation.relative.cnn.evaluate import evaluate_samples, match  # noqa: E402
from testbench.navigation.relative.cnn.model import (  # noqa: E402
    STRIDE, TinyCenterNet, decode, encode_targets, inference_copy, nms, to_tensor)

# One held-out world, small and coarse so that the test renders in a few seconds.
SMALL = dataset.DataSettings(crop_px=128, worlds=(dataset.EVAL_WORLDS[0], dataset.EVAL_WORLDS[2]),
                             world_size_km=2.0, world_gsd_m=2.0, p_negative=0.0, p_second=0.0)


@pytest.fixture(scope="module")
def small_set():
    return dataset.make_samples(40, 2024, SMALL, range_m=(50.0, 100.0))


def test_output_shapes():
    m = TinyCenterNet().eval()
    with torch.no_grad():
        for h, w in ((64, 64), (96, 128), (100, 60)):
            out = m(torch.zeros(2, 3, h, w))
            assert out.shape == (2, 5, -(-h // STRIDE), -(-w // STRIDE))


def test_inference_copy_same_function():
    """The detector's inference copy (BatchNorm folded, channels-last) computes what the
    network does, to float rounding, and leaves the network as it was."""
    torch.manual_seed(3)
    m = TinyCenterNet()
    with torch.no_grad():  # BatchNorm statistics away from the identity, so folding matters
        for mod in m.modules():
            if isinstance(mod, torch.nn.BatchNorm2d):
                mod.running_mean.uniform_(-0.5, 0.5)
                mod.running_var.uniform_(0.5, 2.0)
                mod.weight.uniform_(0.5, 1.5)
                mod.bias.uniform_(-0.2, 0.2)
    m.eval()
    fast = inference_copy(m)
    assert sum(isinstance(x, torch.nn.BatchNorm2d) for x in m.modules()) == 7
    assert not any(isinstance(x, torch.nn.BatchNorm2d) for x in fast.modules())
    img = np.random.default_rng(0).integers(0, 256, (1, 70, 90, 3), dtype=np.uint8)
    with torch.inference_mode():
        ref, out = m(to_tensor(img)), fast(to_tensor(img))
    assert out.shape == ref.shape
    assert float((out - ref).abs().max()) < 1e-4 * max(1.0, float(ref.abs().max()))


def test_targets_decode_round_trip():
    """An ideal network output built from the targets decodes to the same centres and sizes."""
    cs, ss = [np.array([[10.3, 21.7], [40.0, 5.2]])], [np.array([[3.0, 2.0], [30.0, 12.0]])]
    heat, reg, mask = encode_targets(cs, ss, 64, 64)
    out = torch.zeros(1, 5, 16, 16)
    out[:, :1] = torch.logit(heat.clamp(1e-4, 1 - 1e-4))
    out[:, 1:3] = torch.logit(reg[:, :2].clamp(1e-6, 1 - 1e-6))
    out[:, 3:5] = reg[:, 2:]
    d = decode(out, 0.5)[0]
    assert len(d) == 2
    d = d[np.argsort(d[:, 0])]
    np.testing.assert_allclose(d[:, :2], cs[0], atol=1e-3)
    np.testing.assert_allclose(d[:, 2:4], ss[0], rtol=1e-4)


def test_nms():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [50, 50, 60, 60], [100, 100, 102, 102], [101, 100, 103, 102]], float)
    scores = np.array([0.9, 0.8, 0.7, 0.6, 0.95])
    keep = nms(boxes, scores, iou_max=0.4, centre_px=3.0)
    # 1 overlaps 0 (IoU 0.68); 3 is 1 px from the better 4 (tiny boxes: centre rule).
    assert keep.tolist() == [4, 0, 2]
    assert nms(boxes, scores, iou_max=1.0, centre_px=0.0, centre_frac=0.0).tolist() == [4, 0, 1, 2, 3]
    # A poorly sized duplicate on a large target: centre within half the kept box's side.
    big = np.array([[0, 0, 40, 10], [12, 2, 16, 6]], float)
    assert nms(big, np.array([0.9, 0.6])).tolist() == [0]
    assert nms(np.zeros((0, 4)), np.zeros(0)).size == 0


def test_match_criterion():
    truth, wh = np.array([[10.0, 10.0], [50.0, 50.0]]), np.array([[2.0, 2.0], [20.0, 10.0]])
    assert match(np.array([[12.5, 10.0], [58.0, 50.0], [80.0, 80.0]]), truth, wh) == (2, 1, 0)
    assert match(np.array([[13.5, 10.0]]), truth, wh) == (0, 1, 2)


def test_packaged_weights_load():
    assert packaged_weights_path().is_file()
    det = CnnDetector()
    assert det.model.widths == tuple(det.model.widths)
    assert det.detect(np.zeros((64, 64, 3), np.uint8)) == []


def test_detector_runs_torch_on_one_thread_unless_told():
    """The regions are too small for intra-op threads (CnnDetector's docstring): one thread by
    default, the scenario's `threads` when given."""
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        CnnDetector()
        assert torch.get_num_threads() == 1
        CnnDetector(CnnDetector.Params(threads=2))
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_dataset_deterministic():
    s = dataset.DataSettings(crop_px=48, worlds=SMALL.worlds, world_size_km=2.0, world_gsd_m=2.0)
    a, b = dataset.make_samples(6, 5, s), dataset.make_samples(6, 5, s)
    c = dataset.make_samples(6, 6, s)
    for x, y in zip(a, b):
        assert x.roi == y.roi and np.array_equal(x.image, y.image) and np.array_equal(x.centres_px, y.centres_px)
    assert any(not np.array_equal(x.image, z.image) for x, z in zip(a, c))


def test_trained_model_detects_and_random_init_does_not(small_set):
    """40 held-out crops with one vehicle at 50-100 m: the packaged model finds them; a
    random-init network of the same architecture does not."""
    n_truth = sum(len(s.centres_px) for s in small_set)
    assert n_truth >= 38
    tp, fp, fn = evaluate_samples(CnnDetector(), small_set)
    assert tp / (tp + fn) >= 0.85 and tp / max(tp + fp, 1) >= 0.85, (tp, fp, fn)
    torch.manual_seed(0)
    rand = CnnDetector.from_model(TinyCenterNet())
    tp, fp, fn = evaluate_samples(rand, small_set)
    assert not (tp / (tp + fn) >= 0.85 and tp / max(tp + fp, 1) >= 0.85), (tp, fp, fn)
