"""A history's rows as integer codes, made once, and every figure's points from them.

Grouping a history's text columns (series digests, a protocol's pool) once per figure was most
of the time a step search took on a long history, and its copies most of the memory. Here the
texts are coded once (:class:`Coded`), and each figure's rows and points are grouped on
integers with pandas' own aggregations, over the same rows in the same order, so that every
mean, variance and row order is the text grouping's (``tests/history/test_coded.py`` keeps that
grouping as the reference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import pyarrow as pa

from slipbench.history.series import POOL, POOLED, _digest

#: a series' kind by whether it is pooled
KINDS = np.array(["cell", "pooled"], dtype=object)


#: rows hashed at a time: their texts as Python objects only a batch at a time
HASH_BATCH = 1 << 18


def _codes(column: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    """A code per row (-1: missing) and each code's value; a categorical column's own codes
    (its categories no row holds left out), else in order of first appearance."""
    if not isinstance(column.dtype, pd.CategoricalDtype):
        codes, uniques = pd.factorize(column, use_na_sentinel=True)
        return codes.astype(np.int64), np.asarray(uniques, dtype=object)
    codes = column.cat.codes.to_numpy().astype(np.int64)
    values = np.asarray(column.cat.categories, dtype=object)
    used = np.bincount(codes[codes >= 0], minlength=len(values)) > 0
    if not used.all():
        codes = np.where(codes >= 0, (np.cumsum(used) - 1)[codes], -1)
        values = values[used]
    return codes, values


def _first_rows(codes: np.ndarray, n: int) -> np.ndarray:
    """The first row of each of the codes 0..n-1 (each held by a row)."""
    first = np.full(n, len(codes), np.int64)
    np.minimum.at(first, codes, np.arange(len(codes)))
    return first


def _combine_few(*codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_combine` of codes that take few values, in one pass (the codes numbered by
    their combination, not in order of first appearance)."""
    key, size = np.zeros(len(codes[0]), np.int64), 1
    for c in codes:
        width = int(c.max(initial=0)) + 2
        key, size = key * width + (c + 1), size * width
        if size > 1 << 22:
            return _combine(*codes)
    used = np.bincount(key, minlength=size) > 0
    combined = (np.cumsum(used) - 1)[key]
    return combined, _first_rows(combined, int(used.sum()))


def _filled(column: pd.Series) -> pd.Series:
    """A text column with missing values as "" (a categorical one given "" as a category)."""
    if isinstance(column.dtype, pd.CategoricalDtype) and "" not in column.cat.categories:
        column = column.cat.add_categories([""])
    return column.fillna("")


def _hashed(column: pd.Series) -> np.ndarray:
    """``pd.util.hash_pandas_object(column, index=False)``, a batch of rows at a time and each
    value hashed as it comes (not factorized first: a history's keys are nearly all distinct)."""
    if isinstance(column.dtype, pd.CategoricalDtype) or column.hasnans:
        return pd.util.hash_pandas_object(column, index=False).to_numpy()
    out = np.empty(len(column), np.uint64)
    for at in range(0, len(column), HASH_BATCH):
        part = column.iloc[at : at + HASH_BATCH].to_numpy(dtype=object)
        out[at : at + len(part)] = pd.util.hash_array(part, categorize=False)
    return out


def _combine(*codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One code per distinct combination of ``codes`` (in order of first appearance) and the
    row at which each combination first appears; combined a pair at a time, so that no key
    outgrows the rows squared."""
    combined = np.zeros(len(codes[0]), np.int64)
    for c in codes:
        key = combined * (int(c.max(initial=0)) + 2) + (c + 1)
        combined = pd.factorize(key)[0].astype(np.int64)
    _, first = np.unique(combined, return_index=True)
    return combined, first


def texts(codes: np.ndarray, values: np.ndarray) -> pd.Series:
    """``values[codes]`` as a column of text, made from the few values rather than a Python
    object per row."""
    uniques, at = pd.factorize(values)[::-1]
    column = pa.DictionaryArray.from_arrays(
        pa.array(at[codes].astype(np.int32)), pa.array(list(uniques), pa.large_string())
    ).dictionary_decode()
    return pd.Series(pd.array(column, dtype="str"))


def categorical(codes: np.ndarray, values: np.ndarray) -> pd.Series:
    """``values[codes]`` as a categorical column: a code per row, each distinct value once."""
    at, uniques = pd.factorize(values)
    return pd.Series(pd.Categorical.from_codes(at[codes], categories=pd.Index(uniques)))


def _xor_by(group: np.ndarray, values: np.ndarray, groups: int) -> np.ndarray:
    """The XOR of ``values`` per ``group`` (0..groups-1): order does not change it."""
    order = np.argsort(group, kind="stable")
    starts = np.searchsorted(group[order], np.arange(groups))
    return np.bitwise_xor.reduceat(values[order], starts)


@dataclass
class Coded:
    """The columns of a history that every figure's points read, coded once.

    Attributes
    ----------
    series : each row's series as a code into ``names`` (their 16-hex digests, in order of
        first appearance), ``labels`` each code's label.
    pool : each row's pool (:data:`slipbench.history.series.POOL`, missing as "") as a code;
        ``pool_texts`` and ``pool_labels`` what names and labels a pooled series of it.
    run, seed : each row's run and seed (a code; -1: none).
    result, cell_hash : each row's key and series hashed as figure_rows hashes them.
    finished, low_n, df : status "ok", low n (missing: no), degrees of freedom (missing: inf).
    """

    frame: pd.DataFrame
    series: np.ndarray
    names: np.ndarray
    labels: np.ndarray
    pool: np.ndarray
    pool_texts: np.ndarray
    pool_labels: np.ndarray
    run: np.ndarray
    seed: np.ndarray
    seeds: np.ndarray
    result: np.ndarray
    cell_hash: np.ndarray
    finished: np.ndarray
    low_n: np.ndarray
    df: np.ndarray

    @classmethod
    def of(cls, frame: pd.DataFrame) -> Coded:
        """Code a history's rows (:func:`slipbench.store.history.read_history`)."""
        series, names = _codes(frame["series"])
        if (series < 0).any():
            raise ValueError(f"{int((series < 0).sum())} history rows hold no series")
        first = _first_rows(series, len(names))
        # taken before they become Python objects: only one row of each
        labels = frame["series_label"].iloc[first].to_numpy(dtype=object)
        parts = [_codes(_filled(frame[c]))[0] for c in POOL]
        pool, at = _combine_few(*parts)
        tuples = frame[list(POOL)].iloc[at].astype(object).fillna("").to_numpy(dtype=object)
        seed, seeds = pd.factorize(frame["seed"], use_na_sentinel=True)
        return cls(
            frame=frame,
            series=series,
            names=names,
            labels=labels,
            pool=pool,
            pool_texts=np.array(["|".join(map(str, p)) for p in tuples], dtype=object),
            pool_labels=np.array([f"{p[0]} · {p[-1]}" for p in tuples], dtype=object),
            run=frame["run"].to_numpy(np.int64),
            seed=seed.astype(np.int64),
            seeds=np.asarray(seeds),
            result=_hashed(frame["key"]),
            # a value's hash is its own: hashed once per series, taken per row
            cell_hash=pd.util.hash_pandas_object(pd.Series(names), index=False).to_numpy()[series],
            finished=(frame["status"] == "ok").to_numpy(bool),
            low_n=frame["low_n"].fillna(False).astype(bool).to_numpy(),
            df=pd.to_numeric(frame["df"], errors="coerce").fillna(np.inf).to_numpy(float),
        )


@dataclass
class FigureRows:
    """One figure's rows (:func:`figure_rows`), coded:
    ``series`` a code into ``names`` (cells' codes first, then the pooled series'), ``labels``
    and ``pooled`` (whether a code is a pooled series) per code."""

    series: np.ndarray
    run: np.ndarray
    seed: np.ndarray  # the seed's value
    result: np.ndarray
    value: np.ndarray
    se: np.ndarray
    df: np.ndarray
    low_n: np.ndarray
    names: np.ndarray
    labels: np.ndarray
    pooled: np.ndarray

    def frame(self) -> pd.DataFrame:
        """As figure_rows returns it."""
        return pd.DataFrame(
            {
                "series": texts(self.series, self.names),
                "series_label": texts(self.series, self.labels),
                "kind": texts(self.pooled[self.series].astype(int), KINDS),
                "run": self.run,
                "seed": self.seed,
                "result": self.result,
                "value": self.value,
                "se": self.se,
                "df": self.df,
                "low_n": self.low_n,
            }
        )


def figure_rows(coded: Coded, figure: str) -> FigureRows:
    """The finished results of ``figure``, each a row of its series (``kind`` "cell"), and per
    run, seed, protocol and entrant the mean over its cells (a pooled series): its standard
    error the mean of the cells' (their errors taken as moving together, the widest case), its
    degrees of freedom the fewest; a pooled series' identity holds the cells it is over."""
    frame = coded.frame
    ok = np.flatnonzero(coded.finished & frame[figure].notna().to_numpy())
    value = pd.to_numeric(frame[figure], errors="coerce").to_numpy(float)[ok]
    se = pd.to_numeric(frame[f"{figure}_se"], errors="coerce").to_numpy(float)[ok]
    run, seed, pool = coded.run[ok], coded.seed[ok], coded.pool[ok]
    df, low_n = coded.df[ok], coded.low_n[ok]
    cells = pd.DataFrame({"value": value, "se": se, "df": df, "low_n": low_n})
    # groupby drops a missing seed from the pooled rows, as figure_rows' grouping does
    seeded = seed >= 0
    key, first = _combine(run[seeded], seed[seeded], pool[seeded])
    group = cells[seeded].groupby(key, sort=False)
    pooled = group.agg(
        value=("value", "mean"), se=("se", "mean"), df=("df", "min"), low_n=("low_n", "any")
    )
    n_groups = len(pooled)
    result = _xor_by(key, coded.result[ok][seeded], n_groups)
    members = _xor_by(key, coded.cell_hash[ok][seeded], n_groups)
    g_pool = pool[seeded][first]
    named: dict[tuple[int, int], int] = {}
    pooled_names: list[str] = []
    pooled_labels: list[str] = []
    codes = np.empty(n_groups, np.int64)
    n_cells = len(coded.names)
    for i, k in enumerate(zip(g_pool.tolist(), members.tolist())):
        if k not in named:
            named[k] = n_cells + len(pooled_names)
            pooled_names.append(_digest([coded.pool_texts[k[0]], str(k[1])]))
            pooled_labels.append(f"{coded.pool_labels[k[0]]} · {POOLED}")
        codes[i] = named[k]
    g_run, g_seed = run[seeded][first], seed[seeded][first]
    return FigureRows(
        series=np.concatenate([coded.series[ok], codes]),
        run=np.concatenate([run, g_run]),
        seed=np.concatenate([frame["seed"].to_numpy()[ok], coded.seeds[g_seed]]),
        result=np.concatenate([coded.result[ok], result]),
        value=np.concatenate([value, pooled["value"].to_numpy(float)]),
        se=np.concatenate([se, pooled["se"].to_numpy(float)]),
        df=np.concatenate([df, pooled["df"].to_numpy(float)]),
        low_n=np.concatenate([low_n, pooled["low_n"].to_numpy(bool)]),
        names=np.concatenate([coded.names, np.array(pooled_names, dtype=object)]),
        labels=np.concatenate([coded.labels, np.array(pooled_labels, dtype=object)]),
        pooled=np.concatenate([np.zeros(n_cells, bool), np.ones(len(pooled_names), bool)]),
    )


def points(rows: FigureRows) -> pd.DataFrame:
    """(series, run) points of coded rows: each run's mean over its seeds, with the standard
    error compare gives a side of several seeds (the mean of the seeds' standard errors plus
    their spread over the number of seeds) and the fewest degrees of freedom; ``series`` a code
    (the rows' ``names`` name it)."""
    key, first = _combine(rows.series, rows.run)
    table = pd.DataFrame({"value": rows.value, "se": rows.se, "df": rows.df, "low_n": rows.low_n})
    out = table.groupby(key, sort=False).agg(
        value=("value", "mean"),
        spread=("value", "var"),
        se=("se", "mean"),
        n=("value", "size"),
        df=("df", "min"),
        low_n=("low_n", "any"),
    )
    out = out.reset_index(drop=True)
    out.insert(0, "series", rows.series[first])
    out.insert(1, "run", rows.run[first])
    several = out["n"] > 1
    out.loc[several, "se"] = np.sqrt(
        out.loc[several, "se"] ** 2 + out.loc[several, "spread"] / out.loc[several, "n"]
    )
    out.loc[several, "df"] = np.minimum(out.loc[several, "df"], out.loc[several, "n"] - 1)
    return out.drop(columns="spread")
