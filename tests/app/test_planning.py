"""`slipbench run FILE --plan`: the cells and models a run will compute, planned on the
simulated design's layout without simulating it, and their cost from measured rows; the
dask-jobqueue example of the scale-out guide."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from slipbench.app.benchspec import BenchmarkError, load_benchmark
from slipbench.app.planning import SECTIONS, Planning, Section, frame, planning, render
from slipbench.data.defaults import cache_dir
from slipbench.engine import slurm
from slipbench.engine.runner import Run, evaluate, planned, with_columns
from slipbench.protocols.window_size import WindowSize
from slipbench.store.results import ResultsStore

ROOT = Path(__file__).resolve().parents[2]

FILE = """
[benchmark]
out = "res"
[dataset]
scale = {scale}
[run]
split = "grouped"
jobs = 2
cell_timeout = 600
[slurm]
partition = "cpu"
cpus_per_task = 2
array_parallelism = 4
[slurm.holweg]
time = 45
[detectors.holweg]
[detectors.features]
[protocols.window-size]
windows = [50, 100]
[protocols.material-holdout]
"""


def _file(tmp_path: Path, scale: float, name: str = "bench.toml", more: str = "") -> Path:
    path = tmp_path / name
    path.write_text(FILE.format(scale=scale) + more)
    return path


@pytest.mark.slow  # simulates the design to compare with: 10 s
def test_the_layout_plans_the_cells_and_models_the_simulated_data_gives(tmp_path):
    """Planned on the design's layout, a run has the cells, models and windows that planning
    on the simulated samples gives; the plan simulates nothing and writes nothing."""
    from slipbench.app.planning import _layout
    from slipbench.data.defaults import default_dataset
    from slipbench.engine.runner import _signals

    # speed-holdout's cells depend on which trials slip, which the layout can only assume
    bench = load_benchmark(_file(tmp_path, 0.003, more="[protocols.speed-holdout]\n"))
    planning(bench, [], print)
    assert not any(cache_dir().glob("*scale0.003*")), "the plan simulated the dataset"
    assert not (tmp_path / "res").exists(), "the plan wrote into the results folder"
    signals, rec, _, _ = _layout(bench, print)
    ds = default_dataset(0.003, 0)
    assert rec["n_samples"].tolist() == ds.recordings["n_samples"].tolist()
    runs = [
        Run("holweg", WindowSize(windows=[50, 100]), "grouped"),
        Run("holweg", "material-holdout", "grouped"),
        Run("holweg", "streaming", "grouped"),
    ]
    real, _, _ = planned(_signals(ds, runs), ds.recordings, ds.fingerprint, runs, {})
    laid, _, _ = planned(with_columns(signals, rec, runs), rec, ds.fingerprint, runs, {})

    def shape(plan, stream: bool) -> list:
        return [
            (pc.key, pc.skip, len(pc.train or ()), len(pc.test or ()))
            for pc in plan.cells
            if bool(pc.cell.stream) == stream
        ]

    assert shape(real, False) == shape(laid, False)
    # a streaming cell trains on the same windows; its stand-in onsets only place the slip
    assert [s[:3] for s in shape(real, True)] == [s[:3] for s in shape(laid, True)]
    assert [t.model_key for t in real.tasks] == [t.model_key for t in laid.tasks]


def test_a_plan_charges_each_model_from_measured_rows_and_sizes_the_arrays(tmp_path, small):
    from datagen import subset

    rec = small.recordings
    index = subset(small, rec["sensor_type"].eq("Nano17") & rec["sensor_instance"].eq("index"))
    pilot = tmp_path / "pilot"
    evaluate(index, Run("holweg", WindowSize(windows=[50, 100]), "grouped"), ResultsStore(pilot))
    bench = load_benchmark(_file(tmp_path, 0.002))
    p = planning(bench, [pilot], print)
    text = render(p)
    plan = frame(p).set_index("detector")
    assert plan.loc["holweg", "seconds"] > 0 and plan.loc["holweg", "models"] > 0
    assert plan.loc["features", "seconds"] != plan.loc["features", "seconds"]  # nothing measured
    assert "No measured cell of features: run the file at a small scale" in text
    assert "| holweg | partition cpu, 2 cores, 4 GB |" in text
    # holweg's array has its own 45 minutes; features' follows from the cell time limit
    assert re.search(
        r"\| holweg \| partition cpu, 2 cores, 4 GB \| \d+ \| [^|]+ \| 45 min \|", text
    )
    # 48 models in 16 tasks: 3 x 600 s on 2 cores each, the longest, a quarter and 10 minutes
    limit = slurm.time_limit(slurm.Resources(cpus_per_task=2), [600.0] * 3, 2)
    assert limit == 42 and "| features | partition cpu, 2 cores, 4 GB | 16 | - | 42 min |" in text
    assert "no cell ran and no data was generated" in text


def test_a_section_joins_the_plan(tmp_path, monkeypatch):
    """Another part of slipbench adds what it can say about a run as one more builder."""
    bench = load_benchmark(_file(tmp_path, 0.002))
    p = planning(bench, [], print)

    def power(planning: Planning) -> Section:
        return Section("What the gate can see", [f"{len(planning.plan.cells)} cells"])

    monkeypatch.setattr("slipbench.app.planning.SECTIONS", [*SECTIONS, power])
    assert f"## What the gate can see\n\n{len(p.plan.cells)} cells" in render(p)


def test_the_gates_section_ends_the_plan_of_a_file_with_a_gate(tmp_path):
    """`run --plan` says what the gate can see after issue 49's sections; a file without
    [gate] has no such section."""
    without = render(planning(load_benchmark(_file(tmp_path, 0.002)), [], print))
    assert "## The gate" not in without
    path = _file(tmp_path, 0.002, "gated.toml")
    text = path.read_text().replace("jobs = 2", "jobs = 2\nrepeats = 2")
    path.write_text(text + "[gate]\naccuracy = 2.0\nbudget = 4\n")
    text = render(planning(load_benchmark(path), [], print))
    gate = text.index("## The gate ([gate])")
    assert gate > text.index("## On SLURM")
    assert "gate: 2 seeds a side, up to 4 in looks of 2 (2, 4)" in text[gate:]
    assert "no calibration (gated.calibration.json)" in text[gate:]


@pytest.mark.slow  # plans the paper's 4000 cells on its own size: see CHANGELOG for the time
def test_the_paper_file_plans_at_its_own_size_with_its_slurm_table(cli):
    code, out, err = cli(["run", str(ROOT / "reports" / "paper.toml"), "--plan"])
    assert code == 0, err
    assert "the simulated design at scale 1, seed 0, laid out" in out
    assert "## On SLURM ([slurm])" in out and "| lstm | partition cpu, 8 cores, 32 GB |" in out


@pytest.mark.parametrize(
    ("table", "line", "message"),
    [
        ("[slurm]\ntime = 0\n", 3, "[slurm] time: must be minutes an array task may run"),
        ("[slurm]\n[slurm.holweg]\ntasks = 3\n", 4, "[slurm.holweg] tasks: unknown key"),
        ("[slurm.nope]\ntime = 3\n", 2, "[slurm.nope]: not a detector of this run (holweg)"),
    ],
)
def test_a_bad_slurm_table_is_refused_at_its_line(tmp_path, table, line, message):
    path = tmp_path / "b.toml"
    path.write_text("[detectors.holweg]\n" + table + "[protocols.window-size]\n")
    with pytest.raises(BenchmarkError) as err:
        load_benchmark(path)
    assert str(err.value).startswith(f"{path}, line {line}, ") and message in str(err.value)


def test_the_guides_dask_jobqueue_cluster_is_the_job_script_it_says():
    """The scale-out guide's SLURMCluster, built as written: the script each sbatch would get
    retires its workers before the wall time, staggered."""
    pytest.importorskip("dask_jobqueue")
    guide = (ROOT / "docs" / "guides" / "scale-out.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", guide, re.S) if "SLURMCluster(" in b)
    code = block.replace("print(cluster.job_script())", "script = cluster.job_script()")
    scope: dict = {}
    exec(compile(code, "scale-out.md", "exec"), scope)  # noqa: S102 - the guide's own example
    cluster = scope["cluster"]
    try:
        script = scope["script"]
        assert "#SBATCH -p cpu" in script and "#SBATCH -A my-lab" in script
        assert "#SBATCH -t 04:00:00" in script and "#SBATCH --cpus-per-task=8" in script
        assert "--lifetime 3h50m --lifetime-stagger 5m --lifetime-restart" in script
        assert "--nworkers 8" in script and "source ~/venvs/slipbench/bin/activate" in script
    finally:
        cluster.close()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            ["--slurm", "time=10"],
            "--slurm sets the resources of --scheduler slurm or submitit-local",
        ),
        (["--measured", "."], "--measured sets the costs of --plan"),
        (["--scheduler", "slurm", "--slurm", "time=0"], "[slurm] time: must be minutes"),
    ],
)
def test_run_refuses_options_that_do_not_apply(cli, tmp_path, extra, message):
    code, _, err = cli(["run", str(_file(tmp_path, 0.002)), *extra])
    assert code == 2 and message in err
    assert not (tmp_path / "res").exists()


def test_evaluate_refuses_slurm_resources_without_its_scheduler(cli, tmp_path):
    code, _, err = cli(
        ["evaluate", "--detector", "holweg", "--protocol", "window-size", "--slurm", "time=5"]
    )
    assert code == 2 and "--slurm sets the resources of --scheduler slurm" in err
