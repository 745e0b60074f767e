"""The conformance suite over every registered plugin, one test item per check, and the suite
catching broken detectors and protocols."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from slipbench.base import BaseDetector
from slipbench.engine.registry import detectors, protocols
from slipbench.protocol import BaseProtocol, Cell, Layout, Part, Presentation, sensor_pairs
from slipbench.protocols.material_holdout import MaterialHoldout
from slipbench.testing import check_detector, check_protocol, parametrize_with_checks


@parametrize_with_checks(
    [detectors.get(n)() for n in detectors.names()]
    + [protocols.get(n)() for n in protocols.names()]
)
def test_registered_plugin_conforms(plugin, check):
    registry = detectors if isinstance(plugin, BaseDetector) else protocols
    status = registry.status(registry.id_of(type(plugin)))
    if status.state != "ok":  # an optional dependency not installed here (minirocket: aeon)
        pytest.skip(f"{status.state}: {status.detail}")
    check(plugin)


class _Nondeterministic(BaseDetector):
    name = "nondeterministic"

    def __init__(self, factor=1.0):
        self.factor = factor

    def _fit(self, x, y, seed):
        self.cut_ = float(np.random.default_rng().normal())  # ignores the seed

    def _predict_proba(self, x):
        return np.clip(x.mean(axis=1) * self.factor - self.cut_ + 0.5, 0, 1)


class _Renamer(_Nondeterministic):
    def __init__(self, factor=1.0):
        self.factor = factor * 2  # stores a parameter changed

    def _fit(self, x, y, seed):
        self.cut_ = 0.0


class _Unsaveable(_Renamer):
    def __init__(self, factor=1.0):
        self.factor = factor

    def _fit(self, x, y, seed):
        self.cut_, self.model_ = 0.0, object()


class _ChannelBlind(_Renamer):
    """Declares channels but scores each channel, not each window."""

    inputs = ("univariate", "channels")

    def __init__(self, factor=1.0):
        self.factor = factor


class _UnknownInput(_ChannelBlind):
    inputs = ("univariate", "taxels")


class _FirstChannel(_ChannelBlind):
    """Declares channels only and reads a window's first channel."""

    inputs = ("channels",)

    def _predict_proba(self, x):
        return super()._predict_proba(x[:, :, 0])


class _OwnStreamer(_FirstChannel):
    """Brings a stream that scores univariate windows: wrong on channels."""

    def _streamer(self, hop, threshold):
        from slipbench.base import Streamer

        class Flat(Streamer):
            def _push(self, x, n):
                return np.full(n, 0.5)

        return Flat(self, hop, threshold)


@pytest.mark.parametrize(
    "cls, words",
    [
        (_Nondeterministic, "same scores"),
        (_Renamer, "clone must keep"),
        (_Unsaveable, "cannot save"),
        (_ChannelBlind, r"scores of shape \(37, 3\) for 37 windows"),
        (_UnknownInput, "inputs must be a tuple of distinct kinds"),
        (_OwnStreamer, "stream vs predict_proba"),
    ],
)
def test_suite_catches_broken_detectors(cls, words):
    with pytest.raises((AssertionError, Exception), match=words):
        check_detector(cls())


class _Constant(BaseDetector):
    def _fit(self, x, y, seed):
        self.level_ = 0.5

    def _predict_proba(self, x):
        return np.full(len(x), self.level_)


class _NoInit(BaseDetector):
    """A detector without __init__: no parameters, and get_params, clone and repr still work."""

    def _fit(self, x, y, seed):
        self.cut_ = float(np.median(np.abs(x).mean(axis=1)))

    def _predict_proba(self, x):
        return (np.abs(x).mean(axis=1) > self.cut_).astype(float)


def test_checks_run_on_each_declared_input_and_a_univariate_one_is_checked_for_refusing_channels():
    from slipbench.testing import detector_checks

    names = [name for name, _ in detector_checks(_ChannelBlind())]
    assert "check_fit_predict" in names and "check_fit_predict-channels" in names
    assert "check_streaming" in names and "check_streaming-channels" in names
    only = [name for name, _ in detector_checks(_FirstChannel())]
    assert "check_fit_predict-channels" in only and "check_fit_predict" not in only
    assert not any(n.endswith("-channels") for n, _ in detector_checks(_NoInit()))
    check_detector(_FirstChannel())  # a channels-only detector passes on channels alone

    class Lenient(_NoInit):
        """Claims univariate only but lets windows of channels through."""

        def _check_x(self, x):
            return np.asarray(x, np.float32)

    with pytest.raises(AssertionError, match="fit on 'channels' windows, which the detector"):
        check_detector(Lenient())


def test_suite_catches_a_detector_that_ignores_its_input():
    with pytest.raises(AssertionError, match="ignores its input"):
        check_detector(_Constant())


def test_a_detector_without_init_conforms():
    assert _NoInit().get_params() == {} and repr(_NoInit()) == "_NoInit()"
    check_detector(_NoInit())


class _Leaky(BaseProtocol):
    """Claims to hold out each material but trains on it."""

    layout = Layout(("sensor_type", "sensor_instance"), "material", pair="training")

    def cells(self, recordings):
        for sensor in sensor_pairs(recordings):
            for material in ("aluminum", "PVC"):
                test = Part((sensor,), "test", (("material", "==", material),))
                yield Cell(
                    {
                        "sensor_type": sensor[0],
                        "sensor_instance": sensor[1],
                        "material": material,
                        "training": "without",
                    },
                    Part((sensor,), "train", (("material", "==", material),)),
                    test,
                    50,
                )


class _Unlaid(_Leaky):
    """Its layout reads a column its cells lack."""

    layout = Layout(("sensor_type", "sensor_instance"), "window")

    def cells(self, recordings):
        for sensor in sensor_pairs(recordings):
            yield Cell(
                {"sensor_type": sensor[0], "sensor_instance": sensor[1]},
                Part((sensor,), "train"),
                Part((sensor,), "test"),
                50,
            )


class _Unfiltered(MaterialHoldout):
    """The most common holdout bug: its "without" cells forget their filter entirely and train
    on every material, the held-out one too."""

    def cells(self, recordings):
        for cell in super().cells(recordings):
            yield dataclasses.replace(cell, train=Part(cell.train.sensors, "train"))


class _UnfilteredUnpaired(MaterialHoldout):
    """The same bug in a protocol whose layout names no pair column: its two cells per
    material differ in an undeclared "model" column and train alike."""

    layout = Layout(("sensor_type", "sensor_instance"), "material")
    presentation = None  # no pair to draw with and without

    def cells(self, recordings):
        for cell in super().cells(recordings):
            key = {k: v for k, v in cell.key.items() if k != "training"}
            yield dataclasses.replace(
                cell,
                key={**key, "model": cell.key["training"]},
                train=Part(cell.train.sensors, "train"),
            )


@pytest.mark.parametrize(
    "protocol, words",
    [
        (_Leaky(), "trains on .* recordings with that value"),
        (
            _Unfiltered(),
            "is the 'without' cell of material == .* but trains on .* its training part needs the filter",
        ),
        (_UnfilteredUnpaired(), "train on the same windows: the 'without' one needs the filter"),
        (_Unlaid(), "lacks the layout's columns \\['window'\\]"),
    ],
)
def test_suite_catches_broken_protocols(protocol, words):
    with pytest.raises(AssertionError, match=words):
        check_protocol(protocol)


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda: Part((("Nano17", "index"),), "validation"), "Part.side must be one of"),
        (
            lambda: Part((("Nano17", "index"),), "train", (("material", "<", "PVC"),)),
            "operator one of",
        ),
        (
            lambda: Cell({"w": 1}, Part((("a", "b"),), "test"), Part((("a", "b"),), "test"), 50),
            "trains on the train side",
        ),
        (
            lambda: Cell(
                {"w": np.ones(2)}, Part((("a", "b"),), "train"), Part((("a", "b"),), "test"), 50
            ),
            "plain",
        ),
        (lambda: Presentation("x", figure="pie"), "Presentation.figure must be one of"),
        (lambda: Layout(("a",), ""), "Layout.column must name"),
    ],
)
def test_malformed_parts_cells_and_layouts_are_refused(make, words):
    with pytest.raises(ValueError, match=words):
        make()


def test_cell_keys_hold_plain_values():
    cell = Cell(
        {"speed_mm_s": np.float64(25.0), "n": np.int64(3)},
        Part((("a", "b"),), "train"),
        Part((("a", "b"),), "test"),
        50,
    )
    assert type(cell.key["speed_mm_s"]) is float and type(cell.key["n"]) is int
    assert cell.name == '{"n": 3, "speed_mm_s": 25.0}'
