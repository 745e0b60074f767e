// The site's pages: each reads window.SITE (written into the page) and draws with Plotly once
// window.plotlyReady (assets/plotly.js) has it. Text from the data is set as text, never as HTML.
"use strict";

function el(tag, attrs, text) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
  if (text !== undefined && text !== null) node.textContent = String(text);
  return node;
}

function fmt(value, digits) {
  return value === null || value === undefined ? "" : Number(value).toFixed(digits);
}

// A table whose rows a text box filters and whose columns a click on the header sorts.
function table(where, spec, filterBox) {
  const tbl = el("table");
  const head = el("tr");
  spec.columns.forEach((name, i) => {
    const th = el("th", {}, name);
    th.addEventListener("click", () => sortBy(i));
    head.appendChild(th);
  });
  tbl.appendChild(el("thead")).appendChild(head);
  const body = tbl.appendChild(el("tbody"));
  let rows = spec.rows.slice();
  let order = 1;
  function draw() {
    body.textContent = "";
    const needle = filterBox ? filterBox.value.toLowerCase() : "";
    for (const row of rows) {
      if (needle && !row.join(" ").toLowerCase().includes(needle)) continue;
      const tr = body.appendChild(el("tr"));
      row.forEach((cell, i) => {
        const td = tr.appendChild(el("td", {}, cell));
        if (typeof cell === "number") td.className = "num";
        if (spec.link && i === spec.link.column) {
          td.textContent = "";
          td.appendChild(el("a", { href: spec.link.href + encodeURIComponent(spec.link.ids[spec.rows.indexOf(row)]) }, cell));
        }
        if (cell === "regressed" || cell === "improved") td.className = cell;
      });
    }
  }
  function sortBy(i) {
    order = -order;
    rows.sort((a, b) => (a[i] > b[i] ? order : a[i] < b[i] ? -order : 0));
    draw();
  }
  if (filterBox) filterBox.addEventListener("input", draw);
  draw();
  // a narrow screen scrolls the table, never the page: every column stays reachable
  where.appendChild(el("div", { class: "scroll" })).appendChild(tbl);
}

// Legends in rows that wrap: above the plot at a desktop's width; under it at a phone's,
// where the modebar (top right) would cover the entries of a legend above.
const PHONE = window.matchMedia("(max-width: 600px)");
function legend() {
  return PHONE.matches
    ? { orientation: "h", x: 0, xanchor: "left", yref: "container", y: 0, yanchor: "bottom" }
    : { orientation: "h", x: 0, xanchor: "left", y: 1.02, yanchor: "bottom" };
}
PHONE.addEventListener("change", () => {
  for (const p of document.querySelectorAll(".js-plotly-plot")) {
    if (p.layout && p.layout.showlegend !== false) window.Plotly.relayout(p, { legend: legend() });
  }
});

// One plot per protocol: each detector's mean over cells by commit, confirmed steps marked.
function protocolPlots(site, Plotly) {
  const where = document.getElementById("protocols");
  for (const [i, p] of site.protocols.entries()) {
    where.appendChild(el("h2", {}, p.protocol));
    const steps = p.steps.map((st) => `${st.commit}: ${st.regressed} regressed, ${st.improved} improved, ${st.judged}`);
    where.appendChild(el("p", { class: "note" }, `${p.figure}.` + (steps.length
      ? ` Confirmed steps (dotted lines): ${steps.join("; ")}.` : " No confirmed step.")));
    const id = `protocol-${i}`;
    where.appendChild(el("div", { id, class: "plot" }));
    const traces = p.traces.map((t) => ({
      type: "scatter", mode: "lines+markers", name: t.name, x: t.x, y: t.y,
      text: t.x.map((r) => `${site.runs[r][0]} ${site.runs[r][1]}`),
      hovertemplate: "%{text}<br>%{y:.2f}<extra>%{fullData.name}</extra>",
    }));
    const shapes = p.steps.map((st) => ({
      type: "line", x0: st.run - 0.5, x1: st.run - 0.5, yref: "paper", y0: 0, y1: 1,
      line: { color: st.regressed ? "#c00" : "#080", dash: "dot" },
    }));
    const annotations = p.steps.map((st) => ({
      x: st.run - 0.5, yref: "paper", y: 0.98, yanchor: "top", showarrow: false,
      text: st.commit, font: { color: st.regressed ? "#c00" : "#080" },
    }));
    Plotly.newPlot(id, traces, {
      xaxis: { title: { text: "commit (oldest first)" }, automargin: true, tickvals: p.axis.tickvals, ticktext: p.axis.ticktext },
      yaxis: { title: { text: p.figure.split(",")[0] } }, legend: legend(),
      shapes, annotations, margin: { t: 30, r: 10 },
    }, { responsive: true });
  }
}

function indexPage(site, Plotly) {
  const box = document.getElementById("filter");
  table(document.getElementById("leaderboard"), site.leaderboard, box);
  const steps = document.getElementById("steps");
  if (site.steps.rows.length) table(steps, site.steps, box);
  else steps.appendChild(el("p", { class: "note" }, site.steps.none));
  const byDetector = {};
  for (const row of site.leaderboard.rows) {
    (byDetector[row[1]] = byDetector[row[1]] || { x: [], y: [] });
    byDetector[row[1]].x.push(row[0]);
    byDetector[row[1]].y.push(row[3]);
  }
  const traces = Object.entries(byDetector).map(([name, d]) => ({ type: "bar", name, x: d.x, y: d.y }));
  Plotly.newPlot("overview", traces, {
    barmode: "group", xaxis: { automargin: true }, yaxis: { title: { text: site.leaderboard.columns[3] } },
    legend: legend(), margin: { t: 20, r: 10 },
  }, { responsive: true });
  if (site.protocols) protocolPlots(site, Plotly);
}

function comparePage(site, Plotly) {
  const [a, b, fig] = ["left", "right", "figure"].map((id) => document.getElementById(id));
  site.detectors.forEach((d, i) => {
    a.appendChild(el("option", { value: d }, d));
    b.appendChild(el("option", { value: d }, d));
  });
  if (site.detectors.length > 1) b.selectedIndex = 1;
  site.figures.forEach((f) => fig.appendChild(el("option", { value: f }, f)));
  const where = document.getElementById("pairs");
  function draw() {
    const f = site.figures.indexOf(fig.value);
    // the protocol named only where the run holds several
    const several = new Set(site.cells.map((c) => c[0])).size > 1;
    const of = (d) => Object.fromEntries(site.cells.filter((c) => c[2] === d)
      .map((c) => [several ? c[0] + " · " + c[1] : c[1], c[3 + f]]));
    const left = of(a.value), right = of(b.value);
    const shared = Object.keys(left).filter((k) => k in right);
    const rows = shared.map((k) => [k, left[k], right[k], Number(fmt(right[k] - left[k], 2))]);
    where.textContent = "";
    const note = document.getElementById("shared");
    note.textContent = `${shared.length} cells both ran; ${fig.value} in points, ${b.value} − ${a.value}.`;
    table(where, { columns: ["cell", a.value, b.value, "difference"], rows }, null);
    // one bar a row, its cell's label beside it: long labels stay readable at any width
    Plotly.react("difference", [{
      type: "bar", orientation: "h", y: shared, x: rows.map((r) => r[3]),
    }], {
      xaxis: { title: { text: `${b.value} − ${a.value} (points)` } },
      yaxis: { automargin: true, autorange: "reversed", tickfont: { size: 11 } },
      height: 120 + 18 * shared.length, margin: { t: 20, r: 10 },
    }, { responsive: true });
  }
  [a, b, fig].forEach((s) => s.addEventListener("change", draw));
  draw();
}

function seriesPage(site, Plotly) {
  const pick = document.getElementById("series");
  const box = document.getElementById("filter");
  function options() {
    const needle = box.value.toLowerCase();
    const current = pick.value;
    pick.textContent = "";
    for (const s of site.series) {
      const text = `${s.figure} · ${s.label}${s.steps.length ? " (" + s.steps.length + " steps)" : ""}`;
      if (needle && !text.toLowerCase().includes(needle)) continue;
      pick.appendChild(el("option", { value: s.id }, text));
    }
    if ([...pick.options].some((o) => o.value === current)) pick.value = current;
  }
  function draw() {
    const s = site.series.find((x) => x.id === pick.value);
    if (!s) return;
    const commit = (r) => site.runs[r][0];
    const x = s.points.map((p) => p[0]);
    const traces = [{
      type: "scatter", mode: "markers", name: "commits", x,
      y: s.points.map((p) => p[1]),
      error_y: { type: "data", array: s.points.map((p) => 1.96 * p[2]), visible: true, thickness: 1 },
      text: x.map((r) => `${commit(r)} ${site.runs[r][1]}`),
      hovertemplate: "%{text}<br>%{y:.2f}<extra></extra>",
    }];
    s.segments.forEach(([from, to, mean], i) => traces.push({
      type: "scatter", mode: "lines", x: [from, to], y: [mean, mean], showlegend: i === 0,
      name: "segment mean", line: { color: "#555" }, hoverinfo: "skip",
    }));
    const shapes = s.steps.map((st) => ({
      type: "line", x0: st.run - 0.5, x1: st.run - 0.5, yref: "paper", y0: 0, y1: 1,
      line: { color: st.verdict === "regressed" ? "#c00" : "#080", dash: "dot" },
    }));
    const annotations = s.steps.map((st) => ({
      x: st.run - 0.5, yref: "paper", y: 1.02, showarrow: false,
      text: `${commit(st.run)} ${st.change}`,
    }));
    Plotly.react("plot", traces, {
      xaxis: { title: { text: "commit (oldest first)" }, automargin: true, tickvals: s.axis.tickvals, ticktext: s.axis.ticktext },
      yaxis: { title: { text: s.unit } }, legend: legend(), shapes, annotations, margin: { t: 40, r: 10 },
    }, { responsive: true });
    document.getElementById("about").textContent = s.about;
    history.replaceState(null, "", "#" + s.id);
  }
  box.addEventListener("input", () => { options(); draw(); });
  pick.addEventListener("change", draw);
  options();
  const wanted = decodeURIComponent(location.hash.slice(1));
  if (wanted && site.series.some((s) => s.id === wanted)) pick.value = wanted;
  draw();
}

window.plotlyReady.then((Plotly) => {
  const site = window.SITE;
  ({ index: indexPage, compare: comparePage, series: seriesPage })[site.page](site, Plotly);
  document.body.setAttribute("data-drawn", "yes");
});
