"""The LSTM detector and its numba kernels: gradients, schedule, early stopping, normalization."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from slipbench.detectors import lstm_kernels as fastlstm
from slipbench.engine.registry import detectors
from slipbench.errors import UsageError
from slipbench.testing import toy_windows

LSTM = detectors.get("lstm")
H = 20


def _params(seed=0):
    rng = np.random.default_rng(seed)
    return [
        rng.normal(0, 0.3, s).astype(np.float32)
        for s in ((4 * H,), (H, 4 * H), (4 * H,), (2, H), (2,))
    ]


def _torch_model(params):
    w, rt, b, wy, by = params
    lstm, lin = torch.nn.LSTM(1, H, batch_first=True), torch.nn.Linear(H, 2)
    with torch.no_grad():
        (
            lstm.weight_ih_l0.copy_(torch.tensor(w[:, None])),
            lstm.weight_hh_l0.copy_(torch.tensor(rt.T)),
        )
        lstm.bias_ih_l0.copy_(torch.tensor(b)), lstm.bias_hh_l0.zero_()
        lin.weight.copy_(torch.tensor(wy)), lin.bias.copy_(torch.tensor(by))
    return lstm, lin


def test_tanh_approximation_is_float32_accurate():
    x = np.linspace(-12, 12, 200_001).astype(np.float32)
    assert np.abs(fastlstm.tanh(x) - np.tanh(x.astype(np.float64))).max() < 1e-6


def test_gradients_and_scores_match_torch_autograd():
    rng = np.random.default_rng(1)
    x, y = rng.normal(size=(48, 30)).astype(np.float32), (np.arange(48) % 2).astype(np.int8)
    params = _params()
    lstm, lin = _torch_model(params)
    logits = lin(lstm(torch.tensor(x)[:, :, None])[0][:, -1])
    loss = torch.nn.functional.cross_entropy(logits, torch.tensor(y).long())
    loss.backward()
    expected = [
        lstm.weight_ih_l0.grad[:, 0],
        lstm.weight_hh_l0.grad.T,
        lstm.bias_ih_l0.grad,
        lin.weight.grad,
        lin.bias.grad,
    ]
    new = [p.copy() for p in params]
    # one full batch, lr 1, no momentum: the update is minus the gradient
    mean_loss = fastlstm.train_epoch(
        (x, y), np.arange(48), (48, 1.0, 0.0), new, [np.zeros_like(p) for p in new]
    )
    assert mean_loss == pytest.approx(loss.item(), rel=1e-5)
    for before, after, grad in zip(params, new, expected):
        np.testing.assert_allclose(
            before - after, grad.numpy(), atol=1e-5 * np.abs(grad.numpy()).max()
        )
    p_torch = torch.softmax(logits, 1)[:, 1].detach().numpy()
    np.testing.assert_allclose(
        fastlstm.predict_proba(x, fastlstm.network(-1.0, 1.0, params)), p_torch, atol=1e-6
    )
    assert fastlstm.predict_window(x[5], fastlstm.network(-1.0, 1.0, params)) == pytest.approx(
        p_torch[5], abs=1e-6
    )


@pytest.mark.slow
def test_epochs_do_not_depend_on_the_thread_count():
    import numba

    rng = np.random.default_rng(2)
    x, y = rng.normal(size=(600, 20)).astype(np.float32), (np.arange(600) % 2).astype(np.int8)
    order = rng.permutation(600)
    runs = []
    threads = numba.get_num_threads()
    try:
        for kernel, n_threads in (
            (fastlstm.train_epoch_parallel, threads),
            (fastlstm.train_epoch_parallel, 1),
            (fastlstm.train_epoch_serial, 1),
        ):
            numba.set_num_threads(n_threads)
            p = _params()
            kernel((x, y), order, (300, 0.01, 0.125), tuple(p), tuple(np.zeros_like(a) for a in p))
            runs.append(p)
    finally:
        numba.set_num_threads(threads)
    for a, b, c in zip(*runs):
        assert np.array_equal(a, b)  # bitwise, whatever the number of threads
        assert np.array_equal(a, c)  # and the serial kernel: every operation in the same order


def test_parallel_and_serial_kernels_are_cached_apart():
    """numba's cache keys entries by function name and signature, not by the parallel flag."""
    for pair in (
        (fastlstm.train_epoch_parallel, fastlstm.train_epoch_serial),
        (fastlstm.predict_proba_blocks_parallel, fastlstm.predict_proba_blocks_serial),
        (fastlstm.predict_proba_each_parallel, fastlstm.predict_proba_each_serial),
    ):
        assert pair[0].py_func.__qualname__ != pair[1].py_func.__qualname__
        assert pair[0].targetoptions.get("parallel") and not pair[1].targetoptions.get("parallel")


@pytest.mark.parametrize("hidden", [20, 7])
def test_batched_inference_matches_window_by_window_and_torch(hidden):
    """Blocks of LANES windows (with a padded last block) against the single-window path and torch."""
    rng = np.random.default_rng(4)
    n = 3 * fastlstm.LANES + 5
    x = rng.normal(size=(n, 30)).astype(np.float32)
    params = [
        rng.normal(0, 0.3, s).astype(np.float32)
        for s in ((4 * hidden,), (hidden, 4 * hidden), (4 * hidden,), (2, hidden), (2,))
    ]
    each = fastlstm.predict_proba_each_serial(x, fastlstm.network(0.5, 1.5, params))
    for kernel in (fastlstm.predict_proba_blocks_serial, fastlstm.predict_proba_blocks_parallel):
        blocks = kernel(x, fastlstm.network(0.5, 1.5, params))
        np.testing.assert_allclose(blocks, each, atol=1e-6)
        assert np.array_equal(blocks, kernel(x, fastlstm.network(0.5, 1.5, params)))
        # a window's score does not depend on its block or its neighbours
        np.testing.assert_allclose(
            kernel(x[7:40], fastlstm.network(0.5, 1.5, params)), blocks[7:40], atol=1e-6
        )
    lstm = torch.nn.LSTM(1, hidden, batch_first=True)
    w, rt, b, wy, by = params
    with torch.no_grad():
        (
            lstm.weight_ih_l0.copy_(torch.tensor(w[:, None])),
            lstm.weight_hh_l0.copy_(torch.tensor(rt.T)),
        )
        lstm.bias_ih_l0.copy_(torch.tensor(b)), lstm.bias_hh_l0.zero_()
        h = lstm(torch.tensor((x - 0.5) * 1.5 - 1.0)[:, :, None])[0][:, -1]
        p_torch = torch.softmax(h @ torch.tensor(wy).T + torch.tensor(by), 1)[:, 1].numpy()
    np.testing.assert_allclose(
        fastlstm.predict_proba(x, fastlstm.network(0.5, 1.5, params)), p_torch, atol=1e-6
    )
    assert fastlstm.predict_proba(x[:3], fastlstm.network(0.5, 1.5, params)) == pytest.approx(
        each[:3], abs=0
    )  # few: one by one


@pytest.mark.slow
def test_gpu_epoch_matches_cpu_epoch():
    """The torch path (used on GPUs) runs here on the CPU: same model, same updates."""
    from slipbench.detectors.lstm import _numba_epoch, _torch_epoch

    x, y = toy_windows(64, 25)
    x = x / 4
    order = np.random.default_rng(0).permutation(64)
    out = []
    for epoch, kw in ((_numba_epoch, {}), (_torch_epoch, {"device": "cpu"})):
        p = _params(3)
        v = [np.zeros_like(a) for a in p]
        epoch((x, y.astype(np.int8)), order, (8, 0.05, 0.125), (p, v), **kw)
        epoch((x, y.astype(np.int8)), order, (8, 0.05, 0.125), (p, v), **kw)  # velocity kept
        out.append(p)
    for a, b in zip(*out):
        np.testing.assert_allclose(a, b, atol=1e-5)


@pytest.mark.parametrize("input_range", [1.0, 4.0])
def test_normalization_by_training_percentiles(input_range):
    """The training windows' 2.5th and 97.5th percentiles land on -input_range and
    +input_range (the paper's percentiles; 1 is [-1, 1], slipbench 0.1.0's), in every path."""
    x, y = toy_windows(200, 20)
    d = LSTM(max_epochs=1, input_range=input_range).fit(x, y, seed=0)
    lo, hi = np.percentile(x, [2.5, 97.5])
    normalized = (np.array([lo, hi]) - d.lo_) * d.scale_ - 1
    np.testing.assert_allclose(normalized, [-input_range, input_range], rtol=1e-9)
    assert d.predict_window(x[0]) == pytest.approx(d.predict_proba(x[:1])[0], abs=1e-9)


def test_schedule_early_stopping_and_best_weights():
    x, y = toy_windows(200, 20)
    # learning rates too small to move the loss: every stage stops after 1 + patience epochs
    d = LSTM(learning_rates=(1e-9, 1e-10), max_epochs=50, patience=3).fit(x, y, seed=0)
    # (the second stage starts from the best loss so far, so it has no first improvement)
    assert d.history_[:, 0].tolist() == [1e-9] * 4 + [1e-10] * 3
    # the epochs it ran are a fitted choice the result row records (column ``epochs``)
    choices = d.fitted_choices()
    assert (choices["epochs"], choices["validation_loss"]) == (7, d.validation_loss_)
    # a real schedule: rates in order, no stage past its cap, the kept weights are the best seen
    d = LSTM(batch_size=1, max_epochs=(6, 2), learning_rates=(0.05, 0.005), patience=10).fit(
        x, y, seed=0
    )
    rates = d.history_[:, 0]
    assert (
        (np.diff(rates) <= 0).all() and (rates == 0.05).sum() == 6 and (rates == 0.005).sum() == 2
    )
    assert d.validation_loss_ == pytest.approx(d.history_[:, 1].min())
    assert d.validation_loss_ < 0.4  # it learned this easy problem (chance: log 2 = 0.69)


def test_few_windows_stretch_the_epochs_to_the_reference():
    """``reference_windows``: a model with fewer training windows than the reference runs
    reference / n times the epochs (caps and patience), so it gets the updates of one trained
    on the reference; with as many windows or more, or at 0, the schedule is the one given."""
    x, y = toy_windows(200, 20)  # 20 windows validate, 180 train
    slow = {"learning_rates": (1e-9, 1e-10), "max_epochs": 50, "patience": 3}
    d = LSTM(reference_windows=360, **slow).fit(x, y, seed=0)  # stretched twice: patience 6
    assert d.history_[:, 0].tolist() == [1e-9] * 7 + [1e-10] * 6
    d = LSTM(reference_windows=450, max_epochs=(4, 2), learning_rates=(1e-9, 1e-10)).fit(x, y)
    assert d.history_[:, 0].tolist() == [1e-9] * 10 + [1e-10] * 5  # caps 4 and 2, 2.5 times
    plain = LSTM(max_epochs=2).fit(x, y, seed=0)
    for reference in (0, 180):
        same = LSTM(max_epochs=2, reference_windows=reference).fit(x, y, seed=0)
        for k in ("w_", "rt_", "b_", "wy_", "by_", "history_"):
            assert np.array_equal(getattr(same, k), getattr(plain, k))


def test_bad_schedules_are_refused():
    x, y = toy_windows(40, 10)
    with pytest.raises(UsageError, match="one per rate"):
        LSTM(learning_rates=(0.1, 0.01), max_epochs=(3, 3, 3)).fit(x, y)
    with pytest.raises(
        UsageError, match="'batch_size' parameter of LSTM must be an int in \\[1, inf\\]"
    ):
        LSTM(batch_size=0).fit(x, y)
    with pytest.raises(
        UsageError,
        match="'max_epochs' parameter of LSTM must be an int in \\[1, 100000\\], or a non-empty list",
    ):
        LSTM(max_epochs="abc").validate_params()
    with pytest.raises(UsageError, match="'learning_rates' parameter of LSTM must be a float"):
        LSTM(learning_rates=(0.1, -1.0)).validate_params()
    if not torch.cuda.is_available():
        with pytest.raises(UsageError, match="torch sees no CUDA device"):
            LSTM(device="cuda").validate_params()


def test_auto_trains_batch_1_on_the_cpu_and_says_why(monkeypatch):
    """At batch 1 the GPU is the slower device (one kernel launch per update): "auto" picks the
    CPU even where torch sees a GPU, and the fitted choices say which device ran and why."""
    from slipbench.detectors import lstm

    monkeypatch.setattr(lstm, "_cuda_available", lambda: True)
    assert lstm._device_choice("auto", 1) == ("cpu", "batch_size 1 < 128: the GPU is slower there")
    assert lstm._device_choice("auto", 128)[0] == "cuda"
    assert lstm._device_choice("cpu", 512) == ("cpu", "device set")
    monkeypatch.setattr(lstm, "_cuda_available", lambda: False)
    assert lstm._device_choice("auto", 512) == ("cpu", "no CUDA device")
    x, y = toy_windows(60, 20)
    choices = LSTM(max_epochs=1).fit(x, y, seed=0).fitted_choices()
    assert (choices["device"], choices["device_reason"]) == ("cpu", "no CUDA device")


def test_batch_1_fits_launch_no_threads_and_ignore_the_thread_count(monkeypatch):
    """A batch-1 update is far too small to pay a parallel launch (29x slower with 16 threads,
    issue 32): training never calls the parallel kernel, and the weights do not depend on
    numba's thread count."""
    import numba

    def refuse(*args):
        raise AssertionError("a parallel kernel ran at batch 1")

    monkeypatch.setattr(fastlstm, "train_epoch_parallel", refuse)
    x, y = toy_windows(120, 20)
    threads, fits = numba.get_num_threads(), []
    try:
        for n in (1, threads):
            numba.set_num_threads(n)
            fits.append(LSTM(max_epochs=2).fit(x, y, seed=3))
    finally:
        numba.set_num_threads(threads)
    for k in ("w_", "rt_", "b_", "wy_", "by_"):
        assert np.array_equal(getattr(fits[0], k), getattr(fits[1], k))


def _lockstep_plan(orders, rates, batch_size):
    from slipbench.detectors import lstm_lockstep

    lanes = -(-len(orders) // lstm_lockstep.MODELS) * lstm_lockstep.MODELS
    plan = np.zeros((lanes, max(map(len, orders))), np.int64), np.zeros(lanes, np.int64)
    lr = np.zeros(lanes, np.float32)
    for i, o in enumerate(orders):
        plan[0][i, : len(o)], plan[1][i], lr[i] = o, len(o), rates[i]
    return (*plan, lr, batch_size, 0.125)


@pytest.mark.slow  # compiles the lockstep kernels (minutes on a busy 2-core machine, then cached)
@pytest.mark.parametrize("batch_size", [1, 5])
def test_lockstep_epoch_gives_each_model_its_weights_alone(batch_size):
    """Ten models in two blocks of lanes, each with its own windows, order, length of epoch and
    learning rate (the lanes past the tenth empty): each gets, bit for bit, what one epoch of
    the single-model kernel gives it."""
    from slipbench.detectors import lstm_lockstep

    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(200, 30)).astype(np.float32), (rng.random(200) < 0.5).astype(np.int8)
    models = [fastlstm.init_params(H, np.random.default_rng(i)) for i in range(10)]
    orders = [rng.permutation(200)[: 150 + 3 * i] for i in range(10)]
    rates = [0.01 * (1 + i % 3) for i in range(10)]
    params = lstm_lockstep.pack(models)
    velocity = np.zeros_like(params)
    lstm_lockstep.lockstep_epoch(
        (x, y), _lockstep_plan(orders, rates, batch_size), params, velocity
    )
    for i, (model, order) in enumerate(zip(models, orders)):
        alone, v = [p.copy() for p in model], [np.zeros_like(p) for p in model]
        fastlstm.train_epoch((x, y), order, (batch_size, rates[i], 0.125), alone, v)
        for a, b in zip(alone, lstm_lockstep.unpack(params, i, H)):
            assert np.array_equal(a, b)
        for a, b in zip(v, lstm_lockstep.unpack(velocity, i, H)):
            assert np.array_equal(a, b)


@pytest.mark.slow
def test_fit_lockstep_fits_each_model_as_fit_does():
    """The detector contract's lockstep capability: models with their own data, seeds, early
    stops and stages (one with other hyperparameters, which trains in its own group) come out
    as ``fit`` makes them, weights bit for bit, history and fitted choices equal."""
    from slipbench.base import FitJob

    jobs = [FitJob(*toy_windows(90 + 10 * i, 20, seed=i), seed=i) for i in range(3)]
    # models of one group, each stretched by its own reference / n (81 and 90 windows train)
    two = {"learning_rates": (0.05, 0.005), "max_epochs": (3, 2), "reference_windows": 150}
    settings = [two, two, {"max_epochs": 2, "patience": 1}]
    together = LSTM.fit_lockstep([LSTM(**s) for s in settings], jobs)
    for det, s, job in zip(together, settings, jobs):
        alone = LSTM(**s).fit(job.x, job.y, seed=job.seed)
        for k in ("w_", "rt_", "b_", "wy_", "by_", "history_"):
            assert np.array_equal(getattr(det, k), getattr(alone, k))
        assert det.fitted_choices() == alone.fitted_choices()
        assert (det.lo_, det.scale_, det.window_length_) == (alone.lo_, alone.scale_, 20)
    with pytest.raises(UsageError, match="only class"):
        LSTM.fit_lockstep([LSTM()], [FitJob(np.ones((10, 20)), np.zeros(10))])


@pytest.mark.slow
@pytest.mark.parametrize("batch_size", [1, 5])
def test_torch_lockstep_epoch_matches_the_numba_one(batch_size):
    """The GPU path of lockstep training (torch, batched over the models) runs here on the CPU:
    each model's weights agree with the numba lanes' to float32 tolerance."""
    from slipbench.detectors import lstm_lockstep, lstm_lockstep_torch

    rng = np.random.default_rng(1)
    x, y = rng.normal(size=(120, 25)).astype(np.float32), (rng.random(120) < 0.5).astype(np.int8)
    models = [fastlstm.init_params(H, np.random.default_rng(i)) for i in range(9)]
    orders = [rng.permutation(120)[: 60 + 5 * i] for i in range(9)]
    plan = _lockstep_plan(orders, [0.01 * (1 + i % 3) for i in range(9)], batch_size)
    out = []
    for epoch in (lstm_lockstep.lockstep_epoch, lstm_lockstep_torch.lockstep_epoch):
        params = lstm_lockstep.pack(models)
        velocity = np.zeros_like(params)
        kwargs = {"device": "cpu"} if epoch is lstm_lockstep_torch.lockstep_epoch else {}
        epoch((x, y), plan, params, velocity, **kwargs)
        epoch((x, y), plan, params, velocity, **kwargs)  # velocity carried over
        out.append(params)
    assert np.abs(out[0] - lstm_lockstep.pack(models)).max() > 1e-3  # they trained
    np.testing.assert_allclose(out[0], out[1], atol=2e-5)


def test_fit_lockstep_runs_each_group_on_its_device(monkeypatch):
    """Models whose device is CUDA go to the torch lockstep epoch (here on the CPU), the rest
    to the numba lanes; a group never mixes devices."""
    from slipbench.base import FitJob
    from slipbench.detectors import lstm, lstm_compile, lstm_lockstep, lstm_lockstep_torch

    calls = []
    # the kernels' compile exercise (once a process) would call the recorder too: taken as run
    monkeypatch.setattr(lstm_compile, "_ready", set(lstm_compile._EXERCISE))

    def recorder(name):
        def epoch(data, plan, params, velocity):
            calls.append((name, int((plan[1] > 0).sum())))

        return epoch

    monkeypatch.setattr(lstm_lockstep, "lockstep_epoch", recorder("cpu"))
    monkeypatch.setattr(lstm_lockstep_torch, "lockstep_epoch", recorder("cuda"))
    real = lstm._device_choice
    monkeypatch.setattr(
        lstm, "_device_choice", lambda d, b: ("cuda", "test") if b >= 128 else real(d, b)
    )
    jobs = [FitJob(*toy_windows(60, 20, seed=i), seed=i) for i in range(3)]
    dets = [LSTM(max_epochs=1), LSTM(max_epochs=1), LSTM(max_epochs=1, batch_size=128)]
    LSTM.fit_lockstep(dets, jobs)
    assert set(calls) == {("cpu", 2), ("cuda", 1)}  # one call per epoch of each group
    assert [d.fitted_choices()["device"] for d in dets] == ["cpu", "cpu", "cuda"]
