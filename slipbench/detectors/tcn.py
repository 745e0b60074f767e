"""A temporal convolutional network (after Bai, Kolter & Koltun, "An Empirical Evaluation of
Generic Convolutional and Recurrent Networks for Sequence Modeling", 2018): stacked causal
dilated 1-D convolutions with residual connections, dilation doubling per block so the receptive
field covers the window, the last time step's features to one logit. It reads the univariate
signal (one input channel) or the raw channels (one input channel each). On PyTorch, through
:class:`slipbench.torch.TorchDetector` (training, early stopping, saving, streaming)."""

from __future__ import annotations

from typing import Any

from slipbench.params import Interval, Options
from slipbench.torch import TorchDetector


class TCN(TorchDetector):
    """A temporal convolutional network on PyTorch (Bai et al. 2018): dilated causal convolutions.

    ``channels`` features per block, ``kernel_size`` taps per convolution, ``blocks`` residual
    blocks with dilations 1, 2, 4, ... (receptive field ``1 + 2 (kernel_size - 1)(2^blocks - 1)``
    samples: 29 by default); each window centered on its own mean when ``center`` (a level says
    which recording, not whether it slips), the last block's features pooled over time by their
    mean and spread (``pool="stats"``; ``"mean"``, or ``"last"``: the last step's). The training
    parameters are TorchDetector's, with batches of 64 at a learning rate of 1e-2 and at most 12
    epochs of 256 windows (patience 3): a cell's training is capped at 3,072 windows whatever its
    set, chosen by ``benchmarks/tcn_study.py`` (``docs/studies/tcn-study.md``) for learning where a
    logistic regression on per-channel features does, at a cost that fits the whole paper on two
    cores. Reads both inputs (TorchDetector's ``inputs``): the first block takes one input channel
    per channel of the windows (``channels`` is the blocks' width, not the input's)."""

    _parameter_constraints = {
        **TorchDetector.TRAINING_CONSTRAINTS,
        "channels": Interval(int, 1, 256),
        "kernel_size": Interval(int, 2, 16),
        "blocks": Interval(int, 1, 12),
        "dropout": Interval(float, 0.0, 0.9),
        "pool": Options(("stats", "mean", "last")),
        "center": Options((True, False)),
    }
    check_params = {"max_epochs": 2, "patience": 1, "channels": 4, "blocks": 2}

    def __init__(  # noqa: PLR0913 (hyperparameters: get_params reads one keyword each)
        self,
        channels=8,
        kernel_size=3,
        blocks=3,
        dropout=0.0,
        pool="stats",
        center=True,
        batch_size=64,
        learning_rate=1e-2,
        max_epochs=12,
        patience=3,
        validation_fraction=0.2,
        device="auto",
        windows_per_epoch=256,
    ):
        super().__init__(
            batch_size,
            learning_rate,
            max_epochs,
            patience,
            validation_fraction,
            device,
            windows_per_epoch,
        )
        self.channels = channels
        self.kernel_size = kernel_size
        self.blocks = blocks
        self.dropout = dropout
        self.pool = pool
        self.center = center

    def build(self, window_length: int, n_channels: int) -> Any:
        shape = (self.channels, self.kernel_size, self.blocks)
        return _network(n_channels, shape, self.dropout, self.pool, self.center)


def _network(
    n_inputs: int, shape: tuple[int, int, int], dropout: float, pool: str, center: bool
) -> Any:
    """``shape``: (channels, kernel_size, blocks)."""
    import torch
    from torch import nn

    channels, kernel_size, blocks = shape

    class Block(nn.Module):
        """Two causal dilated convolutions (left padding only) and a residual connection."""

        def __init__(self, c_in: int, dilation: int):
            super().__init__()
            pad = (kernel_size - 1) * dilation
            self.body = nn.Sequential(
                nn.ConstantPad1d((pad, 0), 0.0),
                nn.Conv1d(c_in, channels, kernel_size, dilation=dilation),
                nn.ReLU(),
                nn.Dropout(dropout),
                nn.ConstantPad1d((pad, 0), 0.0),
                nn.Conv1d(channels, channels, kernel_size, dilation=dilation),
                nn.ReLU(),
                nn.Dropout(dropout),
            )
            self.skip = nn.Conv1d(c_in, channels, 1) if c_in != channels else nn.Identity()

        def forward(self, x):
            return self.body(x) + self.skip(x)

    class Network(nn.Module):
        def __init__(self):
            super().__init__()
            self.blocks = nn.Sequential(
                *(Block(n_inputs if i == 0 else channels, 2**i) for i in range(blocks))
            )
            self.head = nn.Linear(2 * channels if pool == "stats" else channels, 1)

        def forward(self, x):  # (batch, n_inputs, window) -> (batch,)
            features = self.blocks(x - x.mean(-1, keepdim=True) if center else x)
            if pool == "last":
                pooled = features[:, :, -1]
            elif pool == "mean":
                pooled = features.mean(-1)
            else:
                pooled = torch.cat([features.mean(-1), features.std(-1)], 1)
            return self.head(pooled)[:, 0]

    return Network()
