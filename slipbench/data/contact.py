"""Tangential mechanics of a fingertip's contact, for the simulation (:mod:`slipbench.data.synth`).

A contact carries a shear ``Q`` under a normal load ``P`` without sliding as long as
``|Q| < mu_s P`` (the friction cone). Before that edge it slips partially: by Cattaneo and
Mindlin (Johnson, *Contact Mechanics*, 1985, section 7.2) the stick zone of a Hertz contact of
radius ``a`` shrinks to ``c = a (1 - |Q| / mu_s P)^(1/3)``, so an annulus at the edge slips while
the core sticks; at the edge of the cone the core vanishes and the contact breaks away (gross
slip). Mindlin and Deresiewicz add that a tangential increment smaller than ``mu_s`` times the
normal one slips nowhere: loads that grow in proportion inside the cone do not slip at all.
"""

from __future__ import annotations

import numpy as np


def slip_annulus(shear: np.ndarray, normal: np.ndarray, mu_static: float) -> np.ndarray:
    """Area fraction of the contact that slips, ``1 - (c/a)^2 = 1 - (1 - q)^(2/3)`` with
    ``q = |Q| / (mu_s P)`` (Cattaneo-Mindlin); 0 without load, 1 at the cone's edge.

    Parameters
    ----------
    shear, normal : (n,) tangential and normal load, in N.
    mu_static : the static friction coefficient.
    """
    cone = mu_static * np.maximum(normal, 1e-9)
    q = np.clip(np.abs(shear) / cone, 0.0, 1.0)
    return 1.0 - (1.0 - q) ** (2.0 / 3.0)


def annulus_travel(shear: np.ndarray, normal: np.ndarray, mu_static: float) -> np.ndarray:
    """How far the slip annulus has swept, sample by sample: the cumulative change of its area
    fraction (:func:`slip_annulus`, growing or receding), counted only where the tangential
    increment outpaces the cone's, ``|dQ| > mu_s |dP|`` (Mindlin-Deresiewicz: elsewhere the
    whole contact sticks). A simplification: the annulus has no memory of the loading path.

    Returns
    -------
    (n,) non-decreasing, 0 at the first sample; the edge slips where it rises.
    """
    area = slip_annulus(shear, normal, mu_static)
    outpaces = np.abs(np.diff(np.abs(shear))) > mu_static * np.abs(np.diff(normal))
    return np.r_[0.0, np.cumsum(np.abs(np.diff(area)) * outpaces)]


def breakaway(loading: np.ndarray, limit: np.ndarray, leg: np.ndarray) -> np.ndarray:
    """Whether the contact has broken away, per sample: from the first sample of each leg (a
    stretch of monotonic pull, ``leg`` its non-decreasing index) where the shear the pull puts
    on the contact (``loading``) reaches the static limit ``mu_s P`` (``limit``), to the leg's end.
    """
    reached = np.cumsum(loading >= limit)
    starts = np.r_[0, np.flatnonzero(np.diff(leg)) + 1]
    before = np.repeat(np.r_[0, reached[starts[1:] - 1]], np.diff(np.r_[starts, len(leg)]))
    return reached > before
