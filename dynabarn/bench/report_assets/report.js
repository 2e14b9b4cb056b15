// The sweep report's behaviour: the grid of worlds x planners x trials (one sort for all
// planners, filters, a cell opens its episode), the CSV export and the charts (plotly.js,
// inlined before this script). Reads the JSON block; writes text only (textContent), never
// markup, so no text of a row becomes part of the page.
(function () {
  "use strict";
  const data = JSON.parse(document.getElementById("report-data").textContent);
  const ep = data.episodes;
  const count = ep.planner.length;
  const planners = data.planners;
  const worlds = data.worlds;

  // cells[world][planner] -> [episode index, ...] by seed
  const seeds = planners.map(function () { return []; });
  for (let i = 0; i < count; i++) {
    if (seeds[ep.planner[i]].indexOf(ep.seed[i]) < 0) { seeds[ep.planner[i]].push(ep.seed[i]); }
  }
  seeds.forEach(function (s) { s.sort(function (a, b) { return a - b; }); });
  const cells = worlds.map(function () { return planners.map(function () { return {}; }); });
  for (let i = 0; i < count; i++) { cells[ep.world[i]][ep.planner[i]][ep.seed[i]] = i; }
  function successes(w, p) {
    let k = 0;
    const byseed = cells[w][p];
    for (const s in byseed) { if (ep.outcome[byseed[s]] === 0) { k++; } }
    return k;
  }

  function el(tag, text, cls) {
    const node = document.createElement(tag);
    if (text !== undefined && text !== null) { node.textContent = String(text); }
    if (cls) { node.className = cls; }
    return node;
  }

  const grid = document.getElementById("grid");
  const state = { sort: "id", outcome: "", difficulty: "", shown: planners.map(function () { return true; }) };

  function order() {
    const index = worlds.map(function (_, i) { return i; });
    const key = state.sort;
    function value(w) {
      if (key === "id") { return worlds[w].id === null ? -1 : worlds[w].id; }
      if (key === "difficulty") { return worlds[w].rank; }
      if (key === "measured") { return worlds[w].measured === null ? -1 : -worlds[w].measured; }
      if (key === "successes") { return planners.reduce(function (t, _, p) { return t + successes(w, p); }, 0); }
      return successes(w, +key.split(":")[1]);
    }
    index.sort(function (a, b) {
      const d = value(a) - value(b);
      return d !== 0 ? d : a - b;
    });
    return index;
  }

  function draw() {
    grid.textContent = "";
    const head = el("thead");
    const groups = el("tr");
    const trials = el("tr");
    ["world", "difficulty", "measured"].forEach(function (h) {
      const th = el("th", h);
      th.rowSpan = 2;
      groups.appendChild(th);
    });
    planners.forEach(function (p, pi) {
      if (!state.shown[pi]) { return; }
      const th = el("th", p, "group");
      th.colSpan = seeds[pi].length;
      th.dataset.planner = p;
      groups.appendChild(th);
      seeds[pi].forEach(function (s, k) { trials.appendChild(el("th", s, k === 0 ? "seed first" : "seed")); });
    });
    head.appendChild(groups);
    head.appendChild(trials);
    grid.appendChild(head);
    const body = el("tbody");
    order().forEach(function (w) {
      const world = worlds[w];
      if (state.difficulty && world.difficulty !== state.difficulty) { return; }
      const tr = el("tr");
      tr.dataset.world = world.name;
      tr.appendChild(el("th", world.name));
      tr.appendChild(el("td", world.difficulty));
      tr.appendChild(el("td", world.measured === null ? "-" : world.measured.toFixed(2), "num"));
      planners.forEach(function (p, pi) {
        if (!state.shown[pi]) { return; }
        tr.dataset["s" + pi] = successes(w, pi);
        seeds[pi].forEach(function (s, k) {
          const i = cells[w][pi][s];
          const td = el("td", null, "cell" + (k === 0 ? " first" : ""));
          if (i === undefined) {
            td.classList.add("missing");
            td.dataset.outcome = "none";
          } else {
            const outcome = data.outcomes[ep.outcome[i]];
            td.classList.add(outcome);
            td.dataset.outcome = outcome;
            td.dataset.episode = i;
            td.title = p + " · seed " + s + ": " + outcome + "; " + ep.reason[i];
            if (state.outcome && outcome !== state.outcome) { td.classList.add("dim"); }
          }
          tr.appendChild(td);
        });
      });
      body.appendChild(tr);
    });
    grid.appendChild(body);
  }

  function fmt(value) {
    if (value === null || value === undefined) { return "-"; }
    return Math.abs(value) >= 100 ? value.toFixed(1) : value.toFixed(3);
  }

  function openEpisode(i) {
    const panel = document.getElementById("episode");
    const world = worlds[ep.world[i]];
    document.getElementById("episode-title").textContent =
      planners[ep.planner[i]] + " · " + world.name + " · seed " + ep.seed[i];
    document.getElementById("episode-outcome").textContent = data.outcomes[ep.outcome[i]] + ": " + ep.reason[i];
    const metrics = document.getElementById("episode-metrics");
    metrics.textContent = "";
    data.metrics.forEach(function (m) {
      const tr = el("tr");
      tr.appendChild(el("th", m.name + (m.unit ? " [" + m.unit + "]" : "")));
      tr.appendChild(el("td", fmt(ep[m.name][i]), "num"));
      metrics.appendChild(tr);
    });
    const r = ep.recording[i] >= 0 ? data.recordings[ep.recording[i]] : null;
    const still = document.getElementById("episode-still");
    still.hidden = !(r && r.still);
    if (r && r.still) { still.src = r.still; }
    document.getElementById("episode-replay").hidden = !r;
    document.getElementById("episode-unrecorded").hidden = !!r;
    if (r) {
      document.getElementById("episode-command").textContent = r.command;
      document.getElementById("episode-mcap").href = r.href;
    }
    panel.dataset.episode = i;
    panel.hidden = false;
  }

  grid.addEventListener("click", function (event) {
    const td = event.target.closest("td.cell");
    if (td && td.dataset.episode !== undefined) { openEpisode(+td.dataset.episode); }
  });
  document.getElementById("close-episode").addEventListener("click", function () {
    document.getElementById("episode").hidden = true;
  });
  document.getElementById("sort").addEventListener("change", function (e) { state.sort = e.target.value; draw(); });
  document.getElementById("outcome").addEventListener("change", function (e) { state.outcome = e.target.value; draw(); });
  document.getElementById("difficulty").addEventListener("change", function (e) {
    state.difficulty = e.target.value;
    draw();
  });
  document.getElementById("planners").addEventListener("change", function (e) {
    state.shown[+e.target.value] = e.target.checked;
    draw();
  });

  function csvField(value) {
    const text = value === null || value === undefined ? "" : String(value);
    // Quoted, and a leading = + - @ neutralised: a spreadsheet must not run a row's text.
    const safe = /^[=+\-@\t\r]/.test(text) && isNaN(Number(text)) ? "'" + text : text;
    return "\"" + safe.replace(/"/g, "\"\"") + "\"";
  }
  document.getElementById("csv").addEventListener("click", function () {
    const names = data.metrics.map(function (m) { return m.name; });
    const lines = [["planner", "world", "world_id", "difficulty", "seed", "outcome", "reason"].concat(names).join(",")];
    for (let i = 0; i < count; i++) {
      const world = worlds[ep.world[i]];
      lines.push([planners[ep.planner[i]], world.name, world.id, world.difficulty, ep.seed[i],
        data.outcomes[ep.outcome[i]], ep.reason[i]].concat(names.map(function (m) { return ep[m][i]; }))
        .map(csvField).join(","));
    }
    const link = document.createElement("a");
    link.href = URL.createObjectURL(new Blob([lines.join("\n") + "\n"], { type: "text/csv" }));
    link.download = "episodes.csv";
    document.body.appendChild(link);
    link.click();
    link.remove();
  });

  draw();
  document.body.dataset.gridMs = Math.round(performance.now());
  // The charts once plotly.js (after this script: the grid shows before its 5 MB are read) is in.
  window.addEventListener("load", charts);

  function charts() {
  document.body.dataset.loadMs = Math.round(performance.now());
  if (typeof window.Plotly === "undefined") {
    document.getElementById("charts-missing").hidden = false;
    return;
  }
  const Plotly = window.Plotly;
  const config = { displayModeBar: false, responsive: true };
  const layout = { margin: { l: 55, r: 10, t: 10, b: 45 }, height: 380, legend: { orientation: "h", y: -0.2 } };
  function colour(p) { return data.colours[p] || "#444"; }
  function errors(points) {
    return {
      type: "data", symmetric: false,
      array: points.map(function (q) { return q.hi - q.rate; }),
      arrayminus: points.map(function (q) { return q.rate - q.lo; }),
    };
  }

  const difficulty = data.difficulty_chart;
  if (difficulty) {
    const traces = planners.filter(function (p) { return difficulty.series[p]; }).map(function (p) {
      const points = difficulty.series[p];
      return {
        type: "scatter", mode: "lines+markers", name: p,
        x: points.map(function (q) { return q.x; }), y: points.map(function (q) { return q.rate; }),
        error_y: errors(points), line: { color: colour(p), dash: p === data.floor ? "dash" : "solid" },
        customdata: points.map(function (q) { return [q.lo, q.hi, q.n]; }),
        hovertemplate: p + ": %{y:.2f} [%{customdata[0]:.2f}, %{customdata[1]:.2f}] of %{customdata[2]} episodes<extra></extra>",
      };
    });
    Plotly.newPlot("chart-difficulty", traces, Object.assign({}, layout, {
      xaxis: { title: { text: "corridor blocked (bins of equal world counts)" } },
      yaxis: { title: { text: "success" }, range: [-0.02, 1.02] },
    }), config);
  } else {
    document.getElementById("chart-difficulty-none").hidden = false;
  }

  const fig5 = data.fig5;
  const bars = planners.filter(function (p) { return fig5.series[p]; }).map(function (p) {
    const points = fig5.groups.map(function (g) { return fig5.series[p][g] || { rate: null, lo: 0, hi: 0, n: 0 }; });
    return {
      type: "bar", name: p, x: fig5.groups, y: points.map(function (q) { return q.rate; }),
      marker: { color: colour(p) }, error_y: errors(points),
      customdata: points.map(function (q) { return [q.lo, q.hi, q.n]; }),
      hovertemplate: p + " %{x}: %{y:.2f} [%{customdata[0]:.2f}, %{customdata[1]:.2f}] of %{customdata[2]}<extra></extra>",
    };
  });
  fig5.paper_planners.forEach(function (p) {
    const ys = fig5.groups.map(function (g) { return fig5.series[p][g] ? fig5.series[p][g].paper : null; });
    if (ys.some(function (y) { return y !== null; })) {
      bars.push({ type: "scatter", mode: "markers", name: p + " (paper)", x: fig5.groups, y: ys,
        marker: { symbol: "x", size: 11, color: colour(p) } });
    }
  });
  Plotly.newPlot("chart-fig5", bars, Object.assign({}, layout, {
    barmode: "group", yaxis: { title: { text: "success" }, range: [0, 1.05] },
  }), config);

  function distribution(metric) {
    const traces = planners.map(function (p, pi) {
      const ys = [];
      for (let i = 0; i < count; i++) {
        const v = ep[metric][i];
        if (ep.planner[i] === pi && v !== null && (metric !== "time" || ep.outcome[i] === 0)) { ys.push(v); }
      }
      return { type: "box", name: p, y: ys, marker: { color: colour(p) }, boxpoints: false };
    });
    Plotly.react("chart-distribution", traces, Object.assign({}, layout, { showlegend: false }), config);
  }
  const metric = document.getElementById("metric");
  metric.addEventListener("change", function () { distribution(metric.value); });
  distribution(metric.value);
  document.body.dataset.chartsMs = Math.round(performance.now());
  document.body.dataset.charts = "drawn";
  }
})();
