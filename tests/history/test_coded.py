"""Every figure's rows and points from the coded history are those of the row-by-row pandas
grouping they replaced, kept here as the reference (:func:`_figure_rows`, :func:`_points`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slipbench.history import coded, series


def _history(seed: int, runs: int = 30) -> pd.DataFrame:
    """Rows of two protocols, two detectors and some cells; repeated seeds in a run, results
    kept by a later run, missing figures, failed rows, missing pool settings and low n."""
    rng = np.random.default_rng(seed)
    rows = []
    for run in range(runs):
        for cell in range(12):
            for seed_ in range(1 + (run % 3 == 0)):
                kept = run > 0 and rng.random() < 0.1
                rows.append(
                    {
                        "run": run,
                        "series": f"{cell:016x}",
                        "series_label": f"label {cell}",
                        "key": f"k{run - kept}-{cell}-{seed_}",
                        "seed": int(rng.integers(0, 4)) * 10 + seed_,
                        "status": "ok" if rng.random() > 0.05 else "failed",
                        "low_n": bool(rng.random() < 0.05) if rng.random() > 0.1 else None,
                        "df": 30.0 if rng.random() > 0.1 else np.nan,
                        "protocol": ["window-size", "speed"][cell % 2],
                        "protocol_params": "{}" if cell % 5 else None,
                        "split": "grouped",
                        "labels": "scenario",
                        "detector": ["holweg", "bandpass"][cell % 3 == 0],
                        "accuracy": 0.8 + 0.01 * rng.standard_normal()
                        if rng.random() > 0.05
                        else None,
                        "accuracy_se": 0.01 * rng.random(),
                    }
                )
    return pd.DataFrame(rows)


def _figure_rows(frame: pd.DataFrame, figure: str) -> pd.DataFrame:
    """The finished results of ``figure`` in a history, each a row of its series (``kind``
    "cell"), and per run, seed, protocol and entrant the mean over its cells (``kind``
    "pooled"): its standard error the mean of the cells' (their errors taken as moving
    together, the widest case, as :func:`slipbench.stats.pooled.pooled_from_rows` takes them),
    its degrees of freedom the fewest. A pooled series' identity holds the cells it is over.

    Returns
    -------
    DataFrame
        ``series``, ``series_label``, ``kind``, ``run``, ``seed``, ``result`` (a digest of the
        result keys behind the row: the same results kept by a later run give the same one),
        ``value``, ``se``, ``df``, ``low_n``, in the figure's stored units.
    """
    ok = frame[(frame["status"] == "ok") & frame[figure].notna()]
    # each row's pool as a code, its text made once per pool: joining the texts row by row
    # cost more than the rest of this function on a long history
    pool, pools = pd.MultiIndex.from_frame(ok[list(series.POOL)].fillna("")).factorize()
    texts = np.array(["|".join(map(str, p)) for p in pools], dtype=object)
    labels = np.array([f"{p[0]} · {p[-1]}" for p in pools], dtype=object)
    cells = pd.DataFrame(
        {
            "series": ok["series"].to_numpy(),
            "series_label": series.shown_labels(ok["series_label"]),
            "kind": "cell",
            "run": ok["run"].to_numpy(),
            "seed": ok["seed"].to_numpy(),
            "result": pd.util.hash_pandas_object(ok["key"], index=False).to_numpy(),
            "value": pd.to_numeric(ok[figure], errors="coerce").to_numpy(float),
            "se": pd.to_numeric(ok[f"{figure}_se"], errors="coerce").to_numpy(float),
            "df": pd.to_numeric(ok["df"], errors="coerce").fillna(np.inf).to_numpy(float),
            "low_n": ok["low_n"].fillna(False).astype(bool).to_numpy(),
            "pool": pool,
            "series_hash": pd.util.hash_pandas_object(ok["series"], index=False).to_numpy(),
        }
    )
    group = cells.groupby(["run", "seed", "pool"], sort=False)
    pooled = group.agg(
        value=("value", "mean"),
        se=("se", "mean"),
        df=("df", "min"),
        low_n=("low_n", "any"),
        result=("result", np.bitwise_xor.reduce),
        cells=("series_hash", np.bitwise_xor.reduce),  # which cells: a digest of their set
    )
    codes = pooled.index.get_level_values("pool").to_numpy()
    named = {k: series._digest([texts[k[0]], str(k[1])]) for k in set(zip(codes, pooled["cells"]))}
    pooled["series"] = [named[k] for k in zip(codes, pooled["cells"])]
    pooled["series_label"] = labels[codes] + f" · {series.POOLED}"
    pooled["kind"] = "pooled"
    pooled = pooled.reset_index()
    columns = [
        "series",
        "series_label",
        "kind",
        "run",
        "seed",
        "result",
        "value",
        "se",
        "df",
        "low_n",
    ]
    return pd.concat([cells[columns], pooled[columns]], ignore_index=True)


def _points(rows: pd.DataFrame) -> pd.DataFrame:
    """(series, run) points of :func:`_figure_rows`: each run's mean over its seeds, with the
    standard error compare gives a side of several seeds (the mean of the seeds' standard
    errors plus their spread over the number of seeds) and the fewest degrees of freedom."""
    g = rows.groupby(["series", "run"], sort=False)
    out = g.agg(
        value=("value", "mean"),
        spread=("value", "var"),
        se=("se", "mean"),
        n=("value", "size"),
        df=("df", "min"),
        low_n=("low_n", "any"),
        kind=("kind", "first"),
        series_label=("series_label", "first"),
    ).reset_index()
    several = out["n"] > 1
    out.loc[several, "se"] = np.sqrt(
        out.loc[several, "se"] ** 2 + out.loc[several, "spread"] / out.loc[several, "n"]
    )
    out.loc[several, "df"] = np.minimum(out.loc[several, "df"], out.loc[several, "n"] - 1)
    return out.drop(columns="spread")


def _categorical(frame: pd.DataFrame) -> pd.DataFrame:
    """The texts (but the key) as categoricals, as ``read_history(..., categorical=True)``
    reads them, each with a category no row holds."""
    texts = [c for c in frame if c != "key" and pd.api.types.is_string_dtype(frame[c])]
    out = frame.astype({c: "category" for c in texts})
    for c in texts:
        out[c] = out[c].cat.add_categories(["unheld"])
    return out


@pytest.mark.parametrize("categorical", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rows_and_points_are_the_series_modules(seed, categorical):
    frame = _history(seed)
    want_rows = _figure_rows(frame, "accuracy")
    read = _categorical(frame) if categorical else frame
    got = coded.figure_rows(coded.Coded.of(read), "accuracy")
    pd.testing.assert_frame_equal(got.frame(), want_rows, check_exact=True)
    want = _points(want_rows)
    pts = coded.points(got)
    pts["kind"] = np.where(got.pooled[pts["series"]], "pooled", "cell")
    pts["series_label"] = got.labels[pts["series"]]
    pts["series"] = got.names[pts["series"]]
    pd.testing.assert_frame_equal(pts[want.columns], want, check_exact=True)
    assert (want["kind"] == "pooled").sum() > 0 and (want["n"] > 1).sum() > 0
