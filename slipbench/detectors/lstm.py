"""The paper's LSTM slip classifier (Van Wyk & Falco, section V; LSTM cell after Greff et al.,
"LSTM: A Search Space Odyssey", 2017): one layer of 20 units on the univariate signal, two
outputs from the last step, cross-entropy, SGD with momentum 0.125 through the learning rates
0.01, 1e-3, 1e-4, 1e-5 with early stopping on a validation part, full BPTT, inputs normalized by
the 2.5th/97.5th percentiles, state reset for every window.

Choices the paper leaves open (see the README): batch size 1 (an update per window, as in
PyBrain's BackpropTrainer, whose "10 epochs without progress" rule the paper quotes); 10 % of
the training windows
(stratified, drawn from the seed) validate; the weights with the lowest validation loss are kept
and each learning-rate stage starts from them with zero velocity; MATLAB's initialization
(Glorot input and output weights, orthogonal recurrent weights, forget-gate bias 1); epochs per
stage capped at (20, 5, 3, 2) by default, so that the whole paper runs in minutes
(``max_epochs=100`` is the paper's); the percentiles mapped to [-4, 4] (``input_range``): at
[-1, 1] the input barely moves the gates, and the LSTM did not learn on a real BioTac SP
(docs/studies/lstm-study.md, ``benchmarks/lstm_input_study.py``). ``reference_windows``:
a model trained on fewer windows than it runs reference / n times the epochs (caps and
patience), so few windows (DoS at 1000 ms: 84-95) get the updates many get
(``benchmarks/lstm_window_study.py``); 0 keeps the epochs as given.
CPU: numba kernels (lstm_kernels.py, beside this file); GPU: torch's cuDNN LSTM with the same model and loop.
Many models train together through ``LSTM.fit_lockstep`` (lstm_lockstep.py, lstm_lockstep_torch.py).
Streaming (``streamer``): every window still open keeps its state from push to push, so a
score is ready one step after its last sample (:class:`LSTMStreamer`).
"""

from __future__ import annotations

import importlib.util
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from slipbench.base import BaseDetector, FitJob, Streamer
from slipbench.detectors import lstm_compile
from slipbench.detectors import lstm_kernels as kernels
from slipbench.errors import UsageError
from slipbench.params import Interval, Options, Sequence

PARAMS = ("w_", "rt_", "b_", "wy_", "by_")


class LSTM(BaseDetector):
    """The paper's LSTM (section V): 20 units on the univariate signal, SGD with momentum.

    ``device`` "auto" trains on a CUDA GPU where torch sees one and the batch is large enough
    for it to be faster (``CUDA_MIN_BATCH``), else on the CPU."""

    check_params = {"max_epochs": 2, "validation_fraction": 0.2}  # fast settings for check_detector
    lo_: float  # fitted normalization: (x - lo_) * scale_ - 1, the training windows' 2.5th and
    scale_: float  # 97.5th percentiles at -input_range and +input_range
    lockstep = True  # _fit_lockstep trains models of one window length and settings together
    _parameter_constraints = {
        "hidden_size": Interval(int, 1, 512),
        "batch_size": Interval(int, 1, None),
        "momentum": Interval(float, 0.0, 0.999),
        "patience": Interval(int, 1, None),
        "validation_fraction": Interval(float, 0.01, 0.5),
        "device": Options(("auto", "cpu", "cuda")),
        "learning_rates": Sequence(Interval(float, 1e-12, 10.0)),
        "max_epochs": Sequence(Interval(int, 1, 100_000)),
        "input_range": Interval(float, 1e-3, 1e3),
        "reference_windows": Interval(int, 0, None),
    }

    def __init__(  # noqa: PLR0913 (hyperparameters: get_params reads one keyword each)
        self,
        hidden_size=20,
        batch_size=1,
        momentum=0.125,
        learning_rates=(0.01, 1e-3, 1e-4, 1e-5),
        max_epochs=(20, 5, 3, 2),
        patience=10,
        validation_fraction=0.1,
        device="auto",
        input_range=4.0,
        reference_windows=0,
    ):
        self.hidden_size = hidden_size
        self.batch_size = batch_size
        self.momentum = momentum
        self.learning_rates = learning_rates
        self.max_epochs = max_epochs
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.device = device
        self.input_range = input_range
        self.reference_windows = reference_windows

    def validate_params(self) -> None:
        super().validate_params()
        rates, epochs = np.atleast_1d(self.learning_rates), np.atleast_1d(self.max_epochs)
        if len(epochs) not in (1, len(rates)):
            raise UsageError(
                f"The 'max_epochs' parameter of LSTM needs one cap for all learning rates or one per rate "
                f"({len(rates)}); got {self.max_epochs!r}"
            )
        if self.device == "cuda" and not _torch_installed():
            raise UsageError(
                "The 'device' parameter of LSTM is 'cuda', which runs on torch, and torch is not "
                "installed; install it with: pip install 'slipbench[torch]' (or use 'cpu')"
            )
        if self.device == "cuda" and not _cuda_available():
            raise UsageError(
                "The 'device' parameter of LSTM is 'cuda' but torch sees no CUDA device here; "
                "use 'cpu' or 'auto'"
            )

    def _stages(self, n_train: int | None = None) -> list[tuple[float, int]]:
        """(learning rate, epoch cap) per stage, the caps scaled for ``n_train`` windows
        (:meth:`_epoch_factor`)."""
        rates = [float(r) for r in np.atleast_1d(self.learning_rates)]
        epochs = np.broadcast_to(np.atleast_1d(self.max_epochs), (len(rates),))
        factor = self._epoch_factor(n_train)
        return list(zip(rates, (int(np.ceil(e * factor)) for e in epochs)))

    def _epoch_factor(self, n_train: int | None) -> float:
        """How many times the epochs (caps and patience) are stretched: with
        ``reference_windows`` above 0 and fewer training windows than it, by reference / n, so a
        model trained on few windows gets the updates one on ``reference_windows`` gets."""
        if not self.reference_windows or not n_train:
            return 1.0
        return max(1.0, self.reference_windows / n_train)

    @classmethod
    def prepare(cls, say):
        """Compile the numba kernels once for this machine before any worker starts
        (:mod:`lstm_compile`); nothing where they are cached."""
        lstm_compile.compile_ahead(say)

    @classmethod
    def prepare_ahead(cls, say):
        """Start that compile in a child at once (:func:`lstm_compile.start_ahead`)."""
        lstm_compile.start_ahead(say)

    def _fit(self, x, y, seed):
        lstm_compile.ready("predict", "alone")
        self.device_, self.device_reason_ = _device_choice(self.device, self.batch_size)
        run = _Training(self, x, y, seed)
        epoch = _torch_epoch if self.device_ == "cuda" else _numba_epoch
        while not run.done:
            epoch((run.xn, y), run.order(), (self.batch_size, run.lr, self.momentum), run.state)
            run.end_epoch()
        run.finish()

    @classmethod
    def _fit_lockstep(cls, detectors, data):
        """Fit ``detectors`` (clones of this class), each on its own (x, y, seed), as ``_fit``
        would: those that share hyperparameters (the device among them) and window length train
        together. On the CPU, MODELS at a time in the SIMD lanes (:mod:`lstm_lockstep`), each to
        its weights alone bit for bit; on CUDA, all in batched torch operations
        (:mod:`lstm_lockstep_torch`), to float32 tolerance of torch's LSTM alone."""
        lstm_compile.ready("predict", "lockstep")
        groups: dict[tuple, list[int]] = {}
        for i, (det, (x, _, _, _)) in enumerate(zip(detectors, data)):
            det.device_, det.device_reason_ = _device_choice(det.device, det.batch_size)
            key = (repr(sorted(det.get_params().items())), x.shape[1])
            groups.setdefault(key, []).append(i)
        for members in groups.values():
            _train_in_lockstep([detectors[i] for i in members], [data[i][:3] for i in members])

    def _predict_proba(self, x):
        lstm_compile.ready("predict")
        return kernels.predict_proba(x, self._net())

    def fitted_choices(self):
        """Epochs run over all learning-rate stages (early stopping ends a stage before its cap),
        the lowest validation loss (cross-entropy; ln 2 = 0.693 is a coin's), and the device
        that trained the model and why (``device_reason``)."""
        return {
            "epochs": int(len(self.history_)),
            "validation_loss": float(self.validation_loss_),
            "device": self.device_,
            "device_reason": self.device_reason_,
        }

    @classmethod
    def benchmark(cls, length: int, seconds: float, seed: int = 0):
        """Training, batched inference and one-window latency against stock torch.nn.LSTM;
        None, with a warning saying what to install, where torch (the reference) is missing."""
        if not _torch_installed():
            warnings.warn(
                "lstm: no speed figures against stock torch.nn.LSTM, the reference, because torch "
                "is not installed; install it with: pip install 'slipbench[torch]'",
                stacklevel=2,
            )
            return None
        from slipbench.detectors.lstm_bench import lstm_targets

        return lstm_targets(cls, length, seconds, seed)

    def _streamer(self, hop, threshold):
        return LSTMStreamer(self, hop, threshold)

    def predict_window(self, window: np.ndarray) -> float:
        """Slip probability of one window (float32, the fitted length), unchecked: for control loops."""
        lstm_compile.ready("stream")
        return kernels.predict_window(window, self._net())

    def _net(self) -> tuple:
        return kernels.network(self.lo_, self.scale_, (getattr(self, k) for k in PARAMS))


class LSTMStreamer(Streamer):
    """Streams carrying the state of every open window from push to push
    (:func:`lstm_kernels.stream_push`): window / hop LSTM steps per incoming sample, each
    window's steps those of ``predict_window``."""

    def reset(self):
        super().reset()
        lstm_compile.ready("stream")
        det = self.detector
        self._net = det._net()
        self._state = np.zeros((-(-self.window // self.hop), 2, det.rt_.shape[0]), np.float32)

    def _push(self, x, n):
        out = np.empty(n)
        clock = (self.n_samples, self.window, self.hop)
        kernels.stream_push(x, clock, self._net, (self._state, out))
        return out


def _torch_installed() -> bool:
    return importlib.util.find_spec("torch") is not None


def _cuda_available() -> bool:
    """Whether torch is installed and sees a CUDA device ("auto" runs on the CPU without torch)."""
    if not _torch_installed():
        return False
    import torch

    return torch.cuda.is_available()


# Issue 32, measured on an H100 against CPU cores: at batch 128 the GPU trained 2.46 M samples/s
# against 1.84 M on 16 cores; at batch 1 (one kernel launch per update) 0.034 M against 1.75 M
# on one core. "auto" takes the GPU only from this batch size on.
CUDA_MIN_BATCH = 128


def _device_choice(device: str, batch_size: int) -> tuple[str, str]:
    """The device that trains, and why: "auto" never picks the device known to be slower."""
    if device != "auto":
        return device, "device set"
    if not _cuda_available():
        return "cpu", "no CUDA device"
    if batch_size < CUDA_MIN_BATCH:
        return "cpu", f"batch_size {batch_size} < {CUDA_MIN_BATCH}: the GPU is slower there"
    return "cuda", f"batch_size {batch_size} >= {CUDA_MIN_BATCH}: the GPU is faster there"


class _Training:
    """One model's way through the learning-rate stages, an epoch at a time: the same steps
    whether it trains alone (:meth:`LSTM._fit`) or in lockstep with others."""

    def __init__(self, det: Any, x: np.ndarray, y: np.ndarray, seed: int):
        self.det, self.y = det, y
        self.rng = rng = np.random.default_rng(seed)
        lo, hi = np.percentile(x, [2.5, 97.5])
        scale = 2.0 * det.input_range / max(hi - lo, 1e-12)  # [lo, hi] -> [-range, range]
        det.lo_, det.scale_ = float(lo + (det.input_range - 1.0) / scale), float(scale)
        self.xn = ((x - det.lo_) * det.scale_ - 1.0).astype(np.float32)
        counts = [max(1, int(round(det.validation_fraction * (y == c).sum()))) for c in (0, 1)]
        self.val = np.concatenate(
            [rng.choice(np.flatnonzero(y == c), k, replace=False) for c, k in zip((0, 1), counts)]
        )
        self.train = np.setdiff1d(np.arange(len(y)), self.val)
        if len(self.train) == 0:
            raise UsageError(
                "LSTM: too few windows to keep a validation part; lower validation_fraction"
            )
        self.stages = det._stages(len(self.train))
        self.patience = int(np.ceil(det.patience * det._epoch_factor(len(self.train))))
        self.best, self.best_loss = kernels.init_params(det.hidden_size, rng), np.inf
        self.history: list[tuple[float, float]] = []
        self.total_epochs = sum(e for _, e in self.stages)  # caps: early stopping may end sooner
        self.stage = 0
        self._start_stage()

    def _start_stage(self) -> None:
        """Each stage starts from the best weights so far, with zero velocity."""
        params = [p.copy() for p in self.best]
        self.state = (params, [np.zeros_like(p) for p in params])
        self.stale = self.epochs_in_stage = 0

    @property
    def done(self) -> bool:
        return self.stage >= len(self.stages)

    @property
    def lr(self) -> float:
        return self.stages[self.stage][0]

    def order(self) -> np.ndarray:
        """The training windows in this epoch's order."""
        return self.train[self.rng.permutation(len(self.train))]

    def end_epoch(self, report: bool = True) -> None:
        """Validate the weights in :attr:`state`, keep the best, stop early or change stage;
        ``report`` the epoch to the bar (in lockstep the group reports once per epoch)."""
        params, val, y = self.state[0], self.val, self.y
        net = kernels.network(-1.0, 1.0, params)
        p = np.clip(kernels.predict_proba(self.xn[val], net), 1e-12, 1 - 1e-12)
        loss = float(-np.mean(np.where(y[val] == 1, np.log(p), np.log1p(-p))))
        self.history.append((self.lr, loss))
        if report:
            self.det.report_progress(len(self.history), self.total_epochs, loss=loss)
        self.epochs_in_stage += 1
        if loss < self.best_loss - 1e-6:
            self.best, self.best_loss, self.stale = [q.copy() for q in params], loss, 0
        else:
            self.stale += 1
        if self.stale >= self.patience or self.epochs_in_stage >= self.stages[self.stage][1]:
            self.stage += 1
            if not self.done:
                self._start_stage()

    def finish(self) -> None:
        det = self.det
        det.w_, det.rt_, det.b_, det.wy_, det.by_ = self.best
        det.validation_loss_, det.history_ = self.best_loss, np.array(self.history)


def _train_in_lockstep(dets: list[LSTM], data: list[tuple]) -> None:
    """Train models of one window length and hyperparameters together: an epoch of every model
    still training is one lockstep epoch (on the device the models chose); validation, early
    stopping and stages run per model, as alone (:class:`_Training`)."""
    from slipbench.detectors import lstm_lockstep as lockstep
    from slipbench.detectors import lstm_lockstep_torch

    epoch: Callable[..., None] = (
        lstm_lockstep_torch.lockstep_epoch if dets[0].device_ == "cuda" else lockstep.lockstep_epoch
    )

    runs = [_Training(d, *args) for d, args in zip(dets, data)]
    xs = np.concatenate([r.xn for r in runs])
    ys = np.concatenate([r.y for r in runs])
    offsets = np.cumsum([0] + [len(r.y) for r in runs])[:-1]
    lanes = -(-len(runs) // lockstep.MODELS) * lockstep.MODELS
    longest = max(len(r.train) for r in runs)
    params = lockstep.pack([r.state[0] for r in runs])
    velocity = np.zeros_like(params)
    batch_size, momentum = dets[0].batch_size, dets[0].momentum
    total = max(r.total_epochs for r in runs)
    dets[0].report_progress(0, total, models=len(runs))  # before the first epoch, which is long
    epochs = 0
    while not all(r.done for r in runs):
        orders, counts = np.zeros((lanes, longest), np.int64), np.zeros(lanes, np.int64)
        rates = np.zeros(lanes, np.float32)
        for i, r in enumerate(runs):
            if not r.done:
                order = r.order()
                orders[i, : len(order)], counts[i], rates[i] = order + offsets[i], len(order), r.lr
        plan = (orders, counts, rates, batch_size, momentum)
        epoch((xs, ys), plan, params, velocity)
        for i, r in enumerate(runs):
            if r.done:
                continue
            hidden = r.det.hidden_size
            r.state = (lockstep.unpack(params, i, hidden), lockstep.unpack(velocity, i, hidden))
            stage = r.stage
            r.end_epoch(report=False)
            if r.stage != stage:  # a new stage restarts from the best weights, zero velocity
                lockstep.put(params, i, r.state[0])
                lockstep.put(velocity, i, r.state[1])
        epochs += 1
        _report_group(dets[0], runs, epochs, total)
    for r in runs:
        r.finish()


def _report_group(det: LSTM, runs: list[_Training], epoch: int, total: int) -> None:
    """One report for models trained together, as a TorchDetector's per epoch: the lockstep
    epoch, the models that trained in it and their mean validation loss."""
    losses = [r.history[-1][1] for r in runs if len(r.history) == epoch]
    det.report_progress(epoch, total, models=len(losses), loss=float(np.mean(losses)))


def _numba_epoch(data, order, schedule, state) -> None:
    """One epoch of SGD on ``data`` = (x, y) in ``order``, ``schedule`` = (batch size, learning
    rate, momentum), ``state`` = (params, velocity) updated in place."""
    kernels.train_epoch(data, order, schedule, *state)


def _torch_epoch(data, order, schedule, state, device="cuda") -> None:
    """:func:`_numba_epoch` on a GPU: torch's LSTM with its second bias fixed at 0 (one bias per
    gate, as in the paper) and the same momentum update; arrays go back to numpy after the epoch."""
    import torch

    (x, y), (batch_size, lr, momentum), (params, velocity) = data, schedule, state

    dev = torch.device(device)
    to_torch = [
        lambda a: a[:, None],
        lambda a: a.T,
        lambda a: a,
        lambda a: a,
        lambda a: a,
    ]  # numpy -> torch layout
    to_numpy = [lambda t: t[:, 0], lambda t: t.T, lambda t: t, lambda t: t, lambda t: t]
    lstm = torch.nn.LSTM(1, params[1].shape[0], batch_first=True).to(dev)
    # get_parameter, not attribute access: torch types a module's attributes as Tensor | Module
    lstm.get_parameter("bias_hh_l0").requires_grad_(False).zero_()
    wy, by = (torch.tensor(p, device=dev, requires_grad=True) for p in params[3:])
    weights = (lstm.get_parameter(n) for n in ("weight_ih_l0", "weight_hh_l0", "bias_ih_l0"))
    tensors = [*weights, wy, by]
    with torch.no_grad():
        for t, p, f in zip(tensors[:3], params, to_torch):
            t.copy_(torch.tensor(np.ascontiguousarray(f(p)), device=dev))
    vel = [torch.tensor(np.ascontiguousarray(f(v)), device=dev) for v, f in zip(velocity, to_torch)]
    xs, ys = torch.tensor(x, device=dev)[:, :, None], torch.tensor(y, device=dev).long()
    for start in range(0, len(order), batch_size):
        idx = torch.as_tensor(order[start : start + batch_size], device=dev)
        out, _ = lstm(xs[idx])
        loss = torch.nn.functional.cross_entropy(out[:, -1] @ wy.T + by, ys[idx])
        grads = torch.autograd.grad(loss, tensors)
        with torch.no_grad():
            for t, v, g in zip(tensors, vel, grads):
                v.mul_(momentum).sub_(lr * g)
                t.add_(v)
    with torch.no_grad():
        for p, v, t, tv, f in zip(params, velocity, tensors, vel, to_numpy):
            p[:] = f(t).cpu().numpy()
            v[:] = f(tv).cpu().numpy()


def _exercise_lockstep() -> None:
    """Models trained in lockstep: one block (the serial kernel) and several (the parallel)."""
    from slipbench.detectors.lstm_lockstep import MODELS

    x, y = lstm_compile.exercise_data()
    for n_models in (1, MODELS + 1):
        dets: list[BaseDetector] = [LSTM(max_epochs=1, device="cpu") for _ in range(n_models)]
        LSTM.fit_lockstep(dets, [FitJob(x[:40], y[:40], i) for i in range(n_models)])


def _exercise_alone() -> None:
    """One model trained alone, at a small batch (serial epochs) and a large one (parallel)."""

    x, y = lstm_compile.exercise_data()
    for batch in (1, 256):
        LSTM(max_epochs=1, batch_size=batch, device="cpu").fit(x, y, seed=0)


lstm_compile.register("lockstep", _exercise_lockstep)
lstm_compile.register("alone", _exercise_alone)
