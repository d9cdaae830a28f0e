"""Decoding the heads: one cell by hand, row order, and gradients from scores to pixels."""

import math

import torch

from avsim.perception.yolo.cfg import parse_cfg_text
from avsim.perception.yolo.decode import decode_head, score_rows
from avsim.perception.yolo.model import load_yolo
from avsim.perception.yolo.network import DarknetNetwork
from tests.perception.yolo.darknet_files import TINY_CFG


def test_one_cell_decodes_as_darknet_does():
    head = DarknetNetwork(parse_cfg_text(TINY_CFG)).heads[0]  # anchors (8, 9), (16, 12), (30, 28); 2 classes
    raw = torch.zeros(1, 3 * 7, 4, 5)
    # anchor 2, row 1, column 3: t_x = 0.4, t_y = -1, t_w = 0.5, t_h = -0.2, objectness logit 2, class logits (-1, 3)
    raw.view(1, 3, 7, 4, 5)[0, 2, :, 1, 3] = torch.tensor([0.4, -1.0, 0.5, -0.2, 2.0, -1.0, 3.0])
    decoded = decode_head(raw, head, (32, 40))  # 4 x 5 cells of 8 px
    row = (1 * 5 + 3) * 3 + 2
    sig = lambda v: 1 / (1 + math.exp(-v))  # noqa: E731
    cx, cy = (3 + (sig(0.4) - 0.5) * 1.05 + 0.5) * 8, (1 + (sig(-1.0) - 0.5) * 1.05 + 0.5) * 8
    w, h = math.exp(0.5) * 30, math.exp(-0.2) * 28
    assert torch.allclose(decoded.boxes_xyxy[0, row], torch.tensor([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2]))
    assert math.isclose(decoded.objectness[0, row].item(), sig(2.0), rel_tol=1e-6)
    assert torch.allclose(decoded.class_scores()[0, row], torch.tensor([sig(2) * sig(-1), sig(2) * sig(3)]))
    assert decoded.boxes_xyxy.shape == (1, 60, 4) and decoded.class_prob.shape == (1, 60, 2)


def test_score_rows_are_every_box_and_class_over_the_threshold_best_first():
    head = DarknetNetwork(parse_cfg_text(TINY_CFG)).heads[1]
    raw = torch.full((1, 2 * 7, 2, 2), -8.0)
    raw.view(1, 2, 7, 2, 2)[0, 1, 4:, 0, 1] = torch.tensor([4.0, 3.0, 2.0])  # one box, both classes high
    rows = score_rows(decode_head(raw, head, (4, 4)), 0.5)
    assert rows.shape == (2, 6) and rows[:, 5].tolist() == [0.0, 1.0] and rows[0, 4] > rows[1, 4] > 0.5
    assert torch.equal(rows[0, :4], rows[1, :4])


def test_class_scores_are_differentiable_with_respect_to_pixels():
    model = load_yolo()
    image = torch.full((1, 3, 64, 96), 128.0, requires_grad=True)
    boxes, scores = model(image)
    assert boxes.shape == (1, (2 * 3 + 4 * 6) * 3, 4) and scores.shape[-1] == 80
    scores[..., model.class_names.index("stop sign")].max().backward()
    assert image.grad is not None and image.grad.abs().sum() > 0 and torch.isfinite(image.grad).all()
