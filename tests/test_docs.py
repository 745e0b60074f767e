"""The README and the documentation site: a README read in five minutes that links the site and
what exists, an example that is the shipped plugin, prose that never counts the tests, and the
commit-msg hook that keeps subjects to 72 characters. `mkdocs build --strict` (.ci/run) checks
every link, anchor, included file and page of the site itself."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "pyproject.toml").is_file())
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").rglob("*.md"))]


def test_readme_is_short_and_links_the_site():
    text = README.read_text()
    assert len(text.splitlines()) <= 250
    assert "](docs/index.md)" in text


def github_anchor(heading: str) -> str:
    return re.sub(r"\s", "-", re.sub(r"[^\w\s-]", "", heading.strip().lower()))


@pytest.mark.parametrize("page", ["README.md", "datasets.md"])
def test_root_pages_link_what_exists(page):
    """Links of the pages GitHub shows at the root (the site checks its own): each file exists
    and each anchor is a heading of it, as GitHub spells anchors."""
    for target, anchor in re.findall(r"\]\(([^)#:]+)(?:#([^)]*))?\)", (ROOT / page).read_text()):
        assert (ROOT / target).exists(), f"{page} links a missing {target}"
        if anchor:
            headings = re.findall(r"^#+ (.+)$", (ROOT / target).read_text(), re.M)
            assert anchor in map(github_anchor, headings), f"{page}: {target}#{anchor}"


def test_readme_example_is_the_shipped_plugin():
    shipped = (ROOT / "examples/plugin-repo/plugins/energy.py").read_text()
    code = shipped[shipped.index('"""', 3) + 3 :].strip()  # without the module's docstring
    blocks = re.findall(r"^```python\n(.*?)^```$", README.read_text(), re.M | re.S)
    assert code + "\n" in blocks


def test_no_page_counts_the_tests():
    """A new test changes no prose: no page states how many tests there are."""
    counted = re.compile(r"\b\d[\d,]* (?:tests|test items)\b|\b\d[\d,]* of them\b", re.I)
    for page in PAGES:
        assert not counted.search(page.read_text()), page.relative_to(ROOT)


@pytest.mark.parametrize(
    ("subject", "refused"),
    [("Catch SystemExit in plugin code", False), ("x" * 72, False), ("x" * 73, True),
     ("µ" * 72, False), ("µ" * 73, True)],
)  # fmt: skip
def test_commit_msg_hook_keeps_subjects_to_72_characters(tmp_path, subject, refused):
    pygrep = pytest.importorskip("pre_commit.languages.pygrep")  # the dev extra
    config = yaml.safe_load((ROOT / ".pre-commit-config.yaml").read_text())
    assert "commit-msg" in config["default_install_hook_types"]
    (hook,) = [h for r in config["repos"] for h in r["hooks"] if h["id"] == "subject-length"]
    assert hook["language"] == "pygrep" and hook["stages"] == ["commit-msg"]
    message = tmp_path / "COMMIT_EDITMSG"
    message.write_text(
        f"{subject}\n\nThe why, in a body line longer than the subject may be{'.' * 40}\n"
    )
    # called as pre-commit calls it: the options, the pattern, the file
    assert bool(pygrep.main([*hook["args"], hook["entry"], str(message)])) == refused


@pytest.mark.parametrize("tool", ["detector_page", "figure_page"])
def test_generated_reference_page_is_what_its_generator_writes(tool):
    """The reference pages of what the code declares (the registry's detectors, the results
    schema's figures) are written from it, never by hand, so none goes stale."""
    import importlib

    generator = importlib.import_module(tool)  # docs/tools, on pytest's pythonpath
    page = (ROOT / generator.PAGE).read_text()
    assert page == generator.page(), (
        f"{generator.PAGE} is stale: python docs/tools/{tool}.py > {generator.PAGE}"
    )


def test_every_docs_path_named_in_the_repository_exists():
    """A page moved or renamed leaves no reference to its old path behind: every
    ``docs/...`` file a tracked file names (in code, tests, scripts or pages) is there."""
    import subprocess

    tracked = subprocess.run(
        ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    named = re.compile(r"(?<![\w./-])docs/[\w./-]+\.(?:md|txt|png|py)\b")
    missing = {}
    for name in tracked:
        path = ROOT / name
        if path.suffix not in (".py", ".md", ".toml", ".yml", ".yaml", ".sh", ".txt"):
            continue
        for found in named.findall(path.read_text(errors="replace")):
            if not (ROOT / found).exists():
                missing.setdefault(found, []).append(name)
    assert not missing, f"docs paths named but not there: {missing}"


def test_performance_page_is_what_the_gpu_check_renders():
    """docs/studies/performance.md is rendered from the committed runs it names, never edited by hand."""
    import benchmod  # tests/, on pytest's pythonpath

    gpu_check = benchmod.load("gpu_check")
    page = (ROOT / "docs" / "studies" / "performance.md").read_text()
    results = ROOT / "benchmarks" / "results"
    files = [results / name for name in re.findall(r"^## `(gpu_check-[\w-]+\.json)`$", page, re.M)]
    assert files, "docs/studies/performance.md names no gpu_check run"
    assert page == gpu_check.render(files) + "\n", (
        "docs/studies/performance.md is stale: python benchmarks/gpu_check.py --render "
        + " ".join(f"benchmarks/results/{f.name}" for f in files)
        + " docs/studies/performance.md"
    )


def test_the_readmes_docs_command_silences_the_themes_banner():
    """mkdocs-material prints an end-of-life banner unless NO_MKDOCS_2_WARNING=1 (.ci/run sets it)."""
    commands = re.findall(r"`([^`]*mkdocs (?:serve|build)[^`]*)`", README.read_text())
    assert commands and all("NO_MKDOCS_2_WARNING=1 mkdocs" in c for c in commands)
