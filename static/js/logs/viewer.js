// One log's viewer: waits for processing, then builds the timeline, values tree, quick
// plots, multi-plot, map and 3D attitude around one TimeState, and the replay controls.

import { escapeHtml, getJSON, watchProgress } from "./api.js";
import { HealthReport } from "./health.js";
import { MapView } from "./map.js";
import { Chart } from "./plots.js";
import { Replay } from "./replay.js";
import { SpectrumView } from "./spectrum.js";
import { formatDuration, PALETTE, TimeState } from "./state.js";
import { Timeline } from "./timeline.js";
import { ValuesTree } from "./tree.js";

const PLOTTABLE = new Set(["int", "double", "enum", "time"]);
const QUICK = [
  { key: "altitude", title: "Altitude" },
  { key: "velocity", title: "Velocity" },
  { key: "motors", title: "Motors" },
  { key: "battery", title: "Battery" },
];

export class LogViewer extends EventTarget {
  constructor(root) {
    super();
    this.root = root;
    this.api = root.dataset.api;
    this.wsPath = root.dataset.ws;
    this.compact = root.classList.contains("lv-compact");
    this.state = null;
  }

  part(name) {
    return this.root.querySelector(`[data-part="${name}"]`);
  }

  warn(message) {
    console.warn(`[${this.root.dataset.name}] ${message}`);
  }

  start() {
    const status = this.root.dataset.status;
    if (status === "ready") return this.load();
    if (status === "failed") return Promise.resolve();
    return new Promise((resolve) => {
      watchProgress(this.wsPath, this.api, (event) => {
        this.showProgress(event);
        if (event.status === "ready") this.load().then(resolve);
        else if (event.status !== "processing") resolve();
      });
    });
  }

  showProgress(event) {
    const badge = document.querySelector('[data-part="status-badge"]');
    if (event.status === "processing") {
      const value = Number(event.progress) || 0;
      this.part("progress").value = value;
      this.part("progress-text").textContent = value ? `${Math.round(value * 100)} %` : "Waiting for the import to start…";
      return;
    }
    this.part("processing").hidden = true;
    if (badge) {
      badge.textContent = event.status === "ready" ? "Ready" : event.status === "failed" ? "Failed" : event.status;
      badge.className = `badge ${event.status === "ready" ? "ok" : "bad"}`;
    }
    if (event.status !== "ready") {
      this.part("error").textContent = event.error || "This log is no longer available.";
      this.part("failed").hidden = false;
    }
  }

  async load() {
    this.info = await getJSON(this.api);
    if (this.info.status !== "ready") {
      this.showProgress(this.info);
      return;
    }
    const info = this.info;
    this.units = new Map(info.series.map((s) => [s.path, s]));
    this.state = new TimeState(info.start ?? 0, info.end ?? 1);
    // Open on the span of the streams with data, not on a lone early or late stamp (real
    // PX4 logs have topics stamped once, far from the flight); "Whole log" shows it all.
    const dense = info.layers.filter((l) => l.count >= 10 && l.start !== null);
    if (dense.length) {
      this.state.setView(Math.min(...dense.map((l) => l.start)), Math.max(...dense.map((l) => l.end)));
      this.state.setCursor(this.state.view[0], "force");
    }
    this.part("processing").hidden = true;
    this.part("body").hidden = false;
    this.health = new HealthReport(this.part("health"), this);
    this.bindToolbar();
    const plotted = new Promise((resolve) => this.addEventListener("plotted", resolve, { once: true }));
    this.buildQuickPlots();
    this.buildMultiPlot();
    this.timeline = new Timeline(this.part("timeline-canvas"), this);
    // From here the operator can act (the toolbar, the plots, the health report's links):
    // whatever follows the view, such as the page's address, starts now, not once loaded.
    this.dispatchEvent(new Event("interactive"));
    // The plots' series go first; the heavier requests (every value, the track, the
    // attitude and three.js) follow once a plot is drawn, or shortly after in any case.
    await Promise.race([plotted, new Promise((resolve) => setTimeout(resolve, 400))]);
    this.tree = new ValuesTree(this.part("tree"), this.part("tree-filter"), this);
    this.map = new MapView(this.part("map"), this, { title: this.part("map-title"), note: this.part("map-note") });
    import("./attitude.js").then(({ AttitudeView }) => {
      this.attitude = new AttitudeView(this.part("attitude"), this.part("angles"), this);
    });
    // The flight's recorded video, when the log's drone recorded any during the log.
    if (this.root.dataset.video) {
      import("./video.js").then(({ VideoPanel }) => {
        this.video = new VideoPanel(this.part("video-card"), this, this.root.dataset.video);
        return this.video.load();
      });
    }
    this.root.dataset.loaded = "true";
    this.dispatchEvent(new Event("loaded"));
  }

  bindToolbar() {
    const state = this.state;
    const clock = this.part("clock");
    const wall = this.part("wall");
    const selectionText = this.part("selection-text");
    // Logs stamped with Unix time (recorders, .tlog) also show the wall-clock time.
    const wallClock = state.start > 946684800;
    const showClock = () => {
      const since = `t = ${formatDuration(state.rel(state.cursor))}`;
      clock.textContent = since;
      if (wallClock) wall.textContent = new Date(state.cursor * 1000).toISOString().replace("T", " ").replace("Z", " UTC");
    };
    state.on("cursor", showClock);
    showClock();
    state.on("selection", ({ selection }) => {
      selectionText.textContent = selection
        ? `selected ${formatDuration(state.rel(selection[0]))} – ${formatDuration(state.rel(selection[1]))} (${(selection[1] - selection[0]).toFixed(3)} s)`
        : "";
    });
    this.replay = new Replay(this, { playButton: this.root.querySelector('[data-action="play"]'), speedSelect: this.part("speed") });
    const actions = {
      play: () => this.replay.toggle(),
      stop: () => this.replay.stop(),
      rewind: () => this.replay.rewind(),
      "zoom-selection": () => state.selection && state.setView(...state.selection),
      "clear-selection": () => state.setSelection(null),
      "zoom-reset": () => state.setView(state.start, state.end),
      spectrum: () => this.showSpectrum(),
    };
    this.root.addEventListener("click", (event) => {
      const action = event.target.closest("[data-action]")?.dataset.action;
      if (action && actions[action]) actions[action]();
    });
    this.root.addEventListener("keydown", (event) => {
      if (event.target.closest("input, select, textarea, button")) return;
      if (event.key === " ") { this.replay.toggle(); event.preventDefault(); }
      else if (event.key === "Home") { this.replay.rewind(); event.preventDefault(); }
    });
  }

  /** The spectrum of the plotted quantities over the selection (or the visible window). */
  showSpectrum() {
    this.spectrum ||= new SpectrumView(this.part("spectrum-card"), this);
    const lines = this.plotPaths().map((path) => this.multi.lines.find((l) => l.path === path) || { path });
    this.dispatchEvent(new Event("plotchange"));
    return this.spectrum.show(lines);
  }

  line(path, i) {
    const series = this.units.get(path);
    const name = path.split("/").slice(-1)[0];
    const unit = series?.unit || "";
    return { path, unit, label: unit ? `${name} [${unit}]` : name, color: PALETTE[i % PALETTE.length], scale: 1, offset: 0 };
  }

  buildQuickPlots() {
    const holder = this.part("quick");
    const special = this.info.special || {};
    for (const { key, title } of QUICK) {
      const card = document.createElement("div");
      card.className = "card";
      card.dataset.quick = key;
      const paths = (special[key] || []).filter((p) => PLOTTABLE.has(this.units.get(p)?.kind));
      const layer = paths.length ? paths[0].split("/").slice(0, -1).join("/") : "";
      card.innerHTML = `<div class="lv-head"><h2>${title}</h2><span class="empty">${escapeHtml(layer)}</span></div><div class="lv-chart"></div>`;
      holder.appendChild(card);
      const el = card.querySelector(".lv-chart");
      if (!paths.length) {
        el.innerHTML = `<p class="lv-missing">No ${title.toLowerCase()} in this log.</p>`;
        continue;
      }
      new Chart(el, this, { height: this.compact ? 130 : 150 }).setLines(paths.map((p, i) => this.line(p, i)));
    }
  }

  buildMultiPlot() {
    const picker = this.part("picker");
    const filter = this.part("picker-filter");
    const tbody = this.part("lines").querySelector("tbody");
    const chart = new Chart(this.part("multi"), this, { height: this.compact ? 200 : 260 });
    this.multi = chart;
    const normalise = this.part("normalise");
    normalise?.addEventListener("change", () => chart.setNormalise(normalise.checked));
    let lines = [];
    const series = this.info.series.filter((s) => PLOTTABLE.has(s.kind));
    const byLayer = new Map();
    for (const s of series) {
      const layer = s.path.split("/")[0];
      if (!byLayer.has(layer)) byLayer.set(layer, []);
      byLayer.get(layer).push(s);
    }
    const html = [];
    for (const [layer, members] of byLayer) {
      html.push(`<div class="layer">${escapeHtml(layer)}</div>`);
      for (const s of members) {
        const name = s.path.slice(layer.length + 1);
        html.push(`<label title="${escapeHtml(s.path)} · ${s.count} samples"><input type="checkbox" value="${escapeHtml(s.path)}"> ${escapeHtml(name)}${s.unit ? ` <span class="unit">${escapeHtml(s.unit)}</span>` : ""}</label>`);
      }
    }
    picker.innerHTML = html.join("");
    filter.addEventListener("input", () => {
      const needle = filter.value.trim().toLowerCase();
      for (const label of picker.querySelectorAll("label")) {
        label.hidden = Boolean(needle) && !label.title.toLowerCase().includes(needle);
      }
    });
    const renderRows = () => {
      tbody.innerHTML = lines
        .map(
          (line, i) => `<tr data-path="${escapeHtml(line.path)}">
            <td title="${escapeHtml(line.path)}"><span class="lv-swatch">●</span> ${escapeHtml(line.path)}</td>
            <td><input type="color" value="${line.color}" data-field="color" aria-label="Colour of ${escapeHtml(line.path)}"></td>
            <td><input type="number" step="any" value="${line.scale}" data-field="scale" aria-label="Scale of ${escapeHtml(line.path)}"></td>
            <td><input type="number" step="any" value="${line.offset}" data-field="offset" aria-label="Offset of ${escapeHtml(line.path)}"></td>
            <td><button type="button" data-remove="${i}" aria-label="Remove ${escapeHtml(line.path)}">×</button></td></tr>`,
        )
        .join("");
      // Each swatch in its line's colour, through the DOM: style attributes are refused.
      tbody.querySelectorAll(".lv-swatch").forEach((swatch, i) => { swatch.style.color = lines[i].color; });
    };
    const setPaths = (paths) => {
      const old = new Map(lines.map((l) => [l.path, l]));
      lines = paths.map((p, i) => old.get(p) || this.line(p, lines.length + i));
      renderRows();
      chart.setLines(lines.map((l) => ({ ...l, label: l.unit ? `${l.path} [${l.unit}]` : l.path })));
      this.dispatchEvent(new Event("plotchange"));
    };
    this.plotPaths = () => lines.map((l) => l.path);
    /** Plot exactly these quantities (unknown or unplottable paths are skipped). */
    this.setPlotPaths = (paths) => {
      const wanted = new Set(paths);
      for (const box of picker.querySelectorAll("input")) box.checked = wanted.has(box.value);
      setPaths(paths.filter((p) => PLOTTABLE.has(this.units.get(p)?.kind)));
    };
    picker.addEventListener("change", () => {
      setPaths([...picker.querySelectorAll("input:checked")].map((box) => box.value));
    });
    tbody.addEventListener("input", (event) => {
      const field = event.target.dataset.field;
      const row = event.target.closest("tr");
      if (!field || !row) return;
      const line = lines.find((l) => l.path === row.dataset.path);
      line[field] = field === "color" ? event.target.value : Number.parseFloat(event.target.value);
      if (field === "color") row.querySelector("span").style.color = line.color;
      chart.restyle(lines.map((l) => ({ ...l, label: l.unit ? `${l.path} [${l.unit}]` : l.path })));
    });
    tbody.addEventListener("click", (event) => {
      const index = event.target.dataset.remove;
      if (index === undefined) return;
      const path = lines[Number(index)].path;
      const box = [...picker.querySelectorAll("input")].find((b) => b.value === path);
      if (box) box.checked = false;
      setPaths(lines.filter((l) => l.path !== path).map((l) => l.path));
    });
    // Start with one quantity ticked, so the plot is never empty: the altitude if there
    // is one, else the first floating-point quantity.
    const special = this.info.special || {};
    const preferred =
      (special.altitude || [])[0] || series.find((s) => s.kind === "double")?.path || series[0]?.path;
    const box = [...picker.querySelectorAll("input")].find((b) => b.value === preferred);
    if (box) {
      box.checked = true;
      setPaths([box.value]);
    }
  }
}
