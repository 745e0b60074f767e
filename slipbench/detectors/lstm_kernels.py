"""A small LSTM classifier (one layer, input size 1, many-to-one, two outputs) in numba.

Why hand-written: the paper's network (20 units, 1 input) is far too small for BLAS or torch's
kernels to pay off. On the 2-core AMD EPYC development machine, stock ``torch.nn.LSTM`` trained
at 0.8-1.2 M samples/s (batch 32-128, window 50), inferred at 2.2 M samples/s and took 215 µs for
one 50-sample window: most of that time is per-operator dispatch, not arithmetic. These kernels
fuse one whole sequence (forward and full back-propagation through time) into one loop nest that
LLVM vectorizes over the 4*H gate rows; samples of a batch are split into a fixed number of chunks
that run in parallel, so results do not depend on the number of threads. ``slipbench bench``
measures them against stock torch in the same run.

Batched inference vectorizes across windows instead (:func:`_run_block`): LANES windows at a
time, state laid out (row, window) with the window innermost, so every loop of a time step runs
on whole AVX2 registers. Window by window a step cost about 250 ns per core (4.3 M samples/s on
one core, the same on two: see below); in blocks of 32 it costs about 125 ns (8 M samples/s per
core, 14-15 M samples/s on both cores of an idle machine, against 0.7 M for stock torch). Of that,
the recurrent product (1600 multiply-adds a step) is about half and the 100 tanh a step the rest.

Until this change the ``parallel`` kernels often ran serially: numba's cache keyed the parallel
and the serial compilation of one function under one entry (see :func:`_twice`).

There is no SVML on that machine, so ``exp``/``tanh`` from libm would not vectorize; ``_tanh``
is Eigen's rational float32 approximation (clamped to +-7.9, a few ulp from the exact value),
and the sigmoid is ``0.5 + 0.5 * tanh(x / 2)``. Training and inference use the same functions.

Parameter layout (torch's gate order i, f, g, o; one bias per gate as in the paper):
``w`` (4H,) input weights, ``rt`` (H, 4H) recurrent weights transposed, ``b`` (4H,),
``wy`` (2, H) and ``by`` (2,) the output layer.
"""

from __future__ import annotations

import types
from typing import Literal, TypedDict

import numba as nb
import numpy as np

F32 = np.float32
# Eigen's generic_fast_tanh_float coefficients (Eigen/src/Core/MathFunctionsImpl.h)
_CLAMP = F32(7.90531110763549805)
_A1, _A3, _A5, _A7 = (
    F32(4.89352455891786e-03),
    F32(6.37261928875436e-04),
    F32(1.48572235717979e-05),
    F32(5.12229709037114e-08),
)
_A9, _A11, _A13 = F32(-8.60467152213735e-11), F32(2.00018790482477e-13), F32(-2.76076847742355e-16)
_B0, _B2, _B4, _B6 = (
    F32(4.89352518554385e-03),
    F32(2.26843463243900e-03),
    F32(1.18534705686654e-04),
    F32(1.19825839466702e-06),
)
_HALF, _ONE = F32(0.5), F32(1.0)
N_CHUNKS = 8  # a batch is split into this many parallel chunks, whatever the thread count
LANES = 32  # windows per block in batched inference: 4 AVX2 registers of float32 per gate row
MIN_BLOCK = 16  # fewer windows than this are scored one by one (a padded block costs more)


class _JitOptions(TypedDict):  # typed, so that numba's overloads accept **_jit
    fastmath: bool | set[str]
    cache: bool
    nogil: bool
    error_model: Literal["python", "numpy"]


# error_model="numpy": no ZeroDivisionError checks, which would stop the loops vectorizing
_jit = _JitOptions(fastmath=True, cache=True, nogil=True, error_model="numpy")


def _twice(f, options=_jit):
    """``f`` compiled in parallel and serially (with numba ``options``). Each gets its own copy of the Python function:
    numba's on-disk cache names entries by the function's qualified name and keys them by
    signature only, not by the ``parallel`` flag, so two dispatchers of one function share an
    entry and whichever compiled first served both (the "parallel" kernels ran serially, or
    the serial ones launched threads for every update, depending on the order of first use)."""
    out = []
    for suffix, parallel in (("_parallel", True), ("_serial", False)):
        g = types.FunctionType(
            f.__code__, f.__globals__, f.__name__ + suffix, f.__defaults__, f.__closure__
        )
        g.__qualname__, g.__doc__ = f.__qualname__ + suffix, f.__doc__
        out.append(nb.njit(parallel=parallel, **options)(g))
    return out


@nb.njit(inline="always", **_jit)
def _tanh(x):
    x = min(max(x, -_CLAMP), _CLAMP)
    x2 = x * x
    p = x2 * _A13 + _A11
    p = x2 * p + _A9
    p = x2 * p + _A7
    p = x2 * p + _A5
    p = x2 * p + _A3
    p = x2 * p + _A1
    q = x2 * _B6 + _B4
    q = x2 * q + _B2
    q = x2 * q + _B0
    return x * p / q


@nb.njit(inline="always", **_jit)
def _activate(a, H):
    """Gate pre-activations (4H,) -> values in place: sigmoid(x) = 0.5 + 0.5 tanh(x / 2) for
    i, f, o and tanh for g, written as one branch-free loop so that it vectorizes."""
    for j in range(4 * H):
        s = _ONE if 2 * H <= j < 3 * H else _HALF
        a[j] = (_ONE - s) + s * _tanh(s * a[j])


@nb.njit(**_jit)
def tanh(x):
    """The approximation itself, for tests."""
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = _tanh(x[i])
    return out


# Training runs every float operation as written: no reordering ("reassoc"), no fused
# multiply-adds ("contract"), no reciprocals for divisions ("arcp"). LLVM applies those where
# the code around an operation lets it, so they would round a model's arithmetic differently in
# lstm_lockstep.py (models in the SIMD lanes) than here; without them a model trained in
# lockstep gets the weights it gets alone, bit for bit. Training is chaotic: rounding alone
# moves a model's accuracy by points. The one reduction, dh = R da, is spelled out as P_DH
# partial sums over the gate rows, vectorized over the units. This costs speed: an epoch at
# batch 1 ran at 0.93 M samples/s against 1.29 M with the flags on (CPU time, best of 7 in one
# run, window 50, the 2-core development machine).
_TRAIN_MATH = {"nnan", "ninf", "nsz"}
_train_jit = _JitOptions(**{**_jit, "fastmath": _TRAIN_MATH})
P_DH = 4  # partial sums of dh, over the gate rows j = q mod P_DH (4H rows: no remainder)


@nb.njit(inline="always", **_train_jit)
def padded(H):
    """H rounded up to whole AVX2 vectors of float32 (8)."""
    return (H + 7) // 8 * 8


@nb.njit(inline="always", **_train_jit)
def _forward(x, model, state):
    """One sequence x (T,) through ``model`` = (w, rt, b, wy, by); fills ``state`` = (acts
    (T, 4H) gate values, cs (T+1, H) cells (cs[0] = 0), tcs (T, H) tanh of cells, hs (T+1, H)
    outputs (hs[0] = 0)): the state resets per window."""
    w, rt, b = model[0], model[1], model[2]
    acts, cs, tcs, hs = state
    H = rt.shape[0]
    G = 4 * H
    for j in range(H):
        cs[0, j] = 0
        hs[0, j] = 0
    for t in range(x.shape[0]):
        a = acts[t]
        xt = x[t]
        for j in range(G):
            a[j] = b[j] + w[j] * xt
        for k in range(H):
            hk = hs[t, k]
            for j in range(G):
                a[j] += hk * rt[k, j]
        _activate(a, H)
        for j in range(H):
            c = a[H + j] * cs[t, j] + a[j] * a[2 * H + j]
            tc = _tanh(c)
            cs[t + 1, j] = c
            tcs[t, j] = tc
            hs[t + 1, j] = a[3 * H + j] * tc


@nb.njit(inline="always", **_jit)
def _logit_diff(h, wy, by):
    """Slip logit minus non-slip logit: the softmax of two outputs is the sigmoid of this."""
    z = by[1] - by[0]
    for k in range(h.shape[0]):
        z += (wy[1, k] - wy[0, k]) * h[k]
    return z


@nb.njit(inline="always", **_train_jit)
def _dh(da, rp, part, dh, HP):
    """dh = R da as P_DH partial sums over the gate rows j = q mod 4, each in order of j and
    vectorized over the units k, then (p0 + p1) + (p2 + p3). ``rp`` (4H, HP) is R (the
    recurrent matrix untransposed) padded with zero columns to HP, a multiple of 8, so that
    every row is whole vectors; ``part`` (4, HP) scratch."""
    G = rp.shape[0]
    p0, p1, p2, p3 = part[0], part[1], part[2], part[3]
    da4, rp4 = da.reshape(G // P_DH, P_DH), rp.reshape(G // P_DH, P_DH, HP)  # constant q:
    for jb in range(G // P_DH):  # no index checks
        d, r = da4[jb], rp4[jb]
        d0, d1, d2, d3 = d[0], d[1], d[2], d[3]
        r0, r1, r2, r3 = r[0], r[1], r[2], r[3]
        if jb == 0:
            for k in range(HP):
                p0[k] = r0[k] * d0
                p1[k] = r1[k] * d1
                p2[k] = r2[k] * d2
                p3[k] = r3[k] * d3
        else:
            for k in range(HP):
                p0[k] += r0[k] * d0
                p1[k] += r1[k] * d1
                p2[k] += r2[k] * d2
                p3[k] += r3[k] * d3
    for k in range(dh.shape[0]):
        dh[k] = (p0[k] + p1[k]) + (p2[k] + p3[k])


@nb.njit(inline="always", **_train_jit)
def _backward(xs, dz, model, state, work):
    """Back-propagation through one window after :func:`_forward`, ``dz`` the loss's
    derivative by the logit difference. ``work`` = (grads, scratch, rp): the window's
    gradients are added to ``grads`` = (gw, grt, gb, gwy, gby); ``scratch`` = (dh, dc, da,
    part); ``rp`` is R padded (:func:`_dh`)."""
    wy = model[3]
    acts, cs, tcs, hs = state
    (gw, grt, gb, gwy, gby), (dh, dc, da, part), rp, HP = work
    T, H = tcs.shape
    G = 4 * H
    gby[0] -= dz
    gby[1] += dz
    for k in range(H):
        gwy[0, k] -= dz * hs[T, k]
        gwy[1, k] += dz * hs[T, k]
        dh[k] = dz * (wy[1, k] - wy[0, k])
        dc[k] = 0
    for t in range(T - 1, -1, -1):
        a = acts[t]
        for j in range(H):
            ig, fg, gg, og = a[j], a[H + j], a[2 * H + j], a[3 * H + j]
            tc = tcs[t, j]
            dcj = dc[j] + dh[j] * og * (_ONE - tc * tc)
            da[j] = dcj * gg * ig * (_ONE - ig)
            da[H + j] = dcj * cs[t, j] * fg * (_ONE - fg)
            da[2 * H + j] = dcj * ig * (_ONE - gg * gg)
            da[3 * H + j] = dh[j] * tc * og * (_ONE - og)
            dc[j] = dcj * fg
        xt = xs[t]
        for j in range(G):
            gw[j] += da[j] * xt
            gb[j] += da[j]
        for k in range(H):
            hk = hs[t, k]
            for j in range(G):
                grt[k, j] += hk * da[j]
        _dh(da, rp, part, dh, HP)


@nb.njit(inline="always", **_train_jit)
def _sgd(p, v, g, m, lr):
    for i in range(p.shape[0]):
        v[i] = m * v[i] - lr * g[i]
        p[i] += v[i]


def _train_epoch(data, order, schedule, model, velocity):
    """One epoch of mini-batch SGD with momentum (v = m v - lr g; p += v) on the mean
    cross-entropy over the windows ``x[order]``, ``data`` = (x, y), ``schedule`` =
    (batch_size, lr, momentum); ``model`` = (w, rt, b, wy, by) and ``velocity`` (the same
    shapes) are updated in place. Returns the mean loss.

    A batch is split into up to N_CHUNKS chunks (run in parallel in the parallel kernel),
    whose gradients are summed in a fixed order: chunk 0, plus chunk 1, plus chunk 2, ...
    """
    x, y = data
    batch_size, lr, momentum = schedule
    rt = model[1]
    n, T = order.shape[0], x.shape[1]
    H = rt.shape[0]
    G, HP = 4 * H, padded(H)
    # buffers for every chunk, allocated once per epoch: with small batches, allocation and
    # temporaries per update cost as much as the arithmetic
    gw, gb = np.zeros((N_CHUNKS, G), F32), np.zeros((N_CHUNKS, G), F32)
    grt = np.zeros((N_CHUNKS, H, G), F32)
    gwy, gby = np.zeros((N_CHUNKS, 2, H), F32), np.zeros((N_CHUNKS, 2), F32)
    acts_, tcs_ = np.empty((N_CHUNKS, T, G), F32), np.empty((N_CHUNKS, T, H), F32)
    cs_, hs_ = np.empty((N_CHUNKS, T + 1, H), F32), np.empty((N_CHUNKS, T + 1, H), F32)
    dh_, dc_ = np.empty((N_CHUNKS, H), F32), np.empty((N_CHUNKS, H), F32)
    da_, part_ = np.empty((N_CHUNKS, G), F32), np.empty((N_CHUNKS, P_DH, HP), F32)
    rp = np.zeros((G, HP), F32)
    rp[:, :H] = rt.T
    losses = np.zeros(N_CHUNKS)
    for start in range(0, n, batch_size):
        B = min(batch_size, n - start)
        nc = min(N_CHUNKS, B)
        gw[:nc] = 0
        grt[:nc] = 0
        gb[:nc] = 0
        gwy[:nc] = 0
        gby[:nc] = 0
        inv_b = F32(1.0 / B)
        for c in nb.prange(nc):
            state = (acts_[c], cs_[c], tcs_[c], hs_[c])
            grads = (gw[c], grt[c], gb[c], gwy[c], gby[c])
            scratch = (dh_[c], dc_[c], da_[c], part_[c])
            for s in range(start + c * B // nc, start + (c + 1) * B // nc):
                i = order[s]
                _forward(x[i], model, state)
                p = _probability(state[3][T], model)
                losses[c] += -np.log(max(p if y[i] == 1 else 1.0 - p, 1e-30))
                dz = F32((p - y[i]) * inv_b)  # d loss / d logit1 = -d loss / d logit0
                if H == 20:  # the paper's size: HP a literal, the dh loop whole vectors
                    _backward(x[i], dz, model, state, (grads, scratch, rp, 24))
                else:
                    _backward(x[i], dz, model, state, (grads, scratch, rp, HP))
        # reduce the chunks in a fixed order, so the result is the same on any thread count
        for c in range(1, nc):
            gw[0] += gw[c]
            grt[0] += grt[c]
            gb[0] += gb[c]
            gwy[0] += gwy[c]
            gby[0] += gby[c]
        _update(model, velocity, (gw[0], grt[0], gb[0], gwy[0], gby[0]), F32(momentum), F32(lr))
        rp[:, :H] = rt.T
    return losses.sum() / n


@nb.njit(inline="always", **_train_jit)
def _probability(h, model):
    """The slip probability from the last output h (H,), in float64: one per window."""
    return 1.0 / (1.0 + np.exp(-_logit_diff(h, model[3], model[4])))


@nb.njit(inline="always", **_train_jit)
def _update(model, velocity, grads, m, lr):
    """SGD with momentum on every parameter array of ``model`` by ``grads``."""
    w, rt, b, wy, by = model
    vw, vrt, vb, vwy, vby = velocity
    gw, grt, gb, gwy, gby = grads
    _sgd(w, vw, gw, m, lr)
    _sgd(rt.ravel(), vrt.ravel(), grt.ravel(), m, lr)
    _sgd(b, vb, gb, m, lr)
    _sgd(wy.ravel(), vwy.ravel(), gwy.ravel(), m, lr)
    _sgd(by, vby, gby, m, lr)


# The same epoch compiled twice: in parallel over a batch's chunks, and serially for small
# batches, where a parallel launch per update costs more than it saves (and stalls badly when
# other processes hold the cores). Each is deterministic and independent of the thread count,
# and the two agree bit for bit (every operation in the order written); which one runs depends
# only on the batch size.
train_epoch_parallel, train_epoch_serial = _twice(_train_epoch, _train_jit)
PARALLEL_BATCH = 256  # from this batch size on, an epoch's chunks run in parallel


def train_epoch(data, order, schedule, model, velocity) -> float:
    """One epoch (:func:`_train_epoch`); batches under PARALLEL_BATCH windows run serially."""
    kernel = train_epoch_parallel if schedule[0] >= PARALLEL_BATCH else train_epoch_serial
    return kernel(data, order, schedule, tuple(model), tuple(velocity))


@nb.njit(inline="always", **_jit)
def _step(xt, model, state, H):
    """One step on the normalized input ``xt`` through ``model`` = (w, rt, b, wy, by):
    ``state`` = (h, c, a), h and c (H,) advanced in place, ``a`` (4H,) scratch. The recurrent product keeps one accumulator per gate row (row outer, k
    inner): with H a literal, LLVM unrolls k and vectorizes across rows, and a window of 50
    samples took 5.3 µs against 8.1 µs with k outer (CPU time, development machine)."""
    w, rt, b = model[0], model[1], model[2]
    h, c, a = state
    for j in range(4 * H):
        acc = b[j] + w[j] * xt
        for k in range(H):
            acc += h[k] * rt[k, j]
        a[j] = acc
    _activate(a, H)
    for j in range(H):
        cj = a[H + j] * c[j] + a[j] * a[2 * H + j]
        c[j] = cj
        h[j] = a[3 * H + j] * _tanh(cj)


@nb.njit(inline="always", **_jit)
def _run(x, net, state, H):
    """Forward through one window, keeping only ``state`` (h, c, a: no storage for backward);
    ``net`` = ((lo, scale), model): inputs are normalized on the fly as (x - lo) * scale - 1.
    Returns the slip probability. Callers pass H as the literal 20 for the paper's size (see
    :func:`_step`)."""
    (lo, scale), model = net
    h, c = state[0], state[1]
    h[:] = 0
    c[:] = 0
    for t in range(x.shape[0]):
        _step(F32((x[t] - lo) * scale - 1.0), model, state, H)
    return 1.0 / (1.0 + np.exp(-_logit_diff(h, model[3], model[4])))


def _predict_proba_each(x, net):
    """Probability of slip per raw window of x (n, T), float64, window by window (the
    single-window path); chunks run in parallel. ``net`` = ((lo, scale), (w, rt, b, wy, by))."""
    n = x.shape[0]
    # a parallel loop takes arrays and scalars, not tuples: the net is rebuilt inside it
    (lo, scale), (w, rt, b, wy, by) = net
    H = rt.shape[0]
    out = np.empty(n)
    nc = min(n, 64)
    for c in nb.prange(nc):
        state = (np.empty(H, F32), np.empty(H, F32), np.empty(4 * H, F32))
        inner = ((lo, scale), (w, rt, b, wy, by))
        for s in range(c * n // nc, (c + 1) * n // nc):
            if H == 20:  # the paper's size, as a literal (see _step)
                out[s] = _run(x[s], inner, state, 20)
            else:
                out[s] = _run(x[s], inner, state, H)
    return out


predict_proba_each_parallel, predict_proba_each_serial = _twice(_predict_proba_each)


@nb.njit(inline="always", **_jit)
def _run_block(x, block, net, H):
    """Forward through the m <= LANES windows x[s0 : s0 + m] at once, window s0 + l in lane l
    (lanes past m run on zeros and are dropped); writes their slip probabilities to out.
    ``block`` = (s0, m, st, out); ``net`` = ((lo, scale), (w, rt, b, wy, by)).

    The same arithmetic as :func:`_run`, laid out (row, lane) with the lane innermost so that
    LLVM vectorizes every loop across windows: ``st`` (T + 6H, LANES) holds the normalized
    inputs (T rows), h and c (H rows each) and the gates (4H rows). The recurrent product keeps
    each gate row's accumulator in registers across k when H is a compile-time constant (the
    caller passes the literal 20, the paper's size, so that LLVM unrolls the k loop first)."""
    s0, m, st, out = block
    (lo, scale), (w, rt, b, wy, by) = net
    G = 4 * H
    T = x.shape[1]
    xb, h, c, a = st[:T], st[T : T + H], st[T + H : T + 2 * H], st[T + 2 * H : T + 6 * H]
    xb[:] = 0
    h[:] = 0
    c[:] = 0
    for l in range(m):
        xs = x[s0 + l]
        for t in range(T):
            xb[t, l] = F32((xs[t] - lo) * scale - 1.0)
    for t in range(T):
        xt = xb[t]
        for j in range(G):
            aj = a[j]
            bj, wj = b[j], w[j]
            for l in range(LANES):
                acc = bj + wj * xt[l]
                for k in range(H):
                    acc += h[k, l] * rt[k, j]
                aj[l] = acc
        for j in range(G):
            aj = a[j]
            s = _ONE if 2 * H <= j < 3 * H else _HALF
            o = _ONE - s
            for l in range(LANES):
                aj[l] = o + s * _tanh(s * aj[l])
        for j in range(H):
            ai, af, ag, ao = a[j], a[H + j], a[2 * H + j], a[3 * H + j]
            cj, hj = c[j], h[j]
            for l in range(LANES):
                cl = af[l] * cj[l] + ai[l] * ag[l]
                cj[l] = cl
                hj[l] = ao[l] * _tanh(cl)
    for l in range(m):
        z = by[1] - by[0]
        for k in range(H):
            z += (wy[1, k] - wy[0, k]) * h[k, l]
        out[s0 + l] = 1.0 / (1.0 + np.exp(-z))


def _predict_proba_blocks(x, net):
    """Probability of slip per raw window of x (n, T), float64, LANES windows at a time;
    blocks run in parallel. Each window's result depends only on that window."""
    n, T = x.shape
    (lo, scale), (w, rt, b, wy, by) = net  # rebuilt inside the parallel loop: see above
    H = rt.shape[0]
    out = np.empty(n)
    for i in nb.prange((n + LANES - 1) // LANES):
        st = np.empty((T + 6 * H, LANES), F32)
        s0 = i * LANES
        m = min(LANES, n - s0)
        inner = ((lo, scale), (w, rt, b, wy, by))
        if H == 20:  # the paper's size, as a literal: see _run_block
            _run_block(x, (s0, m, st, out), inner, 20)
        else:
            _run_block(x, (s0, m, st, out), inner, H)
    return out


predict_proba_blocks_parallel, predict_proba_blocks_serial = _twice(_predict_proba_blocks)


def predict_proba(x, net) -> np.ndarray:
    """Slip probability per raw window of x (n, T), float64, of ``net`` = ((lo, scale), (w, rt,
    b, wy, by)) (:func:`network`). From MIN_BLOCK windows on, blocks
    of LANES windows (:func:`_predict_proba_blocks`); fewer go window by window, as
    :func:`predict_window` does. Under 256 windows a parallel launch costs more than it saves."""
    n = x.shape[0]
    if n < MIN_BLOCK:
        return predict_proba_each_serial(x, net)
    kernel = predict_proba_blocks_parallel if n >= 256 else predict_proba_blocks_serial
    return kernel(x, net)


@nb.njit(**_jit)
def predict_window(window, net):
    """Probability of slip for one raw window, single-threaded. Measured 5.3 µs of CPU time for
    50 samples (H = 20) on the development machine."""
    H = net[1][1].shape[0]
    state = (np.empty(H, F32), np.empty(H, F32), np.empty(4 * H, F32))
    if H == 20:  # the paper's size, as a literal (see _step)
        return _run(window, net, state, 20)
    return _run(window, net, state, H)


def network(lo, scale, params) -> tuple:
    """The ``net`` the inference kernels take: ((lo, scale), (w, rt, b, wy, by)), the
    normalization as floats and the five weight arrays as one tuple (numba passes both as
    values: the kernels' speed is that of separate arguments)."""
    return (float(lo), float(scale)), tuple(params)


def init_params(hidden: int, rng: np.random.Generator) -> list[np.ndarray]:
    """MATLAB's LSTM initialization: (w, rt, b, wy, by) as float32 arrays."""
    g = 4 * hidden
    w = rng.uniform(-1, 1, g) * np.sqrt(6 / (1 + g))
    q, r = np.linalg.qr(rng.normal(size=(g, hidden)))
    rt = (q * np.sign(np.diag(r))).T  # orthogonal (4H, H), stored transposed
    b = np.zeros(g)
    b[hidden : 2 * hidden] = 1.0  # forget gate
    wy = rng.uniform(-1, 1, (2, hidden)) * np.sqrt(6 / (hidden + 2))
    return [np.ascontiguousarray(a, dtype=np.float32) for a in (w, rt, b, wy, np.zeros(2))]


# ----------------------------------------------------------------------------- streaming
# The paper's LSTM resets its state for every window, so no state carries from one window to the
# next, and a stream cannot do less than window / hop steps per incoming sample. A stream keeps
# the state (h, c) of every window still open, ceil(window / hop) of them, and advances each
# through the samples of a push, one window after the other (the state stays in a few registers'
# worth of memory through a run of steps); a window's score is ready as soon as its last sample
# arrives, so a push of one sample costs one step per open window, not a whole window.
# Measured on the development machine (CPU time, window 50, hop 10): 0.52 µs per sample for a
# whole signal, 0.61 µs fed a hop per call; advancing every open window by one sample before
# the next (sample-major) cost 0.75 and 0.83 µs; computing b + w x_t once per sample and sharing
# it among the open windows saved nothing measurable (it is 5 % of a step's multiply-adds).


@nb.njit(inline="always", **_jit)
def _stream(x, clock, net, buffers, H):
    t0, window, hop = clock
    state, out = buffers
    (lo, scale), model = net
    slots = state.shape[0]
    h, c, a = np.empty(H, F32), np.empty(H, F32), np.empty(4 * H, F32)
    scratch = (h, c, a)
    last = t0 + x.shape[0] - 1
    n = 0
    # the windows open during this push: those starting at m * hop, t0 - window < m * hop <= last
    for m in range(max(0, (t0 - window + hop) // hop), last // hop + 1):
        start, end = m * hop, m * hop + window - 1
        saved = state[m % slots]
        if start >= t0:
            h[:] = 0
            c[:] = 0
        else:
            h[:] = saved[0]
            c[:] = saved[1]
        for t in range(max(start, t0), min(end, last) + 1):
            _step(F32((x[t - t0] - lo) * scale - 1.0), model, scratch, H)
        if end <= last:
            out[n] = 1.0 / (1.0 + np.exp(-_logit_diff(h, model[3], model[4])))
            n += 1
        else:
            saved[0] = h
            saved[1] = c
    return n


@nb.njit(**_jit)
def stream_push(x, clock, net, buffers):
    """Advance a stream of ``net`` (:func:`network`) by the raw samples ``x`` (float32), the first
    being sample ``t0`` of the stream, ``clock`` = (t0, window, hop); writes the slip probability of every window completed (those ending at
    ``window - 1 + k hop``) to ``out`` in order and returns how many. Each window takes the
    steps of :func:`predict_window` (equal to float32 rounding) in the same order whatever the
    pushes, so how the samples are cut into pushes does not change a bit of any score.

    ``buffers`` = (state, out): ``state`` (ceil(window / hop), 2, H) float32, h and c of the open
    windows (window m in row m mod its length), zeros, or anything, for a new stream.
    Single-threaded: this is the control loop's path."""
    H = net[1][1].shape[0]
    if H == 20:  # the paper's size, as a literal (see _step)
        return _stream(x, clock, net, buffers, 20)
    return _stream(x, clock, net, buffers, H)
