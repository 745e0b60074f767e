"""The CI workflows as shipped: this repository's (.github/workflows/slipbench.yml, bench.toml)
and the plugin repository's example (examples/plugin-repo/). The CI guide shows them as they are;
each workflow has the permissions to comment, caches the base branch's results by its commit,
guards its comment step, lets compare decide the job; the base runs its own bench file and
compare runs from the base's install with the base's bench (nobody grades their own change);
its `slipbench` steps run here through bash as GitHub runs them, on one sensor unit instead of
the simulated dataset."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib
import yaml

ROOT = Path(__file__).resolve().parents[2]
REPOS = {
    "this": (ROOT / ".github/workflows/slipbench.yml", ROOT / "bench.toml"),
    "plugin": (
        ROOT / "examples/plugin-repo/.github/workflows/slipbench.yml",
        ROOT / "examples/plugin-repo/bench.toml",
    ),
}
SHIPPED = [p for pair in REPOS.values() for p in pair]
#: the base branch's install, the judge (a venv from the base's checkout)
JUDGE = "../base-env/bin/slipbench"
#: the base branch's bench file, in its checkout
BASE_BENCH = '../base-src/"$BENCH"'


def workflow(path: Path) -> dict:
    data = yaml.safe_load(path.read_text())
    # YAML 1.1 reads the key `on` as True
    data["on"] = data.pop(True, data.get("on"))
    return data


def steps(path: Path, job: str = "compare") -> list[dict]:
    """The steps of the pull-request job (a workflow of one job: its job's)."""
    jobs = workflow(path)["jobs"]
    return (jobs[job] if len(jobs) > 1 else next(iter(jobs.values())))["steps"]


def step_named(path: Path, words: str) -> dict:
    found = [s for s in steps(path) if words in s.get("name", "")]
    assert len(found) == 1, f"{path}: one step named '... {words} ...'"
    return found[0]


def commands(script: str) -> list[str]:
    return [
        line.strip()
        for line in script.splitlines()
        if line.strip() and not line.strip().startswith("#")
    ]


def compare_out(path: Path) -> str:
    """The file the Markdown compare writes (its --out), from the workflow's last compare line."""
    lines = [c for s in steps(path) for c in commands(s.get("run", "")) if "slipbench compare" in c]
    m = re.search(r"--out (\S+)$", lines[-1])
    assert m and "--format" not in lines[-1], lines[-1]
    return m[1]


def test_the_ci_guide_includes_the_shipped_files():
    """Included whole at build time (``--8<--``), so the guide cannot show a stale copy."""
    guide = (ROOT / "docs" / "guides" / "ci.md").read_text()
    blocks = re.findall(r"^```\w*\n(.*?)^```$", guide, re.M | re.S)
    for path in SHIPPED:
        snippet = f'--8<-- "{path.relative_to(ROOT).as_posix()}"\n'
        assert snippet in blocks, f"docs/guides/ci.md does not include {path.relative_to(ROOT)}"


def test_docs_name_no_missing_plugin_folder():
    pages = [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]
    for m in re.finditer(r"^plugins = (\[.*?\])", "\n".join(p.read_text() for p in pages), re.M):
        assert json.loads(m[1]) == ["plugins"]
    for _, bench in REPOS.values():
        for folder in tomllib.loads(bench.read_text()).get("run", {}).get("plugins", []):
            assert (bench.parent / folder).is_dir(), f"{bench} names a missing folder {folder}"
    assert "plugins" in tomllib.loads(REPOS["plugin"][1].read_text())["run"]


@pytest.mark.parametrize("repo", REPOS)
def test_workflow_comments_caches_and_gates(repo):
    path, bench = REPOS[repo]
    wf = workflow(path)
    if repo == "this":  # and on pushes to main, the history job
        assert wf["on"] == {"pull_request": None, "push": {"branches": ["main"]}}
        assert wf["jobs"]["compare"]["if"] == "github.event_name == 'pull_request'"
        assert wf["permissions"]["actions"] == "read"  # main's artifacts
    else:
        assert wf["on"] == "pull_request"
    assert {k: wf["permissions"][k] for k in ("contents", "pull-requests")} == {
        "contents": "read",
        "pull-requests": "write",
    }
    assert wf["env"]["BENCH"] == bench.name
    # the base results: restored and saved under a key of the base commit (which fixes its
    # bench file; the pull request's bench no longer makes them)
    restore = next(s for s in steps(path) if s.get("uses", "").startswith("actions/cache/restore"))
    key = restore["with"]["key"]
    assert "github.event.pull_request.base.sha" in key and "hashFiles" not in key
    save = next(s for s in steps(path) if s.get("uses", "").startswith("actions/cache/save"))
    assert save["with"]["key"] == f"${{{{ steps.{restore['id']}.outputs.cache-primary-key }}}}"
    assert save["with"]["path"] == restore["with"]["path"] == "base"
    miss = f"steps.{restore['id']}.outputs.cache-hit != 'true'"
    base_run = step_named(path, "on the base branch")
    assert (
        base_run["if"].startswith(miss) and save["if"] == miss and "--out base" in base_run["run"]
    )
    assert f"run {BASE_BENCH} --out base" in base_run["run"]  # the base's own bench
    # the judge: a venv of the base's checkout (this repository) or of its pins (a plugin repo)
    judge = step_named(path, "The judge, the base branch's checkout")
    assert "git worktree add ../base-src" in judge["run"]
    assert "python -m venv ../base-env" in judge["run"]
    assert "../base-env/bin/pip install -c ../base-src/constraints.txt" in judge["run"]
    # every install pinned by the constraints file; torch (where a plugin needs it) from
    # PyTorch's CPU index, never PyPI's multi-GB CUDA build
    installs = " ".join(s.get("run", "") for s in steps(path))
    assert all(
        "--index-url https://download.pytorch.org/whl/cpu" in c
        for c in commands(installs)
        if "pip install" in c and " torch" in c
    )
    assert all(
        re.search(r"-c (\.\./base-src/)?constraints\.txt", c)
        for c in commands(installs)
        if "pip install" in c
    )
    assert (path.parents[2] / "constraints.txt").is_file()
    # compare decides the job: its Markdown call is the step's last command, nothing masks it
    gate = [s for s in steps(path) if "slipbench compare" in s.get("run", "")][-1]
    assert not gate.get("continue-on-error") and "if" not in gate
    last = commands(gate["run"])[-1]
    assert last.startswith(f"{JUDGE} compare base candidate --bench {BASE_BENCH}")
    assert "||" not in last
    candidate = step_named(path, "on this pull request, its own bench")
    assert 'slipbench run "$BENCH" --out candidate' in candidate["run"]
    # the comment: posted whenever compare wrote its file, never failing when it did not
    out = compare_out(path)
    comment = step_named(path, "Comment")
    assert comment["if"].startswith("always() && ")
    assert f"hashFiles('{out}') != ''" in comment["if"]
    assert f"--body-file {out}" in comment["run"] and "GH_TOKEN" in comment["env"]


def test_this_workflow_looks_at_more_seeds_and_refreshes_its_calibration():
    """While compare is undecided short of the budget, the workflow runs the next look's
    seeds on both sides (the base's with the base's code) and compares again; on pushes to
    main, a calibration that no longer holds is measured again and cached for the pull
    requests, which restore it before they compare."""
    path = REPOS["this"][0]
    wf = workflow(path)
    assert wf["on"]["push"] == {"branches": ["main"]}
    assert wf["jobs"]["compare"]["if"] == "github.event_name == 'pull_request'"
    cal = wf["jobs"]["history"]  # main's job: the calibration first, then the history
    assert cal["if"] == "github.event_name == 'push'"
    run = [c for s in cal["steps"] for c in commands(s.get("run", ""))]
    assert 'slipbench calibrate "$BENCH" --if-stale --quiet' in run
    saved = [s for s in cal["steps"] if s.get("uses", "").startswith("actions/cache/save")]
    assert [s["with"]["path"] for s in saved] == ["bench.calibration.json"]
    restored = [
        s
        for s in steps(path)
        if s.get("uses", "").startswith("actions/cache/restore")
        and s["with"]["path"] == "bench.calibration.json"
    ]
    assert restored and restored[0]["with"]["restore-keys"] == "slipbench-calibration-"
    # main's calibration goes beside the base's bench only where the cache held one: the pull
    # request's committed file never stands in for it
    beside = step_named(path, "Beside the base's bench")
    assert beside["if"] == f"steps.{restored[0]['id']}.outputs.cache-matched-key != ''"
    assert "../base-src/" in beside["run"]
    looks = step_named(path, "the next look's seeds on both sides")
    script = looks["run"]
    assert "jq .look.next_seed" in script and "jq .look.final" in script
    assert f"{JUDGE} compare base candidate --bench {BASE_BENCH} --format json" in script
    assert f'{JUDGE} run {BASE_BENCH} --seed "$seed" --out base' in script
    assert 'slipbench run "$BENCH" --seed "$seed" --out candidate' in script
    # then the comparison that decides the job reads every look's seeds
    names = [s.get("name", "") for s in steps(path)]
    assert names.index(looks["name"]) < names.index(
        step_named(path, "Compare on the base's [gate]")["name"]
    )


def tiny(bench: Path, data: Path) -> Path:
    """``bench`` on one sensor unit, one seed (so no budget of more), one window: everything
    else as shipped."""
    text = re.sub(r"(?ms)^\[dataset\].*?(?=^\[)", "", bench.read_text())
    text = re.sub(r"(?m)^repeats = \d+", "repeats = 1", text)
    text = re.sub(r"(?m)^budget = \d+.*\n", "", text)
    text = re.sub(r"(?m)^jobs = \d+", "jobs = 1", text)
    text = re.sub(r"(?m)^windows = \[.*\]", "windows = [50]", text)
    text += f'\n[dataset]\npath = "{data.as_posix()}"\n'
    small, shipped = tomllib.loads(text), tomllib.loads(bench.read_text())
    assert small["detectors"] == shipped["detectors"]
    assert small["protocols"].keys() == shipped["protocols"].keys()
    out = bench.parent / "tiny.toml"
    out.write_text(text)
    return out


def slipbench_steps(path: Path) -> list[dict]:
    """The steps whose every command is a `slipbench` one, the pull request's or the base's
    (installs and git are GitHub's)."""
    return [
        s
        for s in steps(path)
        if "run" in s and all(c.startswith(("slipbench ", f"{JUDGE} ")) for c in commands(s["run"]))
    ]


@pytest.mark.slow
@pytest.mark.parametrize("repo", REPOS)
def test_workflow_slipbench_steps_run(repo, tmp_path, unit):
    path, bench = REPOS[repo]
    work = tmp_path / "repo"
    work.mkdir()
    shutil.copy(bench, work)
    for folder in tomllib.loads(bench.read_text()).get("run", {}).get("plugins", []):
        shutil.copytree(bench.parent / folder, work / folder)
    # what the base branch's checkout step makes: here the same files
    shutil.copytree(work, tmp_path / "base-src")
    small = tiny(work / bench.name, unit)
    shutil.copy(small, tmp_path / "base-src" / small.name)
    # what the judge's step makes: the base's install (here this source, as both sides')
    judge = tmp_path / "base-env" / "bin" / "slipbench"
    judge.parent.mkdir(parents=True)
    judge.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m slipbench "$@"\n')
    judge.chmod(0o755)
    env = {
        **os.environ,
        **{k: str(v) for k, v in workflow(path)["env"].items()},
        "BENCH": small.name,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
        "PYTHONPATH": str(ROOT),  # this source, not the installed one
    }
    ran = slipbench_steps(path)
    assert [("--out base" in s["run"], "compare" in s["run"]) for s in ran] == [
        (True, False),
        (False, False),
        (False, True),
    ]
    for step in ran:
        # GitHub runs a `run:` script with bash -eo pipefail
        done = subprocess.run(
            ["bash", "--noprofile", "--norc", "-eo", "pipefail", "-c", step["run"]],
            cwd=work,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 0, f"{step['name']}: {done.stderr[-2000:]}"
    # the same code on both sides: nothing regressed, and both files the later steps read exist
    assert (work / compare_out(path)).read_text().strip()
    result = json.loads((work / "compare.json").read_text())
    assert result["exit_code"] == 0 and result["counts"]["regressed"] == 0 and result["cells"]
    assert not result["only_base"] and not result["only_candidate"]
    assert (work / "candidate" / "report.html").is_file()
    assert (work / "base" / "benchmark.toml").read_text() == small.read_text()


def test_history_job_keeps_main_history_and_publishes():
    path = REPOS["this"][0]
    job = workflow(path)["jobs"]["history"]
    assert job["if"] == "github.event_name == 'push'"
    assert {("pages", "write"), ("id-token", "write"), ("actions", "read")} <= set(
        job["permissions"].items()
    )
    names = [s.get("uses", "").split("@")[0] for s in job["steps"]]
    assert names.count("actions/upload-artifact") == 2 and "actions/deploy-pages" in names
    uploads = {
        s["with"]["name"]: s["with"]["path"]
        for s in job["steps"]
        if "upload-artifact" in s.get("uses", "")
    }
    assert uploads == {"history": "history", "main-results": "results"}
    text = "\n".join(s.get("run", "") for s in job["steps"])
    assert (
        "--name history --dir history" in text and "history add results --history history" in text
    )
    # the pull request's base: main's latest results, where they ran the base's bench file
    main = next(s for s in steps(path) if s.get("id") == "main")
    assert (
        "--name main-results --dir base" in main["run"]
        and f"cmp -s base/benchmark.toml {BASE_BENCH}" in main["run"]
    )


@pytest.mark.slow
def test_history_job_slipbench_steps_run(tmp_path, unit):
    """The history job's own commands, run through bash on a tiny bench: a run, added twice
    (the second changes nothing), its steps, its site."""
    path, bench = REPOS["this"]
    work = tmp_path / "repo"
    work.mkdir()
    shutil.copy(bench, work)
    small = tiny(work / bench.name, unit)
    subprocess.run(["git", "init", "-q"], cwd=work, check=True)
    subprocess.run(
        [
            "git",
            "-c",
            "user.name=t",
            "-c",
            "user.email=t@t",
            "commit",
            "-q",
            "--allow-empty",
            "-m",
            "x",
        ],
        cwd=work,
        check=True,
    )
    env = {
        **os.environ,
        "BENCH": small.name,
        "GITHUB_SHA": "0123abc",
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
    }
    job = workflow(path)["jobs"]["history"]["steps"]
    ran = [
        s
        for s in job
        if "run" in s
        and "slipbench " in s["run"]
        and not any(w in s["run"] for w in ("gh run", "slipbench calibrate"))
    ]
    assert len(ran) == 4
    for step in [*ran, ran[1]]:
        done = subprocess.run(
            ["bash", "--noprofile", "--norc", "-eo", "pipefail", "-c", step["run"]],
            cwd=work,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 0, f"{step['name']}: {done.stderr[-2000:]}"
    assert len(list((work / "history" / "runs").glob("month=*/0123abc.parquet"))) == 1
    assert "1 runs" in (work / "steps.md").read_text()
    assert {p.name for p in (work / "site").iterdir()} >= {
        "index.html",
        "series.html",
        "report.html",
    }


@pytest.mark.parametrize("repo", REPOS)
def test_shipped_bench_files_plan(repo):
    """Every plugin and parameter the shipped files declare exists and is valid here."""
    from slipbench.app.benchfile import plan_runs
    from slipbench.app.benchspec import load_benchmark

    bench = load_benchmark(REPOS[repo][1])
    runs = plan_runs(bench, echo=lambda line: pytest.fail(f"skipped: {line}"))
    shipped = tomllib.loads(REPOS[repo][1].read_text())
    assert len(runs) == len(shipped["detectors"]) * len(shipped["protocols"]) * bench.repeats
