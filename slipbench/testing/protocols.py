"""The conformance checks of a protocol: its parameters, the cells it plans on a small
simulated dataset, its holdouts, and the tables and figure its layout gives."""

from __future__ import annotations

import json
from collections.abc import Callable

import pandas as pd

from slipbench.data.format import Dataset
from slipbench.errors import UsageError
from slipbench.protocol import BaseProtocol, Cell, Layout, Presentation, described
from slipbench.seeding import rng_for
from slipbench.store.columns import DETECTION_RATE, FALSE_ALARMS, MEDIAN_DELAY
from slipbench.testing.data import assert_refused, toy_dataset
from slipbench.vocabulary import SENSOR_TYPE


def _cells(protocol: BaseProtocol, dataset: Dataset) -> tuple[list[Cell], pd.DataFrame]:
    recordings = dataset.recordings.copy()
    for name, values in protocol.columns(dataset.recordings).items():
        recordings[name] = values
    return list(protocol.cells(recordings)), recordings


def check_protocol_params(protocol: BaseProtocol, dataset: Dataset | None = None) -> None:
    """Options are keyword parameters (get_params/set_params round-trip), valid as given, and an
    unknown option is refused; the layout is a Layout, the presentation a Presentation or none
    (and a with-without figure has the layout's pair to draw)."""
    params = protocol.get_params()
    twin = type(protocol)(**params)
    assert twin.get_params() == params, (
        "the protocol must store every option as given (get_params round trip)"
    )
    protocol.validate_params()
    assert_refused(
        UsageError,
        "no parameter",
        lambda: twin.set_params(no_such_option=1),
        "set_params with an unknown name",
    )
    _layout(protocol)
    presentation = protocol.presentation
    assert presentation is None or isinstance(presentation, Presentation), (
        f"presentation must be a slipbench.protocol.Presentation or None, got {presentation!r}"
    )
    if presentation is not None and presentation.figure == "with-without":
        assert _layout(protocol).pair, "a 'with-without' figure needs Layout.pair"


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
    known = set(zip(recordings[SENSOR_TYPE], recordings["sensor_instance"]))
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
    """The layout renders, as the report shows it: fake results for every cell, recording the
    layout and presentation as a run's rows do, give the report that layout (it fits the
    cells' keys), a table in every format, and the figure the presentation declares."""
    from slipbench.report.document import protocol_tables
    from slipbench.report.outline import layouts
    from slipbench.report.plots import figure
    from slipbench.report.render import FORMATS, renderer

    _layout(protocol)
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
                **described(protocol),
            }
            for c, a in zip(cells, rng.uniform(0.55, 0.95, len(cells)))
        ]
    )
    layout, why = layouts(rows)["checked"]
    assert not why, f"the report cannot use the protocol's layout: {why}"
    for metric in layout.metrics:  # a layout of several metrics shows each
        rows[metric] = rng.uniform(0.55, 0.95, len(rows))
        rows[f"{metric}_lo"], rows[f"{metric}_hi"] = rows[metric] - 0.05, rows[metric] + 0.05
    if layout.figure == "tradeoff":  # a streaming cell's threshold sweep
        rows["tradeoff"] = json.dumps(
            [
                {
                    "threshold": t,
                    DETECTION_RATE.name: 1 - t,
                    MEDIAN_DELAY.name: 20 + 100 * t,
                    FALSE_ALARMS.name: 10 * (1 - t),
                }
                for t in (0.1, 0.5, 0.9)
            ]
        )
    tables = protocol_tables(rows, layout, "checked", "d", intervals=True)
    assert tables, "the layout made no table"
    for _, table in tables:
        assert table.rows and table.columns, f"table {table.caption!r} has no rows or columns"
        shown = {fmt: renderer(fmt).table(table) for fmt in FORMATS}  # every format renders it
        assert shown["md"] and "<table" in shown["html"]
        assert shown["latex"].count(r"\begin{tabular}") >= 1
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
