"""TorchDetector: any ``torch.nn.Module`` that maps a batch of windows to one logit per window,
made a slipbench detector.

What a plugin writes is the module (``build``) and its own parameters; this class owns the rest:

- *input*: univariate windows (n, window) or windows of channels (n, window, channels),
  standardized with the training side's mean and standard deviation (each channel's own), given
  to the network in torch's ``Conv1d`` layout (batch, channels, window), one channel for
  univariate windows;
- *training*: Adam on the binary cross-entropy of the logits, mini-batches of ``batch_size``,
  a validation part of whole trials (``validation_fraction`` of the training windows, every
  class on both sides; by window only where the windows come without their trials, and then
  ``fitted_choices`` says so), early stopping after ``patience`` epochs without a lower
  validation loss, the best epoch's weights kept;
- *determinism*: every random choice (initial weights, validation trials, batch order) is drawn
  from the seed inside a forked torch RNG, so a fit leaves the caller's torch RNG alone and the
  same seed gives the same model on the CPU;
- *device*: ``auto`` (a CUDA GPU when torch sees one), ``cpu`` or ``cuda``;
- *saving*: the state dict as plain arrays in the detector's ``.npz`` (never pickle), rebuilt
  with ``build`` on load;
- *scoring*: batched ``predict_proba``; streaming with the base class's stream (each completed
  window scored once).
"""

from __future__ import annotations

import importlib.util
from typing import Any, ClassVar

import numpy as np

from slipbench.base import BaseDetector
from slipbench.errors import UsageError
from slipbench.params import Interval, Options
from slipbench.seeding import rng_for, seed_int

INSTALL_HINT = "pip install 'slipbench[torch]'"
#: windows scored at once by predict_proba (bounded memory, whatever the batch size)
SCORE_BATCH = 4096
#: windows scored on one CPU thread at most: a stream's push scores one or a few, where torch's
#: thread pool costs more than it gives, and on a busy machine its threads wait for one another
#: (3 windows of tcn's check network: 122 ms on 2 threads of 2 busy cores, 1.6 ms on one)
FEW_WINDOWS = 16


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
    TRAINING_CONSTRAINTS: ClassVar[dict[str, Any]] = {
        "batch_size": Interval(int, 1, 1 << 16),
        "learning_rate": Interval(float, 1e-7, 1.0),
        "max_epochs": Interval(int, 1, 10_000),
        "patience": Interval(int, 1, 10_000),
        "validation_fraction": Interval(float, 0.05, 0.5),
        "device": Options(("auto", "cpu", "cuda")),
    }
    _parameter_constraints = TRAINING_CONSTRAINTS

    def __init__(
        self,
        batch_size=64,
        learning_rate=1e-3,
        max_epochs=30,
        patience=5,
        validation_fraction=0.2,
        device="auto",
    ):
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.max_epochs = max_epochs
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.device = device

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
        train, val, self.validation_by_ = _validation_split(
            y, groups, self.validation_fraction, rng_for(seed, "torch-validation")
        )
        # one forked RNG for the whole fit: weights and dropout draw from the seed, not from
        # the caller's torch RNG (which stays as it was)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed_int(seed, "torch-init"))
            epochs, best_loss, best_state = self._train(
                x, y, train, val, rng_for(seed, "torch-batches")
            )
        self.epochs_, self.validation_loss_ = epochs, best_loss
        self.state_names_ = tuple(best_state)
        for i, value in enumerate(best_state.values()):
            self.__dict__[f"state_{i}_"] = value
        self._net = None  # rebuilt from the kept state on first use

    def _train(
        self,
        x: np.ndarray,
        y: np.ndarray,
        train: np.ndarray,
        val: np.ndarray,
        order_rng: np.random.Generator,
    ) -> tuple[int, float, dict[str, np.ndarray]]:
        """Epochs of Adam until the validation loss stops falling: (epochs run, best loss,
        the best epoch's state)."""
        import torch

        device = self._device()
        model = self._module().to(device)
        xt = torch.from_numpy(self._standardized(x)).to(device)
        yt = torch.from_numpy(y.astype(np.float32)).to(device)
        vt = torch.from_numpy(val).to(device)
        optimizer = torch.optim.Adam(model.parameters(), lr=self.learning_rate)
        loss_fn = torch.nn.BCEWithLogitsLoss()
        best_loss, best_state, stale, epochs = np.inf, _state(model), 0, 0
        for _ in range(self.max_epochs):
            model.train()
            order = torch.from_numpy(train[order_rng.permutation(len(train))]).to(device)
            for start in range(0, len(order), self.batch_size):
                batch = order[start : start + self.batch_size]
                optimizer.zero_grad()
                loss_fn(_logits(model, xt[batch]), yt[batch]).backward()
                optimizer.step()
            epochs += 1
            model.eval()
            with torch.no_grad():
                loss = float(loss_fn(_logits(model, xt[vt]), yt[vt]))
            self.report_progress(epochs, self.max_epochs, loss=loss)
            if loss < best_loss - 1e-6:
                best_loss, best_state, stale = loss, _state(model), 0
            else:
                stale += 1
                if stale >= self.patience:
                    break
        return epochs, best_loss, best_state

    def _predict_proba(self, x: np.ndarray) -> np.ndarray:
        import torch

        net, device = self._network(), self._device()
        xs = self._standardized(x)
        out = []
        threads = torch.get_num_threads()
        few = len(xs) <= FEW_WINDOWS and device.type == "cpu" and threads > 1
        if few:
            torch.set_num_threads(1)
        try:
            with torch.no_grad():
                for start in range(0, len(xs), SCORE_BATCH):
                    batch = torch.from_numpy(xs[start : start + SCORE_BATCH]).to(device)
                    out.append(torch.sigmoid(_logits(net, batch)).double().cpu().numpy())
        finally:
            if few:
                torch.set_num_threads(threads)
        return np.concatenate(out)

    def fitted_choices(self) -> dict[str, Any]:
        return {
            "epochs": int(self.epochs_),
            "validation_loss": float(self.validation_loss_),
            "validation_by": str(self.validation_by_),
        }

    # -- helpers
    def _device(self) -> Any:
        import torch

        if self.device == "cuda" or (self.device == "auto" and torch.cuda.is_available()):
            return torch.device("cuda")
        return torch.device("cpu")

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
            self._net = net.to(self._device()).eval()
        return self._net


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
