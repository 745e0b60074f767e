"""The conformance suite for plugins: ``check_detector(detector)`` and
``check_protocol(protocol)`` run every check and raise AssertionError naming the first that
fails; ``parametrize_with_checks([...])`` makes each check one pytest item. A third-party
plugin runs them in its own tests::

    from slipbench.testing import parametrize_with_checks

    @parametrize_with_checks([MyDetector(), MyProtocol()])
    def test_conformance(plugin, check):
        check(plugin)

A detector class may declare ``check_params``: hyperparameters that make these checks fast (few
epochs, few kernels); they are applied to a clone, never to the detector passed in. The checks
that fit run once per input kind the detector declares (its ``inputs``): on univariate windows
(n, window) and on windows of ``CHANNELS`` channels (n, window, CHANNELS), the latter named
``<Class>-<check>-channels``.
"""

from __future__ import annotations

import functools
import io
import json
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from slipbench.base import INPUT_SHAPES, BaseDetector, NotFittedError, clone, stream_scores
from slipbench.data.format import Dataset
from slipbench.data.read import read_dataset
from slipbench.data.toy import toy_windows
from slipbench.errors import UsageError
from slipbench.protocol import BaseProtocol, Cell, Layout
from slipbench.seeding import rng_for

LENGTHS = (5, 50, 200)
CHANNELS = 3  # channels of the toy windows of channels: not 1, and no window length


def toy_channel_windows(
    n: int, length: int, channels: int = CHANNELS, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Balanced windows of channels (n, length, channels) float32 and labels (n,): every
    channel is noise of its own scale; in slip windows the first carries a 60 Hz burst (at 1 kHz)
    and the second more noise, as one electrode or axis would; the others carry nothing."""
    rng = rng_for(seed, "toy-channels")
    y = np.arange(n) % 2
    x = rng.normal(0, 1, (n, length, channels)) * (1.0 + np.arange(channels) / 2)
    t = np.arange(length) / 1000.0
    burst = 3 * np.sin(2 * np.pi * 60 * t + rng.uniform(0, 2 * np.pi, (n, 1)))
    x[:, :, 0] += y[:, None] * burst
    if channels > 1:
        x[:, :, 1] *= np.where(y, 2.0, 1.0)[:, None]
    return x.astype(np.float32), y


def toy(kind: str, n: int, length: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Toy windows of an input kind: ``toy_windows`` for "univariate", ``toy_channel_windows``
    for "channels"."""
    if kind not in INPUT_SHAPES:
        raise ValueError(f"no input kind {kind!r}; known: {', '.join(INPUT_SHAPES)}")
    return (toy_windows if kind == "univariate" else toy_channel_windows)(n, length, seed=seed)


def _raises(kind: type[Exception], words: str, call, what: str) -> None:
    try:
        call()
    except kind as exc:
        assert words.lower() in str(exc).lower(), (
            f"{what}: the error should mention {words!r}, got: {exc}"
        )
        return
    except Exception as exc:  # noqa: BLE001 - the wrong kind of error is the failure reported
        raise AssertionError(
            f"{what}: expected {kind.__name__}, got {type(exc).__name__}: {exc}"
        ) from exc
    raise AssertionError(f"{what}: expected {kind.__name__}, nothing was raised")


def check_params_protocol(detector: BaseDetector) -> None:
    """__init__ stores parameters as given; get_params/set_params/clone round-trip."""
    params = detector.get_params()
    twin = clone(detector)
    assert type(twin) is type(detector) and twin.get_params() == params, (
        "clone must keep every parameter"
    )
    assert not any(k.endswith("_") for k in vars(twin)), "a new detector must hold no fitted state"
    assert twin.set_params(**params) is twin and twin.get_params() == params, (
        "set_params(**get_params()) must be a no-op"
    )
    _raises(
        UsageError,
        "no parameter",
        lambda: twin.set_params(no_such_parameter=1),
        "set_params with an unknown name",
    )


def check_fit_predict(detector: BaseDetector, kind: str = "univariate") -> None:
    """Shapes, ranges and determinism for windows of 5 to 200 samples; parameters untouched by
    fit; windows of another length (or channel count) refused."""
    channels = CHANNELS if kind == "channels" else 0
    for length in LENGTHS:
        x, y = toy(kind, 120, length)
        before = detector.get_params()
        a = clone(detector)
        assert a.fit(x, y, sampling_rate=1000.0, seed=3) is a, "fit must return the detector"
        assert a.get_params() == before, f"fit must not change parameters (window {length})"
        assert a.window_length_ == length and a.sampling_rate_ == 1000.0
        assert a.n_channels_ == channels, (
            f"n_channels_ must be {channels} after fitting on {kind} windows, got {a.n_channels_}"
        )
        proba, pred = a.predict_proba(x[:37]), a.predict(x[:37])
        assert proba.shape == (37,) and pred.shape == (37,), (
            f"window {length}: one score per window, got {proba.shape}"
        )
        assert np.all((proba >= 0) & (proba <= 1)), f"window {length}: probabilities outside [0, 1]"
        assert set(np.unique(pred)) <= {0, 1}, f"window {length}: predictions must be 0 or 1"
        again = clone(detector).fit(x, y, sampling_rate=1000.0, seed=3).predict_proba(x[:37])
        assert np.array_equal(proba, again), (
            f"window {length}: two fits with one seed must give the same scores"
        )
        other = x[:, :-1] if length > 5 else np.concatenate([x, x], axis=1)
        _raises(
            UsageError,
            f"{length}",
            functools.partial(a.predict_proba, other),
            "predict on another window length",
        )
        if channels:
            _raises(
                UsageError,
                f"{channels} channels",
                functools.partial(a.predict_proba, x[:, :, :-1]),
                "predict on another number of channels",
            )


def check_refusals(detector: BaseDetector, kind: str = "univariate") -> None:
    """NaN input, single-class training data and predicting before fit are refused clearly."""
    x, y = toy(kind, 40, 20)
    bad = x.copy()
    bad[3, 7] = np.nan
    _raises(UsageError, "NaN", lambda: clone(detector).fit(bad, y), "fit on windows with NaN")
    _raises(
        UsageError,
        "only class",
        lambda: clone(detector).fit(x, np.zeros_like(y)),
        "fit on one class",
    )
    _raises(
        NotFittedError, "not fitted", lambda: clone(detector).predict_proba(x), "predict before fit"
    )
    fitted = clone(detector).fit(x, y, seed=0)
    _raises(UsageError, "NaN", lambda: fitted.predict_proba(bad), "predict on windows with NaN")


def check_save_load(detector: BaseDetector, kind: str = "univariate") -> None:
    """A fitted detector saves to a pickle-free file and loads back with the same scores."""
    x, y = toy(kind, 60, 50)
    fitted = clone(detector).fit(x, y, seed=1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "detector.npz"
        fitted.save(path)
        with zipfile.ZipFile(path) as zf:  # every member must load without pickle
            for member in zf.namelist():
                np.lib.format.read_array(io.BytesIO(zf.read(member)), allow_pickle=False)
        for loader in (type(detector).load, BaseDetector.load):
            loaded = loader(path)
            assert (
                type(loaded).__name__ == type(detector).__name__
                and loaded.get_params() == fitted.get_params()
                and loaded.n_channels_ == fitted.n_channels_
            )
            assert np.array_equal(loaded.predict_proba(x), fitted.predict_proba(x)), (
                "a loaded detector must score as saved"
            )


def check_uses_input(detector: BaseDetector, kind: str = "univariate") -> None:
    """Scores depend on the windows: a detector that ignores its input scores every window alike."""
    x, y = toy(kind, 120, 50)
    scores = clone(detector).fit(x, y, seed=0).predict_proba(x)
    assert np.ptp(scores) > 0, "every window got the same score: the detector ignores its input"


def check_streaming(detector: BaseDetector, kind: str = "univariate") -> None:
    """A stream gives ``predict_proba``'s scores of the windows it completes, at hops 1, 7 and the
    window, whether the recording is pushed whole or in pieces of 0 to 40 samples."""
    window = 30
    x, y = toy(kind, 120, window)
    fitted = clone(detector).fit(x, y, sampling_rate=1000.0, seed=0)
    signal = toy(kind, 50, window, seed=1)[0].reshape(50 * window, *x.shape[2:])  # a recording
    cuts = np.cumsum(rng_for(0, "toy", "pieces").integers(0, 41, len(signal)))
    pieces = np.split(signal, cuts[cuts < len(signal)])
    for hop in (1, 7, window):
        ends, scores = stream_scores(fitted, signal, hop)
        assert np.array_equal(ends, np.arange(window - 1, len(signal), hop)), (
            f"hop {hop}: scores must fall on samples window - 1 + k hop"
        )
        windows = np.lib.stride_tricks.sliding_window_view(signal, window, axis=0)[
            ends - window + 1
        ]
        batch = fitted.predict_proba(np.moveaxis(windows, -1, 1))  # (n, window[, channels])
        np.testing.assert_allclose(
            scores, batch, rtol=0, atol=1e-6, err_msg=f"hop {hop}: stream vs predict_proba"
        )
        # pieces change the batches predict_proba sees: wavelet-svm's float32 features score a
        # window 2.6e-6 apart alone and in a batch
        stream = fitted.streamer(hop)
        pushed = np.concatenate([stream.push(piece)[0] for piece in pieces])
        np.testing.assert_allclose(
            pushed, scores, rtol=0, atol=1e-5, err_msg=f"hop {hop}: pieces vs one push"
        )


def check_input_kinds(detector: BaseDetector) -> None:
    """``inputs`` declares known kinds; windows of an undeclared kind are refused by a UsageError
    naming their shape, and a detector fitted on one kind refuses the other."""
    inputs = type(detector).inputs
    assert (
        isinstance(inputs, tuple)
        and inputs
        and set(inputs) <= set(INPUT_SHAPES)
        and len(set(inputs)) == len(inputs)
    ), f"inputs must be a tuple of distinct kinds among {tuple(INPUT_SHAPES)}, got {inputs!r}"
    for kind in (k for k in INPUT_SHAPES if k not in inputs):
        x, y = toy(kind, 40, 20)
        _raises(
            UsageError,
            str(x.shape),
            functools.partial(clone(detector).fit, x, y),
            f"fit on {kind!r} windows, which the detector does not declare",
        )
    if len(inputs) > 1:
        (x, y), (other, _) = toy(inputs[0], 40, 20), toy(inputs[1], 40, 20)
        fitted = clone(detector).fit(x, y, seed=0)
        _raises(
            UsageError,
            "fitted on",
            lambda: fitted.predict_proba(other),
            f"predict on {inputs[1]!r} windows after fitting on {inputs[0]!r} windows",
        )


def _fast(detector: BaseDetector) -> BaseDetector:
    return clone(detector).set_params(**type(detector).check_params)


# checks run once per detector; then those run once per input kind the detector declares
DETECTOR_CHECKS: list[Callable[[BaseDetector], None]] = [check_params_protocol, check_input_kinds]
KIND_CHECKS: list[Callable[..., None]] = [
    check_fit_predict,
    check_refusals,
    check_uses_input,
    check_save_load,
    check_streaming,
]


def detector_checks(detector: BaseDetector) -> list[tuple[str, Callable[[BaseDetector], None]]]:
    """Every check of ``detector`` as (name, check): ``check_params_protocol``, then the rest,
    those that fit once per declared input kind (``<check>-channels`` on windows of channels)."""
    checks: list[tuple[str, Callable[[BaseDetector], None]]] = [
        (c.__name__, c) for c in DETECTOR_CHECKS
    ]
    for kind in (k for k in type(detector).inputs if k in INPUT_SHAPES):  # others: input_kinds
        suffix = "" if kind == "univariate" else f"-{kind}"
        checks += [(c.__name__ + suffix, functools.partial(c, kind=kind)) for c in KIND_CHECKS]
    return checks


def check_detector(detector: BaseDetector) -> None:
    """Run every conformance check on ``detector`` (its class's ``check_params`` applied)."""
    assert isinstance(detector, BaseDetector), f"{type(detector).__name__} is not a BaseDetector"
    for _, check in detector_checks(detector):
        check(detector if check is check_params_protocol else _fast(detector))


# ----------------------------------------------------------------------------- protocols
@functools.cache
def toy_dataset() -> Dataset:
    """A small simulated dataset (every sensor, material and speed; about 0.6 M samples), made
    once per process: what protocol checks plan their cells on."""
    from slipbench.data.synth import synthesize

    folder = Path(tempfile.mkdtemp(prefix="slipbench-check-"))
    return read_dataset(synthesize(folder / "toy", scale=0.01, seed=0))


def _cells(protocol: BaseProtocol, dataset: Dataset) -> tuple[list[Cell], pd.DataFrame]:
    recordings = dataset.recordings.copy()
    for name, values in protocol.columns(dataset.recordings).items():
        recordings[name] = values
    return list(protocol.cells(recordings)), recordings


def check_protocol_params(protocol: BaseProtocol, dataset: Dataset | None = None) -> None:
    """Options are keyword parameters (get_params/set_params round-trip), valid as given, and an
    unknown option is refused; the layout is a Layout."""
    params = protocol.get_params()
    twin = type(protocol)(**params)
    assert twin.get_params() == params, (
        "the protocol must store every option as given (get_params round trip)"
    )
    protocol.validate_params()
    _raises(
        UsageError,
        "no parameter",
        lambda: twin.set_params(no_such_option=1),
        "set_params with an unknown name",
    )
    _layout(protocol)


def _layout(protocol: BaseProtocol) -> Layout:
    assert isinstance(protocol.layout, Layout), (
        f"layout must be a slipbench.protocol.Layout, got {protocol.layout!r}"
    )
    return protocol.layout


def check_protocol_cells(protocol: BaseProtocol, dataset: Dataset | None = None) -> None:
    """Cells are well formed: Cell objects with unique keys holding every column the layout
    reads, on sensors the dataset has; and every cell that is not skipped has windows of both
    classes on both sides (or a reason, from the plan, why not)."""
    from slipbench.data.signals import Signals
    from slipbench.engine.plan import CellData

    dataset = dataset or toy_dataset()
    cells, recordings = _cells(protocol, dataset)
    assert cells, "the protocol made no cells on the check dataset"
    assert all(isinstance(c, Cell) for c in cells), (
        "cells() must yield slipbench.protocol.Cell objects"
    )
    names = [c.name for c in cells]
    assert len(set(names)) == len(names), (
        f"cell keys must be unique; repeated: {sorted({n for n in names if names.count(n) > 1})[:3]}"
    )
    wanted = set(_layout(protocol).keys)
    for cell in cells:
        assert wanted <= set(cell.key), (
            f"cell {cell.name} lacks the layout's columns {sorted(wanted - set(cell.key))}"
        )
    known = set(zip(recordings["sensor_type"], recordings["sensor_instance"]))
    for cell in cells:
        for part in (cell.train, cell.test):
            assert set(part.sensors) <= known, (
                f"cell {cell.name} uses sensors the dataset lacks: {set(part.sensors) - known}"
            )
            for column, _, _ in part.where:
                assert column in recordings, (
                    f"cell {cell.name} filters on {column!r}, which is no recording column"
                )
    signals = Signals.from_dataset(dataset)
    signals.recordings = recordings.reset_index(drop=True)
    data = CellData(signals, "paper", 0)
    ran = 0
    for cell in cells:
        if cell.skip:
            continue
        try:
            train, test = data.part(cell.train, cell.window), data.part(cell.test, cell.window)
        except UsageError:
            continue  # the plan skips such a cell with this reason
        ran += len(train) > 0 and len(test) > 0
    assert ran, "no cell of the protocol has windows to train and test on the check dataset"


def check_protocol_holdouts(protocol: BaseProtocol, dataset: Dataset | None = None) -> None:
    """Holdout cells never train on what they test: where a cell tests on ``column == value``
    and also filters its training windows on that column, no training recording has that value;
    and a "without" cell (``"without"`` in the layout's ``pair`` column) trains on no recording
    of the value it holds out (its ``holdout``, else what it tests on), so one that forgets its
    filter entirely (trains on everything, the held-out material too) fails; without a pair
    column, two cells of one ``holdout`` may not train and test alike."""
    cells, recordings = _cells(protocol, dataset or toy_dataset())
    _check_without_cells(protocol, cells, recordings)
    for cell in cells:
        train_columns = {c for c, _, _ in cell.train.where}
        trained = recordings[cell.train.mask(recordings)]
        for column, op, value in cell.test.where:
            if op == "==" and column in train_columns:
                leaked = trained[trained[column].eq(value)]
                assert leaked.empty, (
                    f"cell {cell.name} tests on {column} == {value!r} and trains on "
                    f"{len(leaked)} recordings with that value (e.g. {leaked['recording_id'].iloc[0]})"
                )


def _check_without_cells(
    protocol: BaseProtocol, cells: list[Cell], recordings: pd.DataFrame
) -> None:
    pair = _layout(protocol).pair
    for cell in cells:
        if pair and cell.key.get(pair) == "without":
            held = cell.holdout or next(
                ((c, v) for c, op, v in cell.test.where if op == "=="), None
            )
            assert held is not None, (
                f"cell {cell.name} is a 'without' cell ({pair} = 'without') but holds nothing "
                "out: give it holdout=(column, value), as holdout_cells does"
            )
            column, value = held
            assert column in recordings, (
                f"cell {cell.name} holds out {column} == {value!r}, which is no recording column"
            )
            trained = recordings[cell.train.mask(recordings)]
            leaked = trained[trained[column].eq(value)]
            assert leaked.empty, (
                f"cell {cell.name} is the 'without' cell of {column} == {value!r} but trains on "
                f"{len(leaked)} recordings with that value (e.g. {leaked['recording_id'].iloc[0]}): "
                f"its training part needs the filter ({column!r}, '!=', {value!r})"
            )
        elif cell.holdout is not None and not (pair and pair in cell.key):
            # no pair column to say which is which: two cells of one holdout that test alike
            # and train alike are one model twice, so the "without" one lost its filter
            twin = next(
                (
                    c
                    for c in cells
                    if c is not cell
                    and c.holdout == cell.holdout
                    and c.test == cell.test
                    and c.train == cell.train
                    and c.window == cell.window
                ),
                None,
            )
            assert twin is None, (
                f"cells {cell.name} and {twin.name} hold out {cell.holdout[0]} == "
                f"{cell.holdout[1]!r} and train on the same windows: the 'without' one needs the "
                f"filter ({cell.holdout[0]!r}, '!=', {cell.holdout[1]!r}) on its training part"
            )


def check_protocol_layout(protocol: BaseProtocol, dataset: Dataset | None = None) -> None:
    """The layout renders: fake results for every cell make a Markdown and a LaTeX table, and
    the figure the layout declares."""
    from slipbench.report.document import protocol_tables
    from slipbench.report.plots import figure
    from slipbench.report.render import to_latex, to_markdown

    layout = _layout(protocol)
    cells, _ = _cells(protocol, dataset or toy_dataset())
    rng = rng_for(0, "toy", "rows")
    rows = pd.DataFrame(
        [
            {
                **c.key,
                "cell": c.name,
                "protocol": "checked",
                "detector": "d",
                "split": "paper",
                "seed": 0,
                "status": "ok",
                "accuracy": a,
                "accuracy_lo": a - 0.05,
                "accuracy_hi": a + 0.05,
            }
            for c, a in zip(cells, rng.uniform(0.55, 0.95, len(cells)))
        ]
    )
    for metric in layout.metrics:  # a layout of several metrics shows each
        rows[metric] = rng.uniform(0.55, 0.95, len(rows))
        rows[f"{metric}_lo"], rows[f"{metric}_hi"] = rows[metric] - 0.05, rows[metric] + 0.05
    if layout.figure == "tradeoff":  # a streaming cell's threshold sweep
        rows["tradeoff"] = json.dumps(
            [
                {
                    "threshold": t,
                    "detection_rate": 1 - t,
                    "median_delay_ms": 20 + 100 * t,
                    "false_alarms_per_min": 10 * (1 - t),
                }
                for t in (0.1, 0.5, 0.9)
            ]
        )
    tables = protocol_tables(rows, layout, "checked", "d", intervals=True)
    assert tables, "the layout made no table"
    for _, table in tables:
        assert table.rows and table.columns, f"table {table.caption!r} has no rows or columns"
        assert to_markdown(table) and to_latex(table).count(r"\begin{tabular}") >= 1
    if layout.figure:
        import matplotlib.pyplot as plt

        fig = figure(rows, layout, "check", paper=False)
        assert fig is not None, f"the layout declares a {layout.figure!r} figure but none was drawn"
        plt.close(fig)


PROTOCOL_CHECKS: list[Callable[..., None]] = [
    check_protocol_params,
    check_protocol_cells,
    check_protocol_holdouts,
    check_protocol_layout,
]


def check_protocol(protocol: BaseProtocol, dataset: Dataset | None = None) -> None:
    """Run every conformance check on ``protocol``, planning its cells on ``dataset`` (default:
    a small simulated dataset)."""
    assert isinstance(protocol, BaseProtocol), f"{type(protocol).__name__} is not a BaseProtocol"
    for check in PROTOCOL_CHECKS:
        check(protocol, dataset)


def parametrize_with_checks(plugins: list) -> Callable:
    """A ``pytest.mark.parametrize`` decorator over (plugin, check): one test item per check of
    each detector or protocol, named ``<Class>-<check>``. The test calls ``check(plugin)``."""
    import pytest

    params = []
    checks: list[tuple[str, Callable[..., None], BaseDetector | BaseProtocol]]
    for plugin in plugins:
        if isinstance(plugin, BaseDetector):
            checks = [
                (name, check, plugin if check is check_params_protocol else _fast(plugin))
                for name, check in detector_checks(plugin)
            ]
        elif isinstance(plugin, BaseProtocol):
            checks = [(check.__name__, check, plugin) for check in PROTOCOL_CHECKS]
        else:
            raise TypeError(f"{plugin!r} is neither a BaseDetector nor a BaseProtocol")
        params += [
            pytest.param(obj, check, id=f"{type(plugin).__name__}-{name}")
            for name, check, obj in checks
        ]
    return pytest.mark.parametrize("plugin, check", params)
