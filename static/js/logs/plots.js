// Plots on uPlot: each line is a series fetched for the visible window with at most about
// one min/max pair per pixel, re-queried when the window changes. The time cursor and the
// selected interval are drawn on top; drag selects an interval, click sets the cursor.

import { getJSON } from "./api.js";
import { debounce, formatDuration } from "./state.js";

let firstPlotMarked = false;

function markFirstPlot(viewer) {
  viewer.dispatchEvent(new Event("plotted"));
  if (firstPlotMarked) return;
  firstPlotMarked = true;
  performance.mark("logs:first-plot");
  document.documentElement.dataset.firstPlot = String(Math.round(performance.now()));
}

/** lines: [{path, label, unit, color, scale, offset}]. Lines of one unit share a y axis
 *  labelled with it; each other unit (and each unitless line) gets its own, so 16 V and
 *  66 m are both readable. `normalise` maps every line to 0–1 on one axis instead. */
export class Chart {
  constructor(el, viewer, { height = 170, lines = [], legend = true } = {}) {
    this.el = el;
    this.viewer = viewer;
    this.state = viewer.state;
    this.height = height;
    this.legend = legend;
    this.lines = lines;
    this.raw = new Map();
    this.normalise = false;
    this.u = null;
    this.controller = null;
    this.refreshSoon = debounce(() => this.refresh(), 120);
    this.state.on("view", () => { this.setRange(); this.refreshSoon(); });
    this.state.on("cursor", () => this.u?.redraw(false, false));
    this.state.on("selection", () => this.u?.redraw(false, false));
    new ResizeObserver(() => this.resize()).observe(el);
  }

  setNormalise(on) {
    this.normalise = on;
    this.rebuild();
  }

  /** The y scale of a line: its unit's (or its own when it has none), or the shared one. */
  scaleOf(line) {
    if (this.normalise) return "norm";
    return line.unit ? `unit:${line.unit}` : `line:${line.path}`;
  }

  setLines(lines) {
    this.lines = lines;
    this.rebuild();
    this.refresh();
  }

  /** Re-apply scale, offset or colour without fetching again. */
  restyle(lines) {
    this.lines = lines;
    this.rebuild();
  }

  get width() {
    return Math.max(this.el.clientWidth, 120);
  }

  async refresh() {
    if (!this.lines.length) { this.rebuild(); return; }
    const [start, end] = this.state.view;
    const points = Math.min(Math.max(Math.round(this.width), 100), 4000);
    // A resize by a few pixels or a repeated event must not abort an identical request.
    const key = `${start}|${end}|${Math.round(points / 50)}|${this.lines.map((l) => l.path).join(";")}`;
    if (key === this.key) return;
    this.key = key;
    this.controller?.abort();
    const controller = (this.controller = new AbortController());
    try {
      const results = await Promise.all(
        this.lines.map((line) =>
          getJSON(`${this.viewer.api}series/`, { path: line.path, start, end, points }, { signal: controller.signal }),
        ),
      );
      this.lines.forEach((line, i) => this.raw.set(line.path, results[i]));
      this.rebuild();
    } catch (err) {
      if (this.key === key) this.key = null;
      if (err.name !== "AbortError") this.viewer.warn(`Plot: ${err.message}`);
    }
  }

  data() {
    const start = this.state.start;
    const tables = this.lines.map((line) => {
      const raw = this.raw.get(line.path) || { t: [], v: [] };
      const scale = Number.isFinite(line.scale) ? line.scale : 1;
      const offset = Number.isFinite(line.offset) ? line.offset : 0;
      let v = raw.v.map((x) => (typeof x === "number" ? x * scale + offset : x === true ? scale + offset : x === false ? offset : null));
      if (this.normalise) v = normalised(v);
      return [raw.t.map((t) => t - start), v];
    });
    if (!tables.length) return [[]];
    if (tables.length === 1) return tables[0];
    return uPlot.join(tables);
  }

  rebuild() {
    const data = this.data();
    const signature = `${this.normalise}|` + this.lines.map((l) => `${l.path}|${l.color}|${l.label}|${l.unit}`).join(";");
    if (this.u && this.signature === signature) {
      this.u.setData(data, false);
      this.setRange();
    } else {
      this.u?.destroy();
      this.signature = signature;
      this.u = new uPlot(this.options(), data, this.el);
    }
    if (this.lines.length && data[0].length) markFirstPlot(this.viewer);
  }

  setRange() {
    if (!this.u) return;
    const [a, b] = this.state.view;
    this.u.setScale("x", { min: a - this.state.start, max: b - this.state.start });
  }

  resize() {
    if (this.u && this.el.clientWidth) {
      this.u.setSize({ width: this.width, height: this.height });
      this.refreshSoon();
    }
  }

  options() {
    const state = this.state;
    let down = null;
    return {
      width: this.width,
      height: this.height,
      legend: { show: this.legend, live: true },
      scales: {
        x: { time: false, auto: false, range: () => [state.view[0] - state.start, state.view[1] - state.start] },
        ...Object.fromEntries(this.lines.map((line) => [this.scaleOf(line), { auto: true }])),
      },
      series: [
        { label: "time", value: (u, v) => (v == null ? "–" : formatDuration(v)) },
        ...this.lines.map((line) => ({
          label: line.label,
          scale: this.scaleOf(line),
          stroke: line.color,
          width: 1.4,
          spanGaps: true,
          points: { show: false },
          value: (u, v) => (v == null ? "–" : formatNumber(v)),
        })),
      ],
      axes: [
        {
          values: (u, ticks, axis, space, incr) => {
            const digits = incr >= 1 ? 0 : Math.min(Math.ceil(-Math.log10(incr) - 1e-9), 6);
            return (ticks || []).map((t) => formatDuration(t, digits));
          },
          size: 30,
          font: "11px system-ui",
          grid: { stroke: "#eef0f3" },
        },
        ...this.yAxes(),
      ],
      cursor: { drag: { x: true, y: false, setScale: false }, points: { size: 5 } },
      select: { show: true },
      hooks: {
        init: [
          (u) => {
            u.over.addEventListener("mousedown", (e) => { down = e.clientX; });
            u.over.addEventListener("click", (e) => {
              if (down !== null && Math.abs(e.clientX - down) > 4) return;
              const x = u.posToVal(u.cursor.left, "x");
              if (Number.isFinite(x)) state.setCursor(x + state.start);
            });
            u.over.addEventListener("wheel", (e) => {
              e.preventDefault();
              const x = u.posToVal(u.cursor.left, "x") + state.start;
              state.zoom(Math.exp(e.deltaY * 0.0015), Number.isFinite(x) ? x : undefined);
            }, { passive: false });
            u.over.addEventListener("dblclick", () => state.setView(state.start, state.end));
          },
        ],
        setSelect: [
          (u) => {
            if (u.select.width > 4) {
              const a = u.posToVal(u.select.left, "x") + state.start;
              const b = u.posToVal(u.select.left + u.select.width, "x") + state.start;
              state.setSelection(a, b);
            }
            u.setSelect({ left: 0, top: 0, width: 0, height: 0 }, false);
          },
        ],
        draw: [(u) => drawOverlay(u, state)],
      },
    };
  }
}

/** One y axis per scale, alternating left and right, labelled with the unit (in the line's
 *  colour when the scale has one line); only the first draws grid lines. */
Chart.prototype.yAxes = function yAxes() {
  const scales = [];
  for (const line of this.lines.length ? this.lines : [{ path: "", unit: "" }]) {
    const key = this.lines.length ? this.scaleOf(line) : "y";
    const found = scales.find((s) => s.key === key);
    if (found) found.lines.push(line);
    else scales.push({ key, lines: [line] });
  }
  return scales.map(({ key, lines }, i) => {
    const only = lines.length === 1 ? lines[0] : null;
    const unit = this.normalise ? "0–1" : lines[0].unit || (only ? only.label : "");
    return {
      scale: key,
      side: i % 2 ? 1 : 3,
      label: unit,
      labelSize: unit ? 16 : 0,
      labelFont: "11px system-ui",
      stroke: only && scales.length > 1 ? only.color : "#475467",
      // Wide enough for the longest tick label (about 6.5 px a character at 11 px).
      size: (u, values) => Math.max(34, ...(values || []).map((v) => String(v).length * 6.5 + 14)),
      font: "11px system-ui",
      grid: { show: i === 0, stroke: "#eef0f3" },
      values: (u, ticks) => (ticks || []).map(formatAxis),
    };
  });
};

function normalised(values) {
  const finite = values.filter((x) => typeof x === "number" && Number.isFinite(x));
  if (!finite.length) return values;
  let lo = Infinity, hi = -Infinity;
  for (const x of finite) { if (x < lo) lo = x; if (x > hi) hi = x; }
  const span = hi - lo || 1;
  return values.map((x) => (typeof x === "number" && Number.isFinite(x) ? (x - lo) / span : null));
}

function drawOverlay(u, state) {
  const ctx = u.ctx;
  const { top, height, left, width } = u.bbox;
  ctx.save();
  const selection = state.selection;
  if (selection) {
    const x0 = Math.max(u.valToPos(selection[0] - state.start, "x", true), left);
    const x1 = Math.min(u.valToPos(selection[1] - state.start, "x", true), left + width);
    if (x1 > x0) {
      ctx.fillStyle = "rgba(35, 88, 214, 0.12)";
      ctx.fillRect(x0, top, x1 - x0, height);
    }
  }
  const cx = u.valToPos(state.cursor - state.start, "x", true);
  if (cx >= left && cx <= left + width) {
    ctx.fillStyle = "#d92d20";
    ctx.fillRect(Math.round(cx) - 1, top, 2 * (window.devicePixelRatio || 1) * 0.75, height);
  }
  ctx.restore();
}

export function formatNumber(v) {
  if (typeof v !== "number" || !Number.isFinite(v)) return v == null ? "–" : String(v);
  const abs = Math.abs(v);
  if (abs !== 0 && (abs >= 1e6 || abs < 1e-3)) return v.toExponential(3);
  return Number(v.toPrecision(6)).toString();
}

const SI = [[1e12, "T"], [1e9, "G"], [1e6, "M"], [1e3, "k"], [1, ""], [1e-3, "m"], [1e-6, "µ"], [1e-9, "n"]];

/** Short tick labels: 1.5k, 250m, 6M — an axis has room for about five characters. */
export function formatAxis(v) {
  if (v === 0 || !Number.isFinite(v)) return String(v);
  const abs = Math.abs(v);
  if (abs >= 0.01 && abs < 10000) return Number(v.toPrecision(4)).toString();
  for (const [factor, prefix] of SI) {
    if (abs >= factor) return `${Number((v / factor).toPrecision(3))}${prefix}`;
  }
  return v.toExponential(1);
}
