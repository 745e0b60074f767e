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
(``max_epochs=100`` is the paper's).
CPU: numba kernels (lstm_kernels.py, beside this file); GPU: torch's cuDNN LSTM with the same model and loop.
Streaming (``streamer``): every window still open keeps its state from push to push, so a
score is ready one step after its last sample (:class:`LSTMStreamer`).
"""

from __future__ import annotations

import importlib.util
import warnings

import numpy as np

from slipbench.base import BaseDetector, Streamer
from slipbench.detectors import lstm_kernels as kernels
from slipbench.errors import UsageError
from slipbench.params import Interval, Options, Sequence

PARAMS = ("w_", "rt_", "b_", "wy_", "by_")


class LSTM(BaseDetector):
    """The paper's LSTM; ``device`` "auto" uses a CUDA GPU when torch sees one."""

    check_params = {"max_epochs": 2, "validation_fraction": 0.2}  # fast settings for check_detector
    _parameter_constraints = {
        "hidden_size": Interval(int, 1, 512),
        "batch_size": Interval(int, 1, None),
        "momentum": Interval(float, 0.0, 0.999),
        "patience": Interval(int, 1, None),
        "validation_fraction": Interval(float, 0.01, 0.5),
        "device": Options(("auto", "cpu", "cuda")),
        "learning_rates": Sequence(Interval(float, 1e-12, 10.0)),
        "max_epochs": Sequence(Interval(int, 1, 100_000)),
    }

    def __init__(
        self,
        hidden_size=20,
        batch_size=1,
        momentum=0.125,
        learning_rates=(0.01, 1e-3, 1e-4, 1e-5),
        max_epochs=(20, 5, 3, 2),
        patience=10,
        validation_fraction=0.1,
        device="auto",
    ):
        self.hidden_size = hidden_size
        self.batch_size = batch_size
        self.momentum = momentum
        self.learning_rates = learning_rates
        self.max_epochs = max_epochs
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.device = device

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

    def _stages(self) -> list[tuple[float, int]]:
        rates = [float(r) for r in np.atleast_1d(self.learning_rates)]
        epochs = np.broadcast_to(np.atleast_1d(self.max_epochs), (len(rates),))
        return list(zip(rates, (int(e) for e in epochs)))

    def _fit(self, x, y, seed):
        stages = self._stages()
        rng = np.random.default_rng(seed)
        lo, hi = np.percentile(x, [2.5, 97.5])
        self.lo_, self.scale_ = (
            float(lo),
            float(2.0 / max(hi - lo, 1e-12)),
        )  # [p2.5, p97.5] -> [-1, 1]
        xn = ((x - self.lo_) * self.scale_ - 1.0).astype(np.float32)
        val = np.concatenate(
            [
                rng.choice(
                    np.flatnonzero(y == c),
                    max(1, int(round(self.validation_fraction * (y == c).sum()))),
                    replace=False,
                )
                for c in (0, 1)
            ]
        )
        train = np.setdiff1d(np.arange(len(y)), val)
        if len(train) == 0:
            raise UsageError(
                "LSTM: too few windows to keep a validation part; lower validation_fraction"
            )
        cuda = self.device == "cuda" or (self.device == "auto" and _cuda_available())
        params = kernels.init_params(self.hidden_size, rng)
        epoch = _torch_epoch if cuda else _numba_epoch
        best, best_loss, self.history_ = [p.copy() for p in params], np.inf, []
        total_epochs = sum(e for _, e in stages)  # the caps: early stopping may end sooner
        for lr, max_epochs in stages:
            params = [p.copy() for p in best]
            velocity = [np.zeros_like(p) for p in params]
            stale = 0
            for _ in range(max_epochs):
                order = train[rng.permutation(len(train))]
                epoch(xn, y, order, self.batch_size, lr, self.momentum, params, velocity)
                p = np.clip(kernels.predict_proba(xn[val], -1.0, 1.0, *params), 1e-12, 1 - 1e-12)
                loss = float(-np.mean(np.where(y[val] == 1, np.log(p), np.log1p(-p))))
                self.history_.append((lr, loss))
                self.report_progress(len(self.history_), total_epochs, loss=loss)
                if loss < best_loss - 1e-6:
                    best, best_loss, stale = [q.copy() for q in params], loss, 0
                else:
                    stale += 1
                    if stale >= self.patience:
                        break
        self.w_, self.rt_, self.b_, self.wy_, self.by_ = best
        self.validation_loss_ = best_loss
        self.history_ = np.array(self.history_)

    def _predict_proba(self, x):
        return kernels.predict_proba(x, self.lo_, self.scale_, *(getattr(self, k) for k in PARAMS))

    def fitted_choices(self):
        """Epochs run over all learning-rate stages (early stopping ends a stage before its cap),
        and the lowest validation loss (cross-entropy; ln 2 = 0.693 is a coin's)."""
        return {"epochs": int(len(self.history_)), "validation_loss": float(self.validation_loss_)}

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
        return kernels.predict_window(
            window, self.lo_, self.scale_, *(getattr(self, k) for k in PARAMS)
        )


class LSTMStreamer(Streamer):
    """Streams carrying the state of every open window from push to push
    (:func:`lstm_kernels.stream_push`): window / hop LSTM steps per incoming sample, each
    window's steps those of ``predict_window``."""

    def reset(self):
        super().reset()
        det = self.detector
        self._args = (float(det.lo_), float(det.scale_), *(getattr(det, k) for k in PARAMS))
        self._state = np.zeros((-(-self.window // self.hop), 2, det.rt_.shape[0]), np.float32)

    def _push(self, x, n):
        out = np.empty(n)
        kernels.stream_push(x, self.n_samples, self.window, self.hop, *self._args, self._state, out)
        return out


def _torch_installed() -> bool:
    return importlib.util.find_spec("torch") is not None


def _cuda_available() -> bool:
    """Whether torch is installed and sees a CUDA device ("auto" runs on the CPU without torch)."""
    if not _torch_installed():
        return False
    import torch

    return torch.cuda.is_available()


def _numba_epoch(x, y, order, batch_size, lr, momentum, params, velocity) -> None:
    kernels.train_epoch((x, y), order, (batch_size, lr, momentum), params, velocity)


def _torch_epoch(x, y, order, batch_size, lr, momentum, params, velocity, device="cuda") -> None:
    """The same epoch on a GPU: torch's LSTM with its second bias fixed at 0 (one bias per gate,
    as in the paper) and the same momentum update; arrays go back to numpy after the epoch."""
    import torch

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
