"""The results site: pages that load nothing from the network, data that cannot break out of
its script, plotly written once; and, in a real headless Chromium, every page drawn with no
console error."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest
from historygen import run_folder

from slipbench.app.cli import main

PLOTTED = ("index.html", "compare.html", "series.html")
#: where the browser test keeps its screenshots (CI uploads the folder as an artifact)
SHOTS = "SLIPBENCH_SCREENSHOTS"
HOSTILE = 'holweg</script><script>alert("x")</script>'


def _cli(*args: str) -> int:
    with pytest.raises(SystemExit) as exit_:
        main(list(args))
        raise SystemExit(0)
    return int(exit_.value.code or 0)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """A history of 10 runs of two detectors (one with a hostile name), a 5-point drop of
    holweg from c05 on, and its site with the last run's report."""
    root = tmp_path_factory.mktemp("site")
    for i in range(10):
        # both detectors' cells in one results folder, each row with its digest (proven)
        both = run_folder(
            root / f"both{i}", seed=i, shift=-0.05 * (i >= 5), code=f"k{i}", cells=True
        )
        run_folder(both, seed=i, code=f"k{i}", detector=HOSTILE, cells=True)
        day = f"2026-02-{i + 1:02d}"
        assert (
            _cli(
                "history",
                "add",
                str(both),
                "--history",
                str(root / "h"),
                "--commit",
                f"c{i:02d}",
                "--date",
                day,
            )
            == 0
        )
    assert (
        _cli(
            "history",
            "page",
            "--history",
            str(root / "h"),
            "--results",
            str(both),
            "--out",
            str(root / "site"),
        )
        == 0
    )
    return root / "site"


@pytest.mark.slow
def test_every_page_loads_scripts_from_the_site_only(site):
    pages = sorted(p.name for p in site.glob("*.html"))
    assert pages == ["compare.html", "index.html", "report.html", "series.html"]
    for name in PLOTTED:
        text = (site / name).read_text()
        sources = re.findall(r'<script[^>]*src="([^"]+)"', text)
        assert sources == ["assets/plotly.js", "assets/site.js"]
        assert not re.search(r'(src|href)="(https?:)?//', text)
    report = (site / "report.html").read_text()
    assert "<script" not in report and not re.search(r'src="(https?:)?//', report)
    # plotly written once, gzipped: the whole site stays small
    assert len(list(site.rglob("plotly*"))) == 1
    total = sum(p.stat().st_size for p in site.rglob("*") if p.is_file())
    assert total < 5_000_000


@pytest.mark.slow
def test_names_cannot_break_out_of_the_page_data(site):
    text = (site / "compare.html").read_text()
    assert HOSTILE not in text and "\\u003c/script\\u003e\\u003cscript\\u003ealert" in text
    data = re.search(r"<script>window.SITE = (.*?);</script>", text, re.S)[1]
    assert HOSTILE in json.loads(data)["detectors"]


@pytest.mark.slow
def test_the_series_page_marks_the_confirmed_step(site):
    text = (site / "series.html").read_text()
    data = json.loads(re.search(r"<script>window.SITE = (.*?);</script>", text, re.S)[1])
    runs = data["runs"]
    stepped = [s for s in data["series"] if s["steps"]]
    assert stepped and all("holweg" in s["label"] and HOSTILE not in s["label"] for s in stepped)
    assert {runs[st["run"]][0] for s in stepped for st in s["steps"]} == {"c05"}
    assert all(len(s["segments"]) == 2 for s in stepped)
    assert all("c05<br>2026-02-06" in s["axis"]["ticktext"] for s in stepped)
    index = (site / "index.html").read_text()
    assert "c05" in index and "regressed" in index
    # the landing page: the protocol's plot over commits, its step marked at its commit
    (protocol,) = _data(site / "index.html")["protocols"]
    assert protocol["protocol"] == "window-size"
    assert {t["name"] for t in protocol["traces"]} == {"holweg", HOSTILE}
    assert [(st["commit"], st["improved"]) for st in protocol["steps"]] == [("c05", 0)]
    assert protocol["steps"][0]["regressed"] > 0
    assert protocol["axis"]["ticktext"][0] == "c00<br>2026-02-01"


def _data(page: Path) -> dict:
    return json.loads(
        re.search(r"<script>window.SITE = (.*?);</script>", page.read_text(), re.S)[1]
    )


def _strings(value) -> list[str]:
    if isinstance(value, dict):
        return [s for v in value.values() for s in _strings(v)]
    if isinstance(value, list):
        return [s for v in value for s in _strings(v)]
    return [value] if isinstance(value, str) else []


@pytest.mark.slow
def test_no_page_names_a_cell_in_json_and_headers_name_commits_not_folders(site):
    for name in PLOTTED:
        raw = [s for s in _strings(_data(site / name)) if '{"' in s]
        assert not raw, (name, raw[:3])
        text = (site / name).read_text()
        assert "History h:" not in text and "Latest run: both" not in text
        assert "from c00 (2026-02-01) to the latest commit, c09 (2026-02-10)" in text
    labels = {s["label"] for s in _data(site / "series.html")["series"]}
    assert "window-size · holweg · Nano17 Index window 50 · paper" in labels, sorted(labels)[:5]


@pytest.mark.slow
def test_one_results_folder_gets_its_pages(tmp_path):
    folder = run_folder(tmp_path / "r", seed=0, cells=True)
    assert _cli("history", "page", "--results", str(folder), "--out", str(tmp_path / "s")) == 0
    assert sorted(p.name for p in (tmp_path / "s").glob("*.html")) == [
        "compare.html",
        "index.html",
        "report.html",
    ]
    assert _cli("history", "page", "--out", str(tmp_path / "t")) == 2


def _site_of(tmp_path, folders) -> None:
    """A history of ``folders`` at commits c0, c1, ... dated a day apart, and its site in
    ``tmp_path / "s"``."""
    for i, folder in enumerate(folders):
        assert (
            _cli(
                "history",
                "add",
                str(folder),
                "--history",
                str(tmp_path / "h"),
                "--commit",
                f"c{i}",
                "--date",
                f"2026-03-0{i + 1}",
            )
            == 0
        )
    assert (
        _cli("history", "page", "--history", str(tmp_path / "h"), "--out", str(tmp_path / "s")) == 0
    )


def test_a_small_history_site_escapes_names_and_loads_local_scripts(tmp_path):
    _site_of(tmp_path, [run_folder(tmp_path / f"r{i}", seed=i, detector=HOSTILE) for i in range(4)])
    for name in PLOTTED:
        text = (tmp_path / "s" / name).read_text()
        assert re.findall(r'<script[^>]*src="([^"]+)"', text) == [
            "assets/plotly.js",
            "assets/site.js",
        ]
        assert HOSTILE not in text
        assert not [s for s in _strings(_data(tmp_path / "s" / name)) if '{"' in s]
    data = re.search(
        r"<script>window.SITE = (.*?);</script>",
        (tmp_path / "s" / "compare.html").read_text(),
        re.S,
    )[1]
    assert json.loads(data)["detectors"] == [HOSTILE]


def test_the_landing_page_shows_the_step_of_a_five_commit_history(tmp_path):
    """Five commits, holweg 5 points lower from the fourth: too short for the segment search,
    the step is judged on the runs' own intervals and the landing page names its commit and
    date, on the protocol's plot and in the steps table, and says how it was judged."""
    _site_of(
        tmp_path,
        [
            run_folder(tmp_path / f"r{i}", seed=i, shift=-0.05 * (i >= 3), code=f"k{i}")
            for i in range(5)
        ],
    )
    index = _data(tmp_path / "s" / "index.html")
    (protocol,) = index["protocols"]
    assert [st["commit"] for st in protocol["steps"]] == ["c3"]
    assert protocol["steps"][0]["regressed"] > 0 and protocol["steps"][0]["improved"] == 0
    assert "judged on the runs' own intervals" in protocol["steps"][0]["judged"]
    assert "c3<br>2026-03-04" in protocol["axis"]["ticktext"]
    steps = index["steps"]
    assert steps["rows"] and steps["columns"][-1] == "judged"
    # rows written directly, without digests: marked unproven, still named at their commit
    assert {(r[0], r[1][:10], r[2][:9]) for r in steps["rows"]} == {
        ("c3", "2026-03-04", "regressed")
    }
    assert all(r[-1].startswith("judged on the runs' own intervals") for r in steps["rows"])


def _browser():
    """A headless Chromium through selenium, or a skip naming what is missing."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed")
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if not (browser and driver):
        pytest.skip("no chromium and chromedriver here (apt-get install chromium chromium-driver)")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(driver), options=options)


@pytest.mark.slow
def test_pages_draw_in_a_real_browser_with_no_console_error(site):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    chrome = _browser()
    try:
        for name in PLOTTED:
            chrome.get((site / name).as_uri())
            WebDriverWait(chrome, 60).until(
                lambda d: d.find_element(By.TAG_NAME, "body").get_attribute("data-drawn") == "yes"
            )
            plots = chrome.find_elements(By.CSS_SELECTOR, ".js-plotly-plot")
            assert plots, f"{name}: no plot drawn"
            assert chrome.find_elements(By.CSS_SELECTOR, ".js-plotly-plot .main-svg")
            errors = [e for e in chrome.get_log("browser") if e["level"] == "SEVERE"]
            assert not errors, f"{name}: {errors}"
        chrome.get((site / "report.html").as_uri())
        assert chrome.find_elements(By.TAG_NAME, "table")
        assert not [e for e in chrome.get_log("browser") if e["level"] == "SEVERE"]
    finally:
        chrome.quit()


#: names that would change how a browser parses a page's inline data: "<!--<script>" holds the
#: element open past its "</script>" (the page's scripts become one), "</script>" ends it
TRICKY = ["x<!--<script>", "a</script><script>alert(1)</script>", "&amp;<!-- -->]]>&"]


def test_every_page_parses_as_a_browser_does_and_its_data_round_trips(tmp_path, monkeypatch):
    """Each page parsed by html5lib (the HTML standard's parsing algorithm, as browsers parse)
    with hostile detector and sensor names: the inline data is one script element of its own,
    followed by the two that load the site's scripts, and its JSON reads back as written."""
    import html5lib  # the test extra's: a page parsed as a browser parses it

    from slipbench.report import site as site_module

    written: dict[str, dict] = {}
    page = site_module._page

    def kept(name, about, body, data, pages):
        written[name] = json.loads(json.dumps(data))
        return page(name, about, body, data, pages)

    monkeypatch.setattr(site_module, "_page", kept)
    for i in range(4):
        folder = run_folder(
            tmp_path / f"r{i}", seed=i, detector=TRICKY[i % 3], sensor_instance=TRICKY[0]
        )
        argv = ["history", "add", str(folder), "--history", str(tmp_path / "h")]
        assert _cli(*argv, "--commit", f"c{i}", "--date", f"2026-03-0{i + 1}") == 0
    assert (
        _cli("history", "page", "--history", str(tmp_path / "h"), "--out", str(tmp_path / "s")) == 0
    )
    assert set(written) == set(PLOTTED)
    for name in PLOTTED:
        tree = html5lib.parse((tmp_path / "s" / name).read_text(), namespaceHTMLElements=False)
        scripts = list(tree.iter("script"))
        assert [s.get("src") for s in scripts] == [None, "assets/plotly.js", "assets/site.js"]
        text = scripts[0].text or ""
        assert text.startswith("window.SITE = ") and text.endswith(";"), (name, text[:80])
        assert json.loads(text[len("window.SITE = ") : -1]) == written[name]
        assert not scripts[1].text and not scripts[2].text
        assert tree.find("body/nav") is not None  # the page's body is still its own
    # the hostile names reached the data the parser read back
    assert TRICKY[0] in json.dumps(written["compare.html"], ensure_ascii=False)
    series = json.dumps(written["series.html"], ensure_ascii=False)
    assert all(n in series for n in TRICKY), series[:300]


def test_the_site_leaderboard_shows_the_constant_answer():
    """The site's sortable leaderboard sets the constant answer beside the accuracy, over the
    rows that give their test windows per class, and says whether the accuracy is above it."""
    from resultgen import fake_rows

    from slipbench.report.site import leaderboard as board

    rows = fake_rows("window-size", "holweg").head(4).assign(accuracy=0.6)
    rows["test_slip_windows"], rows["test_nonslip_windows"] = 20, 80
    out = board(rows)
    assert out["columns"][-2:] == ["Constant answer (%)", "Accuracy above it"]
    assert out["rows"][0][-2:] == [80.0, "no"]
    assert board(rows.assign(accuracy=0.9))["rows"][0][-1] == "yes"
    assert board(rows.drop(columns=["test_slip_windows"]))["rows"][0][-2:] == [None, "—"]


#: the legend entries a plot's modebar lies over (its buttons drawn over their names)
COVERED = """return [...document.querySelectorAll('.js-plotly-plot')].flatMap((plot) => {
  const bar = plot.querySelector('.modebar');
  if (!bar) return [];
  const m = bar.getBoundingClientRect();
  return [...plot.querySelectorAll('.legendtext')].filter((t) => {
    const r = t.getBoundingClientRect();
    return r.right > m.left && r.left < m.right && r.bottom > m.top && r.top < m.bottom;
  }).map((t) => t.textContent);
})"""


@pytest.mark.slow
def test_screenshots_at_1400_and_400_px_and_every_column_reachable(site, tmp_path_factory):
    """Every page drawn at a desktop's and a phone's width, each kept as a PNG under
    $SLIPBENCH_SCREENSHOTS (CI keeps the folder as an artifact; else a temporary folder, printed).
    At 400 px the page does not scroll sideways, the leaderboard's table does, so its last
    column can be reached, and every legend entry lies inside the window, clear of the
    modebar (at 400 px the legend sits under the plot)."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    shots = Path(os.environ.get(SHOTS) or tmp_path_factory.mktemp("screenshots"))
    shots.mkdir(parents=True, exist_ok=True)
    print(f"screenshots of the site in {shots}")
    chrome = _browser()
    try:
        for width in (1400, 400):
            chrome.set_window_size(width, 1000)
            for name in PLOTTED:
                chrome.get((site / name).as_uri())
                WebDriverWait(chrome, 60).until(
                    lambda d: (
                        d.find_element(By.TAG_NAME, "body").get_attribute("data-drawn") == "yes"
                    )
                )
                assert chrome.save_screenshot(str(shots / f"{name[:-5]}-{width}px.png"))
                inner, page = chrome.execute_script(
                    "const d = document.documentElement; return [d.clientWidth, d.scrollWidth]"
                )
                assert page <= inner, f"{name} at {width} px scrolls sideways ({page} > {inner})"
                outside = chrome.execute_script(
                    "return [...document.querySelectorAll('.legendtext')]"
                    ".filter((t) => t.getBoundingClientRect().right > window.innerWidth)"
                    ".map((t) => t.textContent)"
                )
                assert not outside, f"{name} at {width} px: legend entries cut off: {outside}"
                covered = chrome.execute_script(COVERED)
                assert not covered, f"{name} at {width} px: the modebar covers {covered}"
            chrome.get((site / "index.html").as_uri())
            WebDriverWait(chrome, 60).until(
                lambda d: d.find_element(By.TAG_NAME, "body").get_attribute("data-drawn") == "yes"
            )
            scroll, wide, right = chrome.execute_script(
                "const box = document.querySelector('#leaderboard .scroll');"
                "box.scrollLeft = box.scrollWidth;"
                "const last = box.querySelector('thead th:last-child');"
                "return [box.clientWidth, box.scrollWidth, last.getBoundingClientRect().right];"
            )
            assert right <= chrome.execute_script("return window.innerWidth"), (width, right)
            if width == 400:
                assert wide > scroll  # the table is wider than the phone: it scrolls, whole
        assert len(list(shots.glob("*.png"))) >= 6
    finally:
        chrome.quit()
