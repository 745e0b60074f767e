"""Many LSTM models in lockstep on a GPU: one step of every model is a few batched tensor
operations (``torch.baddbmm`` over the models), so one launch advances them all.

The same interface and layout as :func:`lstm_lockstep.lockstep_epoch` (parameters packed
(n_blocks, n_params, MODELS)), so the two are interchangeable and tested against each other on
the CPU. torch's sigmoid and tanh are not the numba kernels' approximation and its sums run in
another order: weights agree to float32 tolerance, not bit for bit. Unmeasured on a GPU here
(benchmarks/gpu_check.py measures it).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from slipbench.detectors.lstm_lockstep import _hidden


def _views(flat: Any, hidden: int) -> tuple:
    """(w (K, G), rt (K, H, G), b (K, G), wy (K, 2, H), by (K, 2)) of flat (K, n_params)."""
    g, k = 4 * hidden, flat.shape[0]
    o1, o2 = g, g + hidden * g
    o3, o4 = o2 + g, o2 + g + 2 * hidden
    return (
        flat[:, :o1],
        flat[:, o1:o2].reshape(k, hidden, g),
        flat[:, o2:o3],
        flat[:, o3:o4].reshape(k, 2, hidden),
        flat[:, o4 : o4 + 2],
    )


def _losses(model: tuple, xb: Any, yb: Any, weight: Any) -> Any:
    """Sum over the models of each one's mean cross-entropy on its windows xb (K, B, T);
    ``weight`` (K, B) is 1 / (the model's batch) for its windows and 0 for padding."""
    import torch

    w, rt, b, wy, by = model
    k, n, _ = xb.shape
    hidden = rt.shape[1]
    h = xb.new_zeros((k, n, hidden))
    c = xb.new_zeros((k, n, hidden))
    for t in range(xb.shape[2]):
        a = torch.baddbmm(b[:, None, :] + w[:, None, :] * xb[:, :, t, None], h, rt)
        i, f, g, o = a.split(hidden, dim=2)
        c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
        h = torch.sigmoid(o) * torch.tanh(c)
    logits = torch.baddbmm(by[:, None, :], h, wy.transpose(1, 2))
    ce = torch.nn.functional.cross_entropy(
        logits.reshape(k * n, 2), yb.reshape(-1), reduction="none"
    )
    return (ce.reshape(k, n) * weight).sum()


def lockstep_epoch(
    data: tuple, plan: tuple, params: np.ndarray, velocity: np.ndarray, device: str = "cuda"
) -> None:
    """:func:`lstm_lockstep.lockstep_epoch` in torch on ``device``; ``params`` and
    ``velocity`` updated in place."""
    import torch

    x, y = data
    orders, counts, lr, batch_size, momentum = plan
    n_blocks, n_params, lanes = params.shape
    hidden = _hidden(n_params)
    dev = torch.device(device)

    def flat(a):
        return torch.tensor(a.transpose(0, 2, 1).reshape(n_blocks * lanes, n_params), device=dev)

    p, v = flat(params).requires_grad_(True), flat(velocity)
    xs, ys = torch.tensor(x, device=dev), torch.tensor(y, device=dev).long()
    order_t, count_t = torch.tensor(orders, device=dev), torch.tensor(counts, device=dev)
    rate = torch.tensor(lr, device=dev)[:, None]
    for start in range(0, int(counts.max()), batch_size):
        cols = torch.arange(start, min(start + batch_size, orders.shape[1]), device=dev)
        rows = order_t[:, cols]  # (K, B)
        valid = cols[None, :] < count_t[:, None]
        size = valid.sum(1, keepdim=True)
        weight = valid / size.clamp(min=1)
        loss = _losses(_views(p, hidden), xs[rows], ys[rows], weight)
        (grad,) = torch.autograd.grad(loss, p)
        with torch.no_grad():
            moving = size > 0
            step = torch.where(moving, momentum * v - rate * grad, v)
            v.copy_(step)
            p.add_(torch.where(moving, step, torch.zeros_like(step)))

    def back(t):
        return t.detach().cpu().numpy().reshape(n_blocks, lanes, n_params).transpose(0, 2, 1)

    params[:] = back(p)
    velocity[:] = back(v)
