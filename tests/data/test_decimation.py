"""Decimation said plainly: ``lag`` is what a slower sensor measures, ``plain`` every k-th sample
of the full-rate difference, the anti-aliasing filter an independent switch; the sampling-rate
protocol's cells are decimation x antialias, its rows and tables say which."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from resultgen import fake_rows
from scipy import signal

from slipbench.data.format import Dataset
from slipbench.data.signals import Signals, Windows, univariate
from slipbench.engine.plan import CellData, Run, keys
from slipbench.errors import UsageError
from slipbench.protocol import Cell, Part
from slipbench.protocols.sampling_rate import SamplingRate
from slipbench.report.document import protocol_tables
from slipbench.report.presentation import shown_protocol


def one_recording(a: np.ndarray, rate: float = 1000.0) -> Signals:
    s = univariate(a)
    rec = pd.DataFrame({"recording_id": ["r"], "sampling_rate_hz": [rate], "scenario": ["slip"]})
    return Signals(s, np.array([0, len(s)]), rec, np.ones(len(s), np.int8))


@settings(max_examples=60, deadline=None)
@given(
    window=st.integers(5, 64),
    factor=st.integers(1, 9),
    n_windows=st.integers(1, 4),
    seed=st.integers(0, 2**16),
)
def test_lag_is_the_difference_a_slower_sensor_measures(window, factor, n_windows, seed):
    """Sample j of a lag-decimated window is ||a|| at the slower sensor's reading j + 1 minus
    ||a|| at its reading j, the slower sensor reading every k-th of the window's readings."""
    if window // factor < 1:
        return
    rng = np.random.default_rng(seed)
    a = 100 + rng.standard_normal((window * n_windows + 3, 3)).cumsum(axis=0)
    windows = one_recording(a).windows(window)
    lag = windows.downsample(factor, "lag")
    plain = windows.downsample(factor, "plain")
    m = window // factor
    assert lag.x.shape == plain.x.shape == (n_windows, m)
    for i in range(n_windows):
        p = i * window  # the window holds s[p:p+window], from readings a_p ... a_{p+window}
        slow = a[p : p + m * factor + 1 : factor]  # the readings of a sensor k times slower
        np.testing.assert_allclose(lag.x[i], univariate(slow), rtol=1e-5, atol=1e-5)
        np.testing.assert_array_equal(plain.x[i], univariate(a)[p : p + m * factor : factor])


def test_plain_is_the_papers_every_kth_sample_where_the_factor_divides_the_window():
    x = np.arange(2 * 200, dtype=np.float32).reshape(2, 200)
    w = Windows(
        x, np.zeros(2, np.int32), np.arange(2, dtype=np.int32), pd.DataFrame(), np.ones(2, np.int8)
    )
    for k in (2, 4, 8):
        np.testing.assert_array_equal(w.downsample(k).x, x[:, ::k])
    # 200 is not a multiple of 16 or 32: the samples after the last whole block are dropped
    assert w.downsample(16).x.shape[1] == 12 and w.downsample(32).x.shape[1] == 6
    np.testing.assert_array_equal(w.downsample(32, "lag").x, x[:, :192].reshape(2, 6, 32).sum(-1))


def test_unknown_decimation_and_too_large_factor_are_refused():
    w = Windows(
        np.zeros((1, 10), np.float32),
        np.zeros(1, np.int32),
        np.zeros(1, np.int32),
        pd.DataFrame(),
        np.ones(1, np.int8),
    )
    with pytest.raises(UsageError, match="unknown decimation 'cubic'; choose plain or lag"):
        w.downsample(2, "cubic")
    with pytest.raises(UsageError, match="windows of 10 samples downsampled by 11 leave no sample"):
        w.downsample(11)


def test_antialias_filters_the_norm_before_differencing():
    """Filtering s equals filtering the norm and differencing it (the filter is linear and
    time-invariant), and the filter keeps what the slower sensor can see and removes what would
    alias: at 1000 Hz decimated by 8 (Nyquist 62.5 Hz, cut-off 50 Hz), a 10 Hz norm passes and
    a 200 Hz norm, which would alias to 50 Hz, is gone."""
    rate, k, t = 1000.0, 8, np.arange(4001) / 1000.0

    def decimated(freq: float, antialias: bool) -> np.ndarray:
        sig = one_recording(np.sin(2 * np.pi * freq * t)[:, None] + 10.0, rate)
        if antialias:
            sig = sig.antialiased(k)
        return sig.windows(400).downsample(k, "lag").x[2:]  # past the filter's start

    a = np.c_[np.sin(2 * np.pi * 200 * t), np.cos(2 * np.pi * 30 * t)] + 10.0
    sig = one_recording(a, rate)
    norm = np.linalg.norm(a, axis=1)
    sos = signal.butter(4, 0.8 * rate / (2 * k), fs=rate, output="sos")
    filtered = signal.sosfilt(sos, norm - norm[0])  # the filter at rest on the first reading
    np.testing.assert_allclose(sig.antialiased(k).buffer, np.diff(filtered), atol=1e-5)

    low = np.abs(decimated(10, True)).max() / np.abs(decimated(10, False)).max()
    high = np.abs(decimated(200, True)).max() / np.abs(decimated(200, False)).max()
    assert 0.8 < low < 1.1
    assert high < 0.01  # 4th order, two octaves above the cut-off: about -48 dB
    with pytest.raises(UsageError, match="needs a downsampling factor >= 2"):
        sig.antialiased(1)


@pytest.fixture(scope="module")
def nano(small):
    rec = small.recordings[small.recordings["sensor_type"].eq("Nano17")].reset_index(drop=True)
    return Dataset(
        rec,
        {k: small.samples[k] for k in rec["recording_id"]},
        {k: small.slip_labels[k] for k in rec["recording_id"] if k in small.slip_labels},
    )


def test_cells_are_decimation_by_antialias_and_say_which(nano):
    protocol = SamplingRate(decimation="both", antialias="both")
    protocol.validate_params()
    cells = list(protocol.cells(nano.recordings))
    assert len(cells) == 3 * 2 * 2 * 6 and len({c.name for c in cells}) == len(cells)
    for c in cells:
        assert (c.key["decimation"], c.key["antialias"]) == (c.decimation, c.antialias)
    assert {(c.decimation, c.antialias) for c in cells} == {
        ("plain", False),
        ("plain", True),
        ("lag", False),
        ("lag", True),
    }
    run = Run("holweg", protocol)
    models = {}
    for c in cells:
        if c.key["sensor_instance"] == "index":
            models.setdefault(c.downsample, set()).add(keys(run, c, "f")[1])
    # the full rate is one model for every variant; each downsampled variant is its own
    assert len(models[1]) == 1 and all(len(models[k]) == 4 for k in (2, 4, 8, 16, 32))
    # a full-rate cell of another protocol shares the model (the window-size model serves them all)
    plain = next(c for c in cells if c.downsample == 1)
    other = Cell({"x": 1}, plain.train, plain.test, plain.window)
    assert keys(run, other, "f")[1] == keys(run, plain, "f")[1]


@pytest.mark.parametrize(
    "options, message",
    [
        (
            dict(decimation="antialias"),
            "The 'decimation' parameter of SamplingRate must be one of 'plain', 'lag', 'both'",
        ),
        (
            dict(antialias="yes"),
            "The 'antialias' parameter of SamplingRate must be one of False, True, 'both'",
        ),
    ],
)
def test_options_are_validated(options, message):
    with pytest.raises(UsageError, match=message):
        SamplingRate(**options).validate_params()
    with pytest.raises(ValueError, match="Cell.antialias must be a bool"):
        Cell(
            {"x": 1}, Part((("a", "b"),), "train"), Part((("a", "b"),), "test"), 10, antialias="yes"
        )


def test_cell_data_cuts_the_same_windows_for_every_variant(nano):
    data = CellData(Signals.from_dataset(nano), "paper", seed=0)
    cells = {
        (c.decimation, c.antialias, c.downsample): c
        for c in SamplingRate(decimation="both", antialias="both").cells(nano.recordings)
        if c.key["sensor_instance"] == "index"
    }
    full = cells[("plain", False, 1)]
    positions = data.part(full.train, full.window)
    x = data.values(positions, full).x
    got = {
        v: data.values(positions, cells[(*v, 8)])
        for v in (("plain", False), ("lag", False), ("plain", True), ("lag", True))
    }
    np.testing.assert_array_equal(
        got["plain", False].x, x[:, ::8]
    )  # the paper's decimation, unchanged
    np.testing.assert_allclose(
        got["lag", False].x, x.reshape(len(x), 25, 8).sum(-1, dtype=np.float64), rtol=1e-6
    )
    for _v, w in got.items():
        assert w.x.shape == (len(x), 25)
        np.testing.assert_array_equal(w.recording, positions.recording)  # the same windows ...
    assert not np.allclose(got["plain", True].x, got["plain", False].x)  # ... low-passed
    assert not np.allclose(got["lag", True].x, got["lag", False].x)
    # the full-rate cell of any variant is the full-rate signal
    np.testing.assert_array_equal(data.values(positions, cells[("lag", True, 1)]).x, x)


@pytest.mark.slow
def test_report_gives_one_table_per_variant(tmp_path):
    rows = fake_rows("sampling-rate")
    variants = [("plain", False), ("lag", False), ("plain", True), ("lag", True)]
    frames = []
    for i, (decimation, antialias) in enumerate(variants):
        part = rows.assign(
            decimation=decimation, antialias=antialias, accuracy=rows["accuracy"] + i / 100
        )
        frames.append(part.assign(cell=part["cell"] + f"{decimation}{antialias}"))
    tables = protocol_tables(
        pd.concat(frames, ignore_index=True),
        shown_protocol(SamplingRate(), "sampling-rate"),
        "sampling-rate",
        "lstm",
    )
    names = [name for name, _ in tables]
    assert names == [
        f"lstm (decimation: {d}, antialias: {a})"
        for d, a in [("plain", False), ("plain", True), ("lag", False), ("lag", True)]
    ]
    for (_name, table), (d, a) in zip(
        tables, [("plain", False), ("plain", True), ("lag", False), ("lag", True)]
    ):
        assert table.caption.endswith(f"Decimation: {d}. Antialias: {a}.")
        # one result per cell, never an average of two variants shown as seeds
        assert not any("±" in text for line in table.cells for text in line)
        i = variants.index((d, a))
        nano_index_32 = (
            rows[
                (rows["sensor_type"] == "Nano17")
                & (rows["sensor_instance"] == "index")
                & (rows["downsample"] == 32)
            ]["accuracy"].iloc[0]
            + i / 100
        )
        assert table.cells[0][0] == f"{100 * nano_index_32:.1f}"
    # and one figure per table; a run of one variant keeps its plain name
    from rendering import write_plots

    both = pd.concat(frames, ignore_index=True).assign(protocol_params="{}")
    names = sorted(p.name for p in write_plots(both, tmp_path / "all", paper=False))
    assert names == sorted(
        f"sampling-rate-lstm-{d}-{a}.{ext}" for d, a in variants for ext in ("png", "pdf")
    )
    single = frames[0].assign(protocol_params="{}")
    assert sorted(p.name for p in write_plots(single, tmp_path / "one", paper=False)) == [
        "sampling-rate-lstm.pdf",
        "sampling-rate-lstm.png",
    ]
