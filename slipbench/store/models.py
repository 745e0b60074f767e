"""Saved models that prove themselves before they are reused.

A fitted model is kept as ``models/<model key>.npz`` (:meth:`~slipbench.base.BaseDetector.save`)
beside ``<model key>.npz.json``, its proof: the model key it was fitted for, its training cost
(which reused cells report) and a SHA-256 over the key, the cost and the model file's bytes.
The proof is written last, so it also marks the model complete. A model whose proof is missing,
unreadable, made for another key, or does not match its bytes is refused (:class:`Unproved`,
naming the file and why) and the caller fits it again: a tampered or damaged file is never
reused, and never blamed on the detector.
"""

from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path
from typing import Any

from slipbench.atomic import write_text_atomic

FORMAT = "slipbench-model-proof-1"


class Unproved(Exception):
    """A saved model that cannot be reused; the message names its file and why."""


class _Named(io.BytesIO):
    """Bytes read from a file, named as that file in the messages of ``load``."""

    def __init__(self, data: bytes, path: Path) -> None:
        super().__init__(data)
        self._path = path

    def __str__(self) -> str:
        return str(self._path)


def proof_path(path: Path) -> Path:
    """Where the proof of the model at ``path`` is kept."""
    return Path(f"{path}.json")


def _digest(key: str, cost: Any, data: bytes) -> str:
    head = json.dumps({"format": FORMAT, "key": key, "cost": cost}, sort_keys=True).encode()
    return hashlib.sha256(head + b"\0" + data).hexdigest()


def keep(detector: Any, path: Path, cost: dict[str, Any]) -> None:
    """Save ``detector`` at ``path`` (its model key is the file's stem), then its proof.
    Raises what ``save`` raises for state that cannot be saved safely (a UsageError)."""
    detector.save(path)
    key = path.stem
    proof = {"format": FORMAT, "key": key, "cost": cost}
    proof["digest"] = _digest(key, cost, path.read_bytes())
    write_text_atomic(proof_path(path), json.dumps(proof, sort_keys=True))


def reuse(cls: Any, path: Path) -> tuple[Any, dict[str, Any]] | None:
    """The model saved at ``path`` (loaded by ``cls.load``) and its cost, once its proof holds;
    None where none was saved. Raises :class:`Unproved` for one that fails its proof."""
    proof = proof_path(path)
    if not proof.exists():
        return None
    try:
        record = json.loads(proof.read_text(encoding="utf-8"))
        data = path.read_bytes()
    except (OSError, ValueError) as exc:  # UnicodeDecodeError is a ValueError
        raise Unproved(f"saved model {path} cannot be read with its proof: {exc}") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise Unproved(f"saved model {path} carries no digest (written by an older slipbench)")
    key = path.stem
    if record.get("key") != key:
        raise Unproved(
            f"saved model {path} was fitted for model key {record.get('key')!r}, not {key!r}"
        )
    cost = record.get("cost")
    if not isinstance(cost, dict) or record.get("digest") != _digest(key, cost, data):
        raise Unproved(f"saved model {path} does not match its digest (changed since it was saved)")
    try:
        detector = cls.load(_Named(data, path))  # the bytes proved, not the file again
    except Exception as exc:  # noqa: BLE001  # proved bytes another version cannot read
        raise Unproved(f"saved model {path} cannot be loaded: {exc}") from None
    return detector, cost
