"""Detectors written in PyTorch: :class:`TorchDetector` turns a ``torch.nn.Module`` into one.

A wing beside the contract: it imports the contract only, and plugins may import it. torch
itself is optional (``pip install 'slipbench[torch]'``): importing this package works without
it; a TorchDetector is listed as unavailable and refused with the install command.
"""

from slipbench.torch.detector import TorchDetector

__all__ = ["TorchDetector"]
