"""The detector's heads and losses on the detection form: K = 2 learned-background Dirichlet per
location, EDL loss gradients (gradcheck), label assignment and box decoding with exact numbers."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from evids.heads import EvidentialHead
from evids.losses import edl_loss
from evids.models.detector import (
    STRIDE,
    CentreDetector,
    DetectorOutput,
    FeatureFusionDetector,
    decode_peaks,
    detection_loss,
    encode_targets,
)


def test_evidential_head_is_k2_per_location():
    torch.manual_seed(0)
    m = CentreDetector(1, "evidential", width=8).eval()
    out = m(torch.randn(2, 1, 32, 40))
    assert out.alpha.shape == (2, 8, 10, 2)
    assert bool((out.alpha >= 1).all())
    s = out.alpha.sum(-1)
    torch.testing.assert_close(out.prob, out.alpha[..., 0] / s)
    torch.testing.assert_close(out.vacuity, 2.0 / s)
    assert out.box.shape == (2, 4, 8, 10)


def test_sigmoid_head_has_no_vacuity():
    m = CentreDetector(3, "sigmoid", width=8).eval()
    out = m(torch.zeros(1, 3, 16, 16))
    assert out.alpha is None and out.logit.shape == (1, 4, 4)
    assert bool(torch.isnan(out.vacuity).all())
    torch.testing.assert_close(out.prob, torch.sigmoid(out.logit))


def test_fusion_detector_shapes_and_attention_weights():
    torch.manual_seed(0)
    m = FeatureFusionDetector(width=8).eval()
    out = m(torch.zeros(1, 3, 32, 32), torch.zeros(1, 1, 32, 32))
    assert out.prob.shape == (1, 8, 8)
    w = m.channel_weights(torch.zeros(1, 3, 32, 32), torch.zeros(1, 1, 32, 32))
    assert w.shape == (1, 2) and bool(((w > 0) & (w < 1)).all())


def test_wrong_channel_count_is_refused():
    with pytest.raises(ValueError, match="in_channels"):
        CentreDetector(2, "sigmoid")
    with pytest.raises(ValueError, match="shape"):
        CentreDetector(1, "sigmoid")(torch.zeros(1, 3, 16, 16))
    with pytest.raises(ValueError, match="head"):
        CentreDetector(1, "softmax")  # type: ignore[arg-type]


def test_edl_loss_gradcheck_on_per_location_alpha():
    """Gradients of the EDL loss through the per-location evidential head, (B, h, w, 2) form."""
    torch.manual_seed(0)
    head = EvidentialHead(3, 2).double()
    z = torch.randn(1, 2, 3, 3, dtype=torch.float64, requires_grad=True)
    target = torch.tensor([[[0, 1, 1], [1, 1, 0]]])

    def f(z):
        return edl_loss(head(z), target, epoch=3.0, anneal_epochs=10.0, reduction="sum")

    assert torch.autograd.gradcheck(f, (z,), eps=1e-6, atol=1e-5)


def test_k1_is_rejected_for_detection():
    with pytest.raises(ValueError, match="num_classes=1"):
        EvidentialHead(4, 1)


def test_encode_targets_exact_cells():
    # a 12 x 6 box with its centre at (106, 53): centre cell (row 13, col 26); the half-size core
    # keeps cells whose centre lies within 3 px (x) and 1.5 px (y) of it
    label, reg, n = encode_targets([np.array([[100, 50, 12, 6]]), np.zeros((0, 4))], 64, 128)
    assert label.shape == (2, 16, 32)
    pos = np.argwhere(label[0].numpy() == 1).tolist()
    assert pos == [[13, 26]]
    assert int(n[0]) == 1 and int(n[1]) == 0
    ign = np.argwhere(label[0].numpy() == -1).tolist()
    assert ign == [[12, 25], [12, 26], [12, 27], [13, 25], [13, 27]]  # other cells inside the box
    assert reg[0, :, 13, 26].tolist() == pytest.approx([106 / 4 - 26.5, 53 / 4 - 13.5, np.log(12), np.log(6)])
    assert bool((label[1] == 0).all())


def test_decode_inverts_encode():
    box = np.array([[60.0, 20.0, 10.0, 8.0]])
    label, reg, _ = encode_targets([box], 64, 96)
    prob = torch.where(label == 1, 0.5, 0.0)
    prob[0, 24 // 4, 65 // 4] = 0.9  # the centre cell is the peak; its 3x3 neighbours are suppressed
    prob[0, 0, 0] = 0.2  # a weaker, isolated peak
    dets = decode_peaks(prob, reg, 0.1, 5)[0]
    assert dets["scores"].tolist() == pytest.approx([0.9, 0.2])
    np.testing.assert_allclose(dets["boxes"][0], box[0], atol=1e-5)
    assert decode_peaks(prob, reg, 0.95, 5)[0]["boxes"].shape == (0, 4)


def test_detection_loss_both_heads_and_ignore_cells():
    torch.manual_seed(0)
    label, reg, _ = encode_targets([np.array([[10, 10, 8, 8]])], 32, 32)
    for head in ("sigmoid", "evidential"):
        m = CentreDetector(1, head, width=8)
        out = m(torch.randn(1, 1, 32, 32))
        loss, parts = detection_loss(out, label, reg, epoch=1.0, anneal_epochs=10.0)
        loss.backward()
        assert np.isfinite(parts["cls"]) and np.isfinite(parts["box"]) and parts["box"] > 0
        assert all(p.grad is not None for p in m.parameters() if p.requires_grad)
    # ignored cells do not change the loss
    out = DetectorOutput(prob=torch.full((1, 8, 8), 0.5), box=torch.zeros(1, 4, 8, 8),
                         alpha=torch.ones(1, 8, 8, 2), logit=None)
    a, _ = detection_loss(out, label, reg, 0.0, 1.0)
    out.alpha[label == -1] = torch.tensor([50.0, 1.0])
    b, _ = detection_loss(out, label, reg, 0.0, 1.0)
    assert float(a) == pytest.approx(float(b))


def test_stride_is_four():
    assert STRIDE == 4
