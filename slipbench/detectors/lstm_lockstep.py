"""Many LSTM models trained in lockstep on the CPU: one SGD step advances a block of MODELS
models, one per SIMD lane, each on its own window, label, learning rate and batch.

The paper's network (20 units, one input) is too small to keep a core busy alone: a step of one
model is a chain of short loops, latency-bound. Laid out (row, model) with the model innermost,
every operation of a step works on a vector of independent models (:mod:`lstm_simd`). Each
model's arithmetic is :func:`lstm_kernels._train_epoch`'s, operation for operation (the same
order, no fused multiply-adds), so a model trained here gets the weights it gets alone, bit for
bit. A lane whose model has no window in a step (its epoch is over, it stopped early, its last
batch is shorter, or the lane is empty) is masked: its parameters and velocities do not move.

Parameters live in one flat vector per model (:func:`flat_layout`: w, rt, b, wy, by); a block
of models is an array (n_params, MODELS), the model innermost, and a group of blocks
(n_blocks, n_params, MODELS). Blocks are independent: several run in parallel (numba threads),
and no result depends on the thread count.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from slipbench.detectors import lstm_simd as v
from slipbench.detectors.lstm_kernels import (
    _A1,
    _A3,
    _A5,
    _A7,
    _A9,
    _A11,
    _A13,
    _B0,
    _B2,
    _B4,
    _B6,
    _CLAMP,
    _HALF,
    _ONE,
    F32,
    N_CHUNKS,
    P_DH,
    _train_jit,
    _twice,
)

MODELS = v.WIDTH  # models per block: the lanes of a vector


def flat_layout(hidden: int) -> list[tuple[int, int, tuple[int, ...]]]:
    """(start, stop, shape) of w, rt, b, wy, by in a model's flat parameter vector."""
    g = 4 * hidden
    out, start = [], 0
    for shape in [(g,), (hidden, g), (g,), (2, hidden), (2,)]:
        stop = start + int(np.prod(shape))
        out.append((start, stop, shape))
        start = stop
    return out


def n_params(hidden: int) -> int:
    """Parameters of one model: 4H^2 + 10H + 2."""
    return flat_layout(hidden)[-1][1]


# ----------------------------------------------------------------------------- one block
# Arrays of a block are C-contiguous, the lane axis last; ``v.load(a, i * M)`` is row i's lanes.


@nb.njit(inline="always", **_train_jit)
def _tanh(x):
    """:func:`lstm_kernels._tanh` on every lane."""
    x = v.minimum(v.maximum(x, v.splat(-_CLAMP)), v.splat(_CLAMP))
    x2 = v.mul(x, x)
    p = v.add(v.mul(x2, v.splat(_A13)), v.splat(_A11))
    for c in (_A9, _A7, _A5, _A3, _A1):
        p = v.add(v.mul(x2, p), v.splat(c))
    q = v.add(v.mul(x2, v.splat(_B6)), v.splat(_B4))
    for c in (_B2, _B0):
        q = v.add(v.mul(x2, q), v.splat(c))
    return v.div(v.mul(x, p), q)


@nb.njit(inline="always", **_train_jit)
def _activated(a, j, H):
    """Gate row j's value from its sum: sigmoid(x) = 0.5 + 0.5 tanh(x / 2), tanh for g."""
    s = _ONE if 2 * H <= j < 3 * H else _HALF
    return v.add(v.splat(_ONE - s), v.mul(v.splat(s), _tanh(v.mul(v.splat(s), a))))


@nb.njit(inline="always", **_train_jit)
def _gates(xt, model, h, acts, H):
    """acts[j] = activation of b[j] + w[j] x_t + sum over k of h[k] rt[k, j] (k in order),
    four rows at a time in registers; ``h`` (H, M) the previous outputs."""
    w, rt, b = model[0], model[1], model[2]
    G, M = 4 * H, MODELS
    for j in range(0, G, 4):
        a0 = v.add(v.load(b, j * M), v.mul(v.load(w, j * M), xt))
        a1 = v.add(v.load(b, (j + 1) * M), v.mul(v.load(w, (j + 1) * M), xt))
        a2 = v.add(v.load(b, (j + 2) * M), v.mul(v.load(w, (j + 2) * M), xt))
        a3 = v.add(v.load(b, (j + 3) * M), v.mul(v.load(w, (j + 3) * M), xt))
        for k in range(H):
            hk, r = v.load(h, k * M), (k * G + j) * M
            a0 = v.add(a0, v.mul(hk, v.load(rt, r)))
            a1 = v.add(a1, v.mul(hk, v.load(rt, r + M)))
            a2 = v.add(a2, v.mul(hk, v.load(rt, r + 2 * M)))
            a3 = v.add(a3, v.mul(hk, v.load(rt, r + 3 * M)))
        v.store(acts, j * M, _activated(a0, j, H))
        v.store(acts, (j + 1) * M, _activated(a1, j + 1, H))
        v.store(acts, (j + 2) * M, _activated(a2, j + 2, H))
        v.store(acts, (j + 3) * M, _activated(a3, j + 3, H))


@nb.njit(inline="always", **_train_jit)
def _forward(xb, model, state, H):
    """:func:`lstm_kernels._forward` on every lane: xb (T, M) the lanes' windows; ``state`` =
    (acts (T, G, M), cs (T+1, H, M), tcs (T, H, M), hs (T+1, H, M))."""
    acts, cs, tcs, hs = state
    M = MODELS
    cs[0] = 0
    hs[0] = 0
    for t in range(xb.shape[0]):
        a = acts[t]
        _gates(v.load(xb, t * M), model, hs[t], a, H)
        c0, c1, tc1, h1 = cs[t], cs[t + 1], tcs[t], hs[t + 1]
        for j in range(H):
            ai, af = v.load(a, j * M), v.load(a, (H + j) * M)
            ag, ao = v.load(a, (2 * H + j) * M), v.load(a, (3 * H + j) * M)
            c = v.add(v.mul(af, v.load(c0, j * M)), v.mul(ai, ag))
            tc = _tanh(c)
            v.store(c1, j * M, c)
            v.store(tc1, j * M, tc)
            v.store(h1, j * M, v.mul(ao, tc))


@nb.njit(inline="always", **_train_jit)
def _probabilities(h, model, H, out):
    """Each lane's slip probability (float64) from its last output h (H, M), as
    :func:`lstm_kernels._probability`."""
    wy, by = model[3], model[4]
    for lane in range(MODELS):
        z = by[1, lane] - by[0, lane]
        for k in range(H):
            z += (wy[1, k, lane] - wy[0, k, lane]) * h[k, lane]
        out[lane] = 1.0 / (1.0 + np.exp(-z))


@nb.njit(inline="always", **_train_jit)
def _gates_backward(a, cells, deltas, H):
    """One step back through the gates: da from dh and dc, and dc one step back."""
    c, tcs = cells
    dh, dc, da = deltas
    M, one = MODELS, v.splat(_ONE)
    for j in range(H):
        ig, fg = v.load(a, j * M), v.load(a, (H + j) * M)
        gg, og = v.load(a, (2 * H + j) * M), v.load(a, (3 * H + j) * M)
        tc, dhj = v.load(tcs, j * M), v.load(dh, j * M)
        dcj = v.add(v.load(dc, j * M), v.mul(v.mul(dhj, og), v.sub(one, v.mul(tc, tc))))
        v.store(da, j * M, v.mul(v.mul(v.mul(dcj, gg), ig), v.sub(one, ig)))
        v.store(da, (H + j) * M, v.mul(v.mul(v.mul(dcj, v.load(c, j * M)), fg), v.sub(one, fg)))
        v.store(da, (2 * H + j) * M, v.mul(v.mul(dcj, ig), v.sub(one, v.mul(gg, gg))))
        v.store(da, (3 * H + j) * M, v.mul(v.mul(v.mul(dhj, tc), og), v.sub(one, og)))
        v.store(dc, j * M, v.mul(dcj, fg))


@nb.njit(inline="always", **_train_jit)
def _dh(da, rt, dh, H):
    """dh = R da in :func:`lstm_kernels._dh`'s order: partial sums over the gate rows
    j = q mod 4, each in order of j, then (p0 + p1) + (p2 + p3); two units at a time."""
    G, M = 4 * H, MODELS
    for k in range(0, H - 1, 2):
        r0, r1 = k * G * M, (k + 1) * G * M
        d0, d1, d2, d3 = v.load(da, 0), v.load(da, M), v.load(da, 2 * M), v.load(da, 3 * M)
        p0, p1 = v.mul(v.load(rt, r0), d0), v.mul(v.load(rt, r0 + M), d1)
        p2, p3 = v.mul(v.load(rt, r0 + 2 * M), d2), v.mul(v.load(rt, r0 + 3 * M), d3)
        q0, q1 = v.mul(v.load(rt, r1), d0), v.mul(v.load(rt, r1 + M), d1)
        q2, q3 = v.mul(v.load(rt, r1 + 2 * M), d2), v.mul(v.load(rt, r1 + 3 * M), d3)
        for j in range(P_DH, G, P_DH):
            d0, d1 = v.load(da, j * M), v.load(da, (j + 1) * M)
            d2, d3 = v.load(da, (j + 2) * M), v.load(da, (j + 3) * M)
            o0, o1 = r0 + j * M, r1 + j * M
            p0 = v.add(p0, v.mul(v.load(rt, o0), d0))
            p1 = v.add(p1, v.mul(v.load(rt, o0 + M), d1))
            p2 = v.add(p2, v.mul(v.load(rt, o0 + 2 * M), d2))
            p3 = v.add(p3, v.mul(v.load(rt, o0 + 3 * M), d3))
            q0 = v.add(q0, v.mul(v.load(rt, o1), d0))
            q1 = v.add(q1, v.mul(v.load(rt, o1 + M), d1))
            q2 = v.add(q2, v.mul(v.load(rt, o1 + 2 * M), d2))
            q3 = v.add(q3, v.mul(v.load(rt, o1 + 3 * M), d3))
        v.store(dh, k * M, v.add(v.add(p0, p1), v.add(p2, p3)))
        v.store(dh, (k + 1) * M, v.add(v.add(q0, q1), v.add(q2, q3)))
    if H % 2:
        _dh_unit(da, rt, dh, H - 1, H)


@nb.njit(inline="always", **_train_jit)
def _dh_unit(da, rt, dh, k, H):
    """:func:`_dh` of unit k alone."""
    G, M = 4 * H, MODELS
    r = k * G * M
    p0, p1 = v.mul(v.load(rt, r), v.load(da, 0)), v.mul(v.load(rt, r + M), v.load(da, M))
    p2 = v.mul(v.load(rt, r + 2 * M), v.load(da, 2 * M))
    p3 = v.mul(v.load(rt, r + 3 * M), v.load(da, 3 * M))
    for j in range(P_DH, G, P_DH):
        p0 = v.add(p0, v.mul(v.load(rt, r + j * M), v.load(da, j * M)))
        p1 = v.add(p1, v.mul(v.load(rt, r + (j + 1) * M), v.load(da, (j + 1) * M)))
        p2 = v.add(p2, v.mul(v.load(rt, r + (j + 2) * M), v.load(da, (j + 2) * M)))
        p3 = v.add(p3, v.mul(v.load(rt, r + (j + 3) * M), v.load(da, (j + 3) * M)))
    v.store(dh, k * M, v.add(v.add(p0, p1), v.add(p2, p3)))


@nb.njit(inline="always", **_train_jit)
def _grt(hs, das, grt, H):
    """grt[k, j] += h_t[k] da_t[j] for t from the window's end to its start, as the single
    kernel adds them step by step; two units by four gate rows in registers."""
    T, G, M = das.shape[0], 4 * H, MODELS
    for k in range(0, H - 1, 2):
        for j in range(0, G, 4):
            o0, o1 = (k * G + j) * M, ((k + 1) * G + j) * M
            a0, a1 = v.load(grt, o0), v.load(grt, o0 + M)
            a2, a3 = v.load(grt, o0 + 2 * M), v.load(grt, o0 + 3 * M)
            b0, b1 = v.load(grt, o1), v.load(grt, o1 + M)
            b2, b3 = v.load(grt, o1 + 2 * M), v.load(grt, o1 + 3 * M)
            for t in range(T - 1, -1, -1):
                h0, h1 = v.load(hs, (t * H + k) * M), v.load(hs, (t * H + k + 1) * M)
                d = (t * G + j) * M
                d0, d1 = v.load(das, d), v.load(das, d + M)
                d2, d3 = v.load(das, d + 2 * M), v.load(das, d + 3 * M)
                a0, a1 = v.add(a0, v.mul(h0, d0)), v.add(a1, v.mul(h0, d1))
                a2, a3 = v.add(a2, v.mul(h0, d2)), v.add(a3, v.mul(h0, d3))
                b0, b1 = v.add(b0, v.mul(h1, d0)), v.add(b1, v.mul(h1, d1))
                b2, b3 = v.add(b2, v.mul(h1, d2)), v.add(b3, v.mul(h1, d3))
            v.store(grt, o0, a0)
            v.store(grt, o0 + M, a1)
            v.store(grt, o0 + 2 * M, a2)
            v.store(grt, o0 + 3 * M, a3)
            v.store(grt, o1, b0)
            v.store(grt, o1 + M, b1)
            v.store(grt, o1 + 2 * M, b2)
            v.store(grt, o1 + 3 * M, b3)
    if H % 2:
        k = H - 1
        for j in range(G):
            o = (k * G + j) * M
            acc = v.load(grt, o)
            for t in range(T - 1, -1, -1):
                acc = v.add(acc, v.mul(v.load(hs, (t * H + k) * M), v.load(das, (t * G + j) * M)))
            v.store(grt, o, acc)


@nb.njit(inline="always", **_train_jit)
def _backward(xb, dz, model, state, work):
    """:func:`lstm_kernels._backward` on every lane; ``dz`` (M,) float32, 0 in a lane without
    a window; ``work`` = (grads (gw, grt, gb, gwy, gby) in lanes, scratch (dh, dc, das), H),
    ``das`` (T, G, M) the gate deltas of every step."""
    wy, rt = model[3], model[1]
    acts, cs, tcs, hs = state
    (gw, grt, gb, gwy, gby), (dh, dc, das), H = work
    T, G, M = xb.shape[0], 4 * H, MODELS
    z = v.load(dz, 0)
    v.store(gby, 0, v.sub(v.load(gby, 0), z))
    v.store(gby, M, v.add(v.load(gby, M), z))
    for k in range(H):
        hk = v.load(hs[T], k * M)
        v.store(gwy, k * M, v.sub(v.load(gwy, k * M), v.mul(z, hk)))
        v.store(gwy, (H + k) * M, v.add(v.load(gwy, (H + k) * M), v.mul(z, hk)))
        v.store(dh, k * M, v.mul(z, v.sub(v.load(wy, (H + k) * M), v.load(wy, k * M))))
        v.store(dc, k * M, v.splat(0.0))
    for t in range(T - 1, -1, -1):
        da = das[t]
        _gates_backward(acts[t], (cs[t], tcs[t]), (dh, dc, da), H)
        xt = v.load(xb, t * M)
        for j in range(G):
            daj = v.load(da, j * M)
            v.store(gw, j * M, v.add(v.load(gw, j * M), v.mul(daj, xt)))
            v.store(gb, j * M, v.add(v.load(gb, j * M), daj))
        _dh(da, rt, dh, H)
    _grt(hs, das, grt, H)


@nb.njit(inline="always", **_train_jit)
def _flush(cur, total, ends, first):
    """Where a lane's chunk ends (``ends`` > 0): total = cur (its first chunk, ``first`` > 0)
    or total + cur, as the single kernel sums its chunks; then cur = 0 there."""
    e, f, zero = v.load(ends, 0), v.load(first, 0), v.splat(0.0)
    for i in range(0, cur.size, MODELS):
        c, t = v.load(cur, i), v.load(total, i)
        v.store(total, i, v.where(e, v.where(f, c, v.add(t, c)), t))
        v.store(cur, i, v.where(e, zero, c))


@nb.njit(inline="always", **_train_jit)
def _update(P, V, grads, lr, moving):
    """v = m v - lr g; p += v in the lanes that ``moving`` marks (> 0), each with its own
    ``lr`` (M,); ``grads`` = (g (n_params, M), m)."""
    g, m = grads
    go, rate, mv = v.load(moving, 0), v.load(lr, 0), v.splat(m)
    for i in range(0, P.size, MODELS):
        vi = v.load(V, i)
        step = v.sub(v.mul(mv, vi), v.mul(rate, v.load(g, i)))
        v.store(V, i, v.where(go, step, vi))
        pi = v.load(P, i)
        v.store(P, i, v.where(go, v.add(pi, step), pi))


@nb.njit(inline="always", **_train_jit)
def _views(P, H):
    """(w (G, M), rt (H, G, M), b (G, M), wy (2, H, M), by (2, M)) of a block's flat P."""
    G, M = 4 * H, P.shape[1]
    o1, o2 = G, G + H * G
    o3, o4 = o2 + G, o2 + G + 2 * H
    return (
        P[:o1],
        P[o1:o2].reshape(H, G, M),
        P[o2:o3],
        P[o3:o4].reshape(2, H, M),
        P[o4 : o4 + 2],
    )


@nb.njit(inline="always", **_train_jit)
def _lanes_of_step(step, plan, lanes):
    """Each lane's batch in this step (sizes), its chunks (n_chunks), whether it moves."""
    counts, batch_size = plan[1], plan[3]
    sizes, n_chunks, moving = lanes
    for lane in range(MODELS):
        sizes[lane] = max(0, min(batch_size, counts[lane] - step * batch_size))
        n_chunks[lane] = max(1, min(N_CHUNKS, sizes[lane]))
        moving[lane] = 1.0 if sizes[lane] > 0 else 0.0


@nb.njit(inline="always", **_train_jit)
def _chunk_ends(i, sizes, n_chunks, ends, first):
    """Whether window i of its batch ends a chunk of each lane (``ends``, 1.0) and whether that
    chunk is the lane's first (``first``); chunk c holds windows [c B / nc, (c + 1) B / nc)."""
    for lane in range(MODELS):
        B, nc = sizes[lane], n_chunks[lane]
        ends[lane], first[lane] = 0.0, 0.0
        for c in range(nc if i < B else 0):
            if (c + 1) * B // nc == i + 1:
                ends[lane], first[lane] = 1.0, 1.0 if c == 0 else 0.0


@nb.njit(inline="always", **_train_jit)
def _gather(x, rows, out):
    """Each lane's window, row ``rows[lane]`` of x (zeros where -1), into out (T, M)."""
    for lane in range(MODELS):
        r = rows[lane]
        for t in range(x.shape[1]):
            out[t, lane] = x[r, t] if r >= 0 else 0.0


def _block_epoch(data, plan, P, V, H):
    """One epoch of a block's models (P, V (n_params, M) updated in place); ``plan`` as
    :func:`lockstep_epoch`'s, its rows those of this block."""
    x, y = data
    orders, counts, lr, batch_size, momentum = plan
    T, G, M = x.shape[1], 4 * H, MODELS
    xb = np.zeros((T, M), F32)
    state = (
        np.empty((T, G, M), F32),
        np.empty((T + 1, H, M), F32),
        np.empty((T, H, M), F32),
        np.empty((T + 1, H, M), F32),
    )
    cur, total = np.zeros(P.shape, F32), np.zeros(P.shape, F32)
    scratch = (np.empty((H, M), F32), np.empty((H, M), F32), np.empty((T, G, M), F32))
    model, grads = _views(P, H), _views(cur, H)
    p, dz, rows = np.empty(M), np.zeros(M, F32), np.empty(M, np.int64)
    lanes = (np.zeros(M, np.int64), np.ones(M, np.int64), np.zeros(M, F32))
    ends, first = np.zeros(M, F32), np.zeros(M, F32)
    rates = lr.astype(F32)
    longest = counts.max()
    for step in range((longest + batch_size - 1) // batch_size):
        _lanes_of_step(step, plan, lanes)
        sizes = lanes[0]
        cur[:] = 0
        for i in range(min(batch_size, longest - step * batch_size)):
            for lane in range(M):
                rows[lane] = orders[lane, step * batch_size + i] if i < sizes[lane] else -1
            _gather(x, rows, xb)
            if H == 20:  # the paper's size as a literal: every loop bound a constant
                _forward(xb, model, state, 20)
                _probabilities(state[3][T], model, 20, p)
            else:
                _forward(xb, model, state, H)
                _probabilities(state[3][T], model, H, p)
            for lane in range(M):
                r = rows[lane]
                dz[lane] = F32((p[lane] - y[r]) * F32(1.0 / sizes[lane])) if r >= 0 else 0.0
            if H == 20:
                _backward(xb, dz, model, state, (grads, scratch, 20))
            else:
                _backward(xb, dz, model, state, (grads, scratch, H))
            if batch_size > 1:
                _chunk_ends(i, sizes, lanes[1], ends, first)
                _flush(cur, total, ends, first)
        _update(P, V, (cur if batch_size == 1 else total, F32(momentum)), rates, lanes[2])


_block_epoch_jit = nb.njit(inline="always", **_train_jit)(_block_epoch)


def _lockstep_epoch(data, plan, params, velocity, hidden):
    """Every block's epoch; blocks run in parallel in the parallel kernel."""
    orders, counts, lr, batch_size, momentum = plan
    M = MODELS
    for blk in nb.prange(params.shape[0]):
        lo, hi = blk * M, (blk + 1) * M
        block_plan = (orders[lo:hi], counts[lo:hi], lr[lo:hi], batch_size, momentum)
        _block_epoch_jit(data, block_plan, params[blk], velocity[blk], hidden)


lockstep_epoch_parallel, lockstep_epoch_serial = _twice(_lockstep_epoch, _train_jit)


def lockstep_epoch(data, plan, params, velocity) -> None:
    """One epoch of every model in ``params``.

    Parameters
    ----------
    data : (x (N, T) float32, the normalized windows of every model; y (N,) int8 labels).
    plan : (orders (n_blocks * MODELS, steps * batch_size) int64, each lane's windows in the
        order it sees them (rows of x); counts (n_blocks * MODELS,) int64, how many (0: the
        lane sits this epoch out); lr (n_blocks * MODELS,) float32; batch_size; momentum).
    params, velocity : (n_blocks, n_params, MODELS) float32, updated in place.
    """
    hidden = _hidden(params.shape[1])
    kernel = lockstep_epoch_parallel if params.shape[0] > 1 else lockstep_epoch_serial
    kernel(data, plan, params, velocity, hidden)


def _hidden(n: int) -> int:
    """H from n_params = 4H^2 + 10H + 2."""
    h = int(round((-10 + np.sqrt(100 - 16 * (2 - n))) / 8))
    if n_params(h) != n:
        raise ValueError(f"{n} is not the parameter count of an LSTM")
    return h


def pack(models: list[list[np.ndarray]]) -> np.ndarray:
    """Models' (w, rt, b, wy, by) into lanes: (n_blocks, n_params, MODELS), empty lanes 0."""
    flat = [np.concatenate([np.ravel(a) for a in m]).astype(np.float32) for m in models]
    n_blocks = -(-len(flat) // MODELS)
    out = np.zeros((n_blocks * MODELS, len(flat[0])), np.float32)
    out[: len(flat)] = flat
    return np.ascontiguousarray(out.reshape(n_blocks, MODELS, -1).transpose(0, 2, 1))


def unpack(lanes: np.ndarray, i: int, hidden: int) -> list[np.ndarray]:
    """Model i's (w, rt, b, wy, by) out of its lane, as contiguous copies."""
    flat = lanes[i // MODELS, :, i % MODELS]
    return [flat[a:b].reshape(shape).copy() for a, b, shape in flat_layout(hidden)]


def put(lanes: np.ndarray, i: int, model: list[np.ndarray]) -> None:
    """Write model i's (w, rt, b, wy, by) into its lane."""
    lanes[i // MODELS, :, i % MODELS] = np.concatenate([np.ravel(a) for a in model])
