"""Target assignment and loss: finite on edge cases, and it trains."""

from __future__ import annotations

import torch

from avsim.perception.detector.assign import assign_targets
from avsim.perception.detector.boxes import flatten_outputs
from avsim.perception.detector.loss import compute_loss
from avsim.perception.detector.model import STRIDES, build_detector

H_IN, W_IN = 128, 160


def _model() -> torch.nn.Module:
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        return build_detector(width_mult=0.5)


def _target(boxes: list[list[float]], classes: list[int]) -> dict[str, torch.Tensor]:
    return {"boxes": torch.tensor(boxes, dtype=torch.float32).reshape(-1, 4), "classes": torch.tensor(classes, dtype=torch.long)}


def _cells():
    outputs = [torch.zeros(1, 8, H_IN // s, W_IN // s) for s in STRIDES]
    _, centres, strides = flatten_outputs(outputs, STRIDES)
    return centres, strides


def test_assignment_gives_every_box_a_cell_at_the_right_scale():
    centres, strides = _cells()
    tiny, small, large = [50.3, 40.2, 55.1, 46.0], [10.0, 10.0, 30.0, 40.0], [60.0, 20.0, 150.0, 120.0]
    assigned = assign_targets([_target([tiny, small, large], [0, 1, 2])], centres, strides)
    pos = assigned.positive[0]
    for k, box in enumerate([tiny, small, large]):
        cells = pos & (assigned.boxes[0] == torch.tensor(box)).all(dim=1)
        assert cells.any(), f"box {k} has no positive cell"
        assert (assigned.classes[0][cells] == k).all()
    large_cells = pos & (assigned.classes[0] == 2)
    assert (strides[large_cells] == 16).all()  # 100 px: stride 16 only
    tiny_cells = pos & (assigned.classes[0] == 0)
    assert (strides[tiny_cells] == 8).all() and 1 <= int(tiny_cells.sum()) <= 4
    assert (assigned.classes[0][~pos] == -1).all()


def test_loss_finite_on_empty_targets_and_pushes_objectness_down():
    model = _model().train()
    outputs = model(torch.rand(2, 3, H_IN, W_IN))
    losses = compute_loss(outputs, [_target([], []), _target([], [])])
    assert set(losses) == {"obj", "cls", "box", "total"}
    assert all(torch.isfinite(v) for v in losses.values())
    assert losses["cls"].item() == 0 and losses["box"].item() == 0 and losses["obj"].item() > 0
    losses["total"].backward()
    obj_bias_grad = model.heads[0].reg_pred.bias.grad[0]
    assert obj_bias_grad > 0  # gradient descent lowers the objectness logit


def test_loss_finite_with_tiny_and_degenerate_boxes():
    model = _model().train()
    outputs = model(torch.rand(2, 3, H_IN, W_IN))
    targets = [_target([[10.0, 10.0, 13.0, 14.0], [100.2, 50.0, 100.7, 58.0]], [0, 1]), _target([[0.0, 0.0, 8.0, 8.0]], [2])]
    losses = compute_loss(outputs, targets)
    assert all(torch.isfinite(v) for v in losses.values())
    assert losses["box"].item() > 0 and losses["cls"].item() > 0
    losses["total"].backward()
    assert all(torch.isfinite(p.grad).all() for p in model.parameters() if p.grad is not None)


def test_loss_decreases_on_a_tiny_set():
    model = _model().train()
    generator = torch.Generator().manual_seed(0)
    images = torch.rand(4, 3, H_IN, W_IN, generator=generator) * 0.2
    targets = []
    for i in range(4):
        x0, y0 = 20 + 25 * i, 30 + 10 * i
        size = 12 + 8 * i
        images[i, 0, y0:y0 + size, x0:x0 + size] = 0.9
        targets.append(_target([[x0, y0, x0 + size, y0 + size]], [i % 3]))
    optimizer = torch.optim.AdamW(model.parameters(), lr=3e-3)
    history = []
    for _ in range(30):
        losses = compute_loss(model(images), targets)
        optimizer.zero_grad()
        losses["total"].backward()
        optimizer.step()
        history.append({k: v.item() for k, v in losses.items()})
    assert history[-1]["total"] < 0.5 * history[0]["total"]
    for term in ("obj", "cls", "box"):
        assert history[-1][term] < history[0][term], term
