"""TorchDetector: any ``torch.nn.Module`` that maps a batch of windows to one logit per window,
made a slipbench detector.

What a plugin writes is the module (``build``) and its own parameters; this class owns the rest:

- *input*: univariate windows (n, window) or windows of channels (n, window, channels),
  standardized with the training side's mean and standard deviation (each channel's own), given
  to the network in torch's ``Conv1d`` layout (batch, channels, window), one channel for
  univariate windows;
- *training*: Adam on the binary cross-entropy of the logits, mini-batches of ``batch_size``,
  epochs of ``windows_per_epoch`` windows drawn from successive shuffles of the training
  windows (a small training set is passed several times per epoch, a large one in parts, so
  an epoch costs the same whatever the set's size; None: one pass), a validation part of whole
  trials (``validation_fraction`` of the training windows, at most :data:`MAX_VALIDATION`,
  every class on both sides; by
  window only where the windows come without their trials, and then ``fitted_choices`` says
  so), early stopping after ``patience`` epochs without a lower validation loss, the best
  epoch's weights kept, and its scores on the validation windows (``validation_y_``,
  ``validation_scores_``: what the engine judges "did not learn" on);
- *determinism*: every random choice (initial weights, validation trials, batch order) is drawn
  from the seed inside a forked torch RNG, so a fit leaves the caller's torch RNG alone and the
  same seed gives the same model on the CPU;
- *device*: ``cpu``, ``cuda`` or ``auto``: the CPU without CUDA, else the device measured
  faster for this network and batch (:mod:`slipbench.torch.device`); ``fitted_choices`` says
  which ran and why;
- *saving*: the state dict as plain arrays in the detector's ``.npz`` (never pickle), rebuilt
  with ``build`` on load;
- *scoring*: batched ``predict_proba``; streaming with the base class's stream (each completed
  window scored once).
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from slipbench.base import BaseDetector
from slipbench.errors import UsageError
from slipbench.params import Interval, Options
from slipbench.seeding import rng_for, seed_int
from slipbench.torch import device as devices

INSTALL_HINT = "pip install 'slipbench[torch]'"
#: windows scored at once by predict_proba (bounded memory, whatever the batch size)
SCORE_BATCH = 4096
#: windows scored on one CPU thread at most: a stream's push scores one or a few, where torch's
#: thread pool costs more than it gives, and on a busy machine its threads wait for one another
#: (3 windows of tcn's check network: 122 ms on 2 threads of 2 busy cores, 1.6 ms on one)
FEW_WINDOWS = 16
#: validation windows at most: each epoch scores them all, and beyond a few hundred they cost
#: more than an epoch's training (tcn: 256 windows per epoch; 40,000 windows at 5 samples give
#: 8,000 at a fifth), while the "did not learn" interval is still +-0.04 at 512; the rest train
MAX_VALIDATION = 512
#: training windows per epoch by default: an epoch's cost bounded whatever the training set
WINDOWS_PER_EPOCH = 1024


@dataclass(frozen=True)
class EpochWindows:
    """None (an epoch is one pass over the training windows) or an int number of windows."""

    def check(self, value: Any) -> bool:
        return value is None or Interval(int, 1, None).check(value)

    def __str__(self) -> str:
        return "None (one pass) or an int in [1, inf]"


class TorchDetector(BaseDetector):
    """A detector around the ``torch.nn.Module`` that :meth:`build` returns.

    Subclasses implement ``build(window_length, n_channels) -> torch.nn.Module``, a module that
    takes a float32 tensor of windows (batch, n_channels, window_length) and returns one logit
    per window, shape (batch,) or (batch, 1); they declare their own parameters in ``__init__``
    beside the training ones (pass those on to ``super().__init__``) and in
    ``_parameter_constraints`` (extend :attr:`TRAINING_CONSTRAINTS`).

    Every TorchDetector reads both inputs (:attr:`inputs`): univariate windows reach the network
    as one channel (``n_channels`` 1), windows of channels (n, window, C) as C channels, so one
    ``build`` serves both. A network that makes sense on the univariate signal only declares
    ``inputs = ("univariate",)``.
    """

    requires: ClassVar[tuple[str, ...]] = ("torch",)
    install_hint: ClassVar[str | None] = INSTALL_HINT
    check_params: ClassVar[dict[str, Any]] = {"max_epochs": 3, "patience": 1}
    inputs: ClassVar[tuple[str, ...]] = ("univariate", "channels")
    # one window of each class to validate on (early stopping), one to train on
    min_class_windows: ClassVar[int] = 2
    TRAINING_CONSTRAINTS: ClassVar[dict[str, Any]] = {
        "batch_size": Interval(int, 1, 1 << 16),
        "learning_rate": Interval(float, 1e-7, 1.0),
        "max_epochs": Interval(int, 1, 10_000),
        "patience": Interval(int, 1, 10_000),
        "validation_fraction": Interval(float, 0.05, 0.5),
        "device": Options(("auto", "cpu", "cuda")),
        "windows_per_epoch": EpochWindows(),
    }
    _parameter_constraints = TRAINING_CONSTRAINTS

    def __init__(  # noqa: PLR0913 (hyperparameters: get_params reads one keyword each; subclasses pass them on by position)
        self,
        batch_size=64,
        learning_rate=1e-3,
        max_epochs=30,
        patience=5,
        validation_fraction=0.2,
        device="auto",
        windows_per_epoch=WINDOWS_PER_EPOCH,
    ):
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.max_epochs = max_epochs
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.device = device
        self.windows_per_epoch = windows_per_epoch

    @classmethod
    def benchmark(cls, length: int, seconds: float, seed: int = 0) -> Any:
        """Training and batched inference against the same network in a plain hand-written torch
        loop, timed in the same run (:func:`slipbench.torch.bench.torch_targets`); None where
        torch is missing (``slipbench bench`` lists the detector as unavailable)."""
        if importlib.util.find_spec("torch") is None:
            return None
        from slipbench.torch.bench import torch_targets

        return torch_targets(cls, length, seconds, seed)

    def build(self, window_length: int, n_channels: int) -> Any:
        """The network: windows (batch, n_channels, window_length) -> logits (batch,);
        ``n_channels`` is 1 for univariate windows."""
        raise NotImplementedError(
            f"{type(self).__name__} must implement build(window_length, n_channels)"
        )

    # -- what the base class calls
    def validate_params(self) -> None:
        super().validate_params()
        if importlib.util.find_spec("torch") is None:
            raise UsageError(
                f"{type(self).__name__} runs on torch, which is not installed: {INSTALL_HINT}"
            )
        if self.device == "cuda":
            import torch

            if not torch.cuda.is_available():
                raise UsageError(
                    f"The 'device' parameter of {type(self).__name__} is 'cuda' but torch sees no "
                    "CUDA device here; use 'cpu' or 'auto'"
                )

    def _fit(
        self, x: np.ndarray, y: np.ndarray, seed: int, groups: np.ndarray | None = None
    ) -> None:
        import torch

        if x.ndim == 3:  # each channel its own scale
            self.mean_ = x.mean(axis=(0, 1), dtype=np.float64)
            self.std_ = np.maximum(x.std(axis=(0, 1), dtype=np.float64), 1e-12)
        else:
            self.mean_, self.std_ = float(x.mean()), float(max(x.std(), 1e-12))
        share = min(self.validation_fraction, MAX_VALIDATION / len(y))
        train, val, self.validation_by_ = _validation_split(
            y, groups, share, rng_for(seed, "torch-validation")
        )
        self.device_, self.device_why_ = devices.choose(
            self.device, self._timing_key(), self._step_seconds
        )
        # one forked RNG for the whole fit: weights and dropout draw from the seed, not from
        # the caller's torch RNG (which stays as it was)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed_int(seed, "torch-init"))
            fit = self._train(x, y, train, val, rng_for(seed, "torch-batches"))
        self.epochs_, self.best_epoch_, self.validation_loss_ = fit.epochs, fit.best_epoch, fit.loss
        self.validation_y_, self.validation_scores_ = y[val], fit.scores
        self.state_names_ = tuple(fit.state)
        for i, value in enumerate(fit.state.values()):
            self.__dict__[f"state_{i}_"] = value
        self._net = None  # rebuilt from the kept state on first use

    def _train(
        self,
        x: np.ndarray,
        y: np.ndarray,
        train: np.ndarray,
        val: np.ndarray,
        order_rng: np.random.Generator,
    ) -> _Fit:
        """Epochs of Adam until the validation loss stops falling: the best epoch's state,
        loss and validation scores, and the epochs run."""
        import torch
        import torch.nn.functional as F

        device = torch.device(self.device_)
        model = self._module().to(device)
        xt = torch.from_numpy(self._standardized(x)).to(device)
        yt = torch.from_numpy(y.astype(np.float32)).to(device)
        optimizer = torch.optim.Adam(model.parameters(), lr=self.learning_rate)
        loss_fn = torch.nn.BCEWithLogitsLoss()
        draws = _Draws(train, order_rng)
        best, stale = _Fit(_state(model), np.inf, np.full(len(val), 0.5), 0), 0
        for epoch in range(1, self.max_epochs + 1):
            model.train()
            order = torch.from_numpy(draws.take(self.windows_per_epoch or len(train))).to(device)
            for start in range(0, len(order), self.batch_size):
                batch = order[start : start + self.batch_size]
                optimizer.zero_grad()
                loss_fn(_logits(model, xt[batch]), yt[batch]).backward()
                optimizer.step()
            logits = _all_logits(model.eval(), xt, val)
            loss = float(F.binary_cross_entropy_with_logits(logits, yt[val].double()))
            self.report_progress(epoch, self.max_epochs, loss=loss)
            if loss < best.loss - 1e-6:
                best, stale = _Fit(_state(model), loss, _probabilities(logits), epoch), 0
            else:
                stale += 1
                if stale >= self.patience:
                    break
        best.epochs = epoch
        return best

    def _predict_proba(self, x: np.ndarray) -> np.ndarray:
        import torch

        net = self._network()
        device = next(net.parameters(), torch.empty(0)).device
        threads = torch.get_num_threads()
        few = len(x) <= FEW_WINDOWS and device.type == "cpu" and threads > 1
        if few:
            torch.set_num_threads(1)
        try:
            xt = torch.from_numpy(self._standardized(x)).to(device)
            return _probabilities(_all_logits(net, xt))
        finally:
            if few:
                torch.set_num_threads(threads)

    def fitted_choices(self) -> dict[str, Any]:
        return {
            "epochs": int(self.epochs_),
            "best_epoch": int(self.best_epoch_),
            "windows_per_epoch": self.windows_per_epoch,
            "validation_loss": float(self.validation_loss_),
            "validation_by": str(self.validation_by_),
            "validation_windows": len(self.validation_y_),
            "device": str(self.device_),
            "device_why": str(self.device_why_),
        }

    # -- helpers
    def _timing_key(self) -> dict[str, Any]:
        """What a step's time depends on, besides torch and the GPU (:func:`devices.choose`)."""
        import torch

        cls = type(self)
        params = {k: v for k, v in self.get_params().items() if k != "device"}
        return {
            "detector": f"{cls.__module__}:{cls.__qualname__}",
            "params": params,
            "window_length": self.window_length_,
            "n_channels": self.n_channels_,
            "cpu_threads": torch.get_num_threads(),
        }

    def _step_seconds(self, device: str) -> float:
        """Seconds per training step of this network on batches of ``batch_size`` random
        windows on ``device``, the best of :data:`devices.STEPS` after as many warm-up steps."""
        import time

        import torch

        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(0)
            model = self._module().to(device)
            shape = (self.batch_size, max(1, self.n_channels_), self.window_length_)
            x = torch.randn(shape, device=device)
        y = (torch.arange(self.batch_size, device=device) % 2).float()
        optimizer = torch.optim.Adam(model.parameters(), lr=self.learning_rate)
        loss_fn = torch.nn.BCEWithLogitsLoss()
        best = np.inf
        for i in range(2 * devices.STEPS):
            t0 = time.perf_counter()
            optimizer.zero_grad()
            loss_fn(_logits(model, x), y).backward()
            optimizer.step()
            if device == "cuda":
                torch.cuda.synchronize()
            if i >= devices.STEPS:
                best = min(best, time.perf_counter() - t0)
        return float(best)

    def _standardized(self, x: np.ndarray) -> np.ndarray:
        """Windows standardized, in the network's layout (n, channels, window)."""
        z = ((x - self.mean_) / self.std_).astype(np.float32)
        return z[:, None, :] if z.ndim == 2 else np.ascontiguousarray(z.transpose(0, 2, 1))

    def _module(self) -> Any:
        """A new network for the fitted window length and channels, checked to be a Module."""
        import torch

        net = self.build(self.window_length_, max(1, self.n_channels_))
        if not isinstance(net, torch.nn.Module):
            raise UsageError(
                f"{type(self).__name__}.build returned a {type(net).__name__}, not a torch.nn.Module"
            )
        return net

    def _network(self) -> Any:
        """The fitted network: built once from the kept state (after ``fit`` or ``load``)."""
        import torch

        if getattr(self, "_net", None) is None:
            with torch.random.fork_rng(devices=[]):  # its initial weights are overwritten
                net = self._module()
            names = list(self.state_names_)
            state = {
                n: torch.from_numpy(np.asarray(self.__dict__[f"state_{i}_"]))
                for i, n in enumerate(names)
            }
            net.load_state_dict(state)
            self._net = net.to(self._scoring_device()).eval()
        return self._net

    def _scoring_device(self) -> str:
        """Where a fitted network scores: the device it was trained on, or the CPU where a
        model saved on a GPU machine is loaded without one (the same weights either way)."""
        import torch

        on_gpu = getattr(self, "device_", "cpu") == "cuda"
        return "cuda" if on_gpu and torch.cuda.is_available() else "cpu"


@dataclass
class _Fit:
    """The best epoch of a fit: its state, validation loss and scores, and the epochs run."""

    state: dict[str, np.ndarray]
    loss: float
    scores: np.ndarray
    best_epoch: int
    epochs: int = 0


class _Draws:
    """Windows for epochs: successive shuffles of ``rows``, taken in turn, so an epoch of any
    size sees every window once before any twice."""

    def __init__(self, rows: np.ndarray, rng: np.random.Generator):
        self.rows, self.rng = rows, rng
        self.left = rows[:0]

    def take(self, n: int) -> np.ndarray:
        parts, need = [], n
        while need > 0:
            if not len(self.left):
                self.left = self.rows[self.rng.permutation(len(self.rows))]
            parts.append(self.left[:need])
            self.left = self.left[need:]
            need -= len(parts[-1])
        return np.concatenate(parts)


def _all_logits(net: Any, xt: Any, rows: np.ndarray | None = None) -> Any:
    """Logits (float64, on the network's device) of the windows ``xt[rows]`` (all of them
    without ``rows``), :data:`SCORE_BATCH` at a time so memory stays bounded."""
    import torch

    n = len(xt) if rows is None else len(rows)
    out = []
    with torch.no_grad():
        for start in range(0, n, SCORE_BATCH):
            part = slice(start, start + SCORE_BATCH)
            batch = xt[part] if rows is None else xt[torch.from_numpy(rows[part]).to(xt.device)]
            out.append(_logits(net, batch).double())
    return torch.cat(out)


def _probabilities(logits: Any) -> np.ndarray:
    import torch

    return torch.sigmoid(logits).cpu().numpy()


def _logits(net: Any, x: Any) -> Any:
    out = net(x)
    return out.reshape(out.shape[0])


def _state(net: Any) -> dict[str, np.ndarray]:
    """A copy of the module's state dict as NumPy arrays (what ``save`` writes)."""
    return {k: v.detach().cpu().numpy().copy() for k, v in net.state_dict().items()}


def _validation_split(
    y: np.ndarray, groups: np.ndarray | None, fraction: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, str]:
    """(training windows, validation windows, "trial" | "window"): whole trials drawn at random
    until they hold ``fraction`` of the windows, with both classes on both sides; by window
    (stratified by class) where the trials cannot give that (no trials, or too few)."""
    n = len(y)
    if groups is not None:
        trials = np.unique(groups)
        picked: list = []
        count = 0
        for t in rng.permutation(trials):
            if count >= fraction * n:
                break
            picked.append(t)
            count += int((groups == t).sum())
        val_mask = np.isin(groups, picked)
        if all(len(np.unique(y[m])) == 2 for m in (val_mask, ~val_mask)):
            return np.flatnonzero(~val_mask), np.flatnonzero(val_mask), "trial"
    val = np.concatenate(
        [
            rng.choice(
                np.flatnonzero(y == c), max(1, round(fraction * (y == c).sum())), replace=False
            )
            for c in (0, 1)
        ]
    )
    train = np.setdiff1d(np.arange(n), val)
    if len(np.unique(y[train])) < 2:
        raise UsageError(
            "too few windows of a class to keep a validation part; lower validation_fraction"
        )
    return train, np.sort(val), "window"
