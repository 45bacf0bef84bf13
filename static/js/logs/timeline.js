// The timeline: one lane per message stream (layer), drawn from the server's per-bin sample
// counts for the visible window. Click selects a time, drag selects an interval, the wheel
// zooms around the pointer, dragging the ruler (or Shift+drag, or the middle button) pans.

import { getJSON } from "./api.js";
import { debounce, formatDuration, PALETTE } from "./state.js";

const RULER = 24;
const LANE = 16;
const GAP = 3;
const LABEL = 150;
const CLICK_SLOP = 4;

export class Timeline {
  constructor(canvas, viewer) {
    this.canvas = canvas;
    this.viewer = viewer;
    this.state = viewer.state;
    this.layers = viewer.info.layers.map((layer) => ({ name: layer.name, counts: [] }));
    this.labelWidth = viewer.compact ? 110 : LABEL;
    this.window = null;
    this.hover = null;
    this.drag = null;
    this.controller = null;
    this.fetchSoon = debounce(() => this.fetch(), 90);
    this.bindEvents();
    new ResizeObserver(() => this.resize()).observe(canvas.parentElement);
    canvas.parentElement.addEventListener("scroll", () => this.draw(), { passive: true });
    this.state.on("cursor", () => this.draw());
    this.state.on("selection", () => this.draw());
    this.state.on("view", () => { this.draw(); this.fetchSoon(); });
    this.resize();
  }

  get laneWidth() {
    return Math.max(this.width - this.labelWidth - 8, 50);
  }

  resize() {
    const width = this.canvas.parentElement.clientWidth;
    if (!width) return;
    const height = RULER + this.layers.length * (LANE + GAP) + 8;
    const dpr = window.devicePixelRatio || 1;
    // Names take at most 28 % of a narrow (phone, side-by-side) timeline.
    this.labelWidth = Math.min(this.viewer.compact ? 110 : LABEL, Math.round(width * 0.28));
    this.width = width;
    this.height = height;
    this.canvas.width = Math.round(width * dpr);
    this.canvas.height = Math.round(height * dpr);
    this.canvas.style.height = `${height}px`;
    this.ctx = this.canvas.getContext("2d");
    this.ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    this.draw();
    this.fetchSoon();
  }

  async fetch() {
    const [start, end] = this.state.view;
    this.controller?.abort();
    this.controller = new AbortController();
    const bins = Math.min(Math.round(this.laneWidth), 4000);
    try {
      const body = await getJSON(`${this.viewer.api}timeline/`, { start, end, bins }, { signal: this.controller.signal });
      const byName = new Map(body.layers.map((layer) => [layer.name, layer.counts]));
      for (const layer of this.layers) layer.counts = byName.get(layer.name) || [];
      this.window = [body.start, body.end];
      this.draw();
    } catch (err) {
      if (err.name !== "AbortError") this.viewer.warn(`Timeline: ${err.message}`);
    }
  }

  x(t) {
    const [a, b] = this.state.view;
    return this.labelWidth + ((t - a) / (b - a)) * this.laneWidth;
  }

  t(x) {
    const [a, b] = this.state.view;
    return a + ((x - this.labelWidth) / this.laneWidth) * (b - a);
  }

  draw() {
    const ctx = this.ctx;
    if (!ctx) return;
    const { width, height } = this;
    // The canvas scrolls inside its card when there are many layers; the ruler stays on top.
    const top = this.canvas.parentElement.scrollTop;
    ctx.clearRect(0, 0, width, height);
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, width, height);
    const ticks = this.ticks();
    ctx.fillStyle = "#f0f2f5";
    for (const { x } of ticks) ctx.fillRect(x, RULER, 1, height - RULER);
    this.drawLanes(ctx);
    this.drawRuler(ctx, top, ticks);
    const bottom = height - 4;
    const selection = this.state.selection;
    if (selection) {
      const x0 = Math.max(this.x(selection[0]), this.labelWidth);
      const x1 = Math.min(this.x(selection[1]), this.labelWidth + this.laneWidth);
      if (x1 > x0) {
        ctx.fillStyle = "rgba(35, 88, 214, 0.14)";
        ctx.fillRect(x0, 0, x1 - x0, bottom);
        ctx.fillStyle = "rgba(35, 88, 214, 0.7)";
        ctx.fillRect(x0, 0, 1, bottom);
        ctx.fillRect(x1 - 1, 0, 1, bottom);
      }
    }
    if (this.drag?.mode === "select" && this.drag.moved) {
      const x0 = Math.min(this.drag.x0, this.drag.x1);
      ctx.fillStyle = "rgba(35, 88, 214, 0.2)";
      ctx.fillRect(x0, top + RULER, Math.abs(this.drag.x1 - this.drag.x0), bottom - top - RULER);
    }
    if (this.hover !== null && !this.drag) {
      ctx.fillStyle = "rgba(16, 24, 40, 0.25)";
      ctx.fillRect(Math.round(this.hover), top + RULER, 1, bottom - top - RULER);
    }
    const cx = this.x(this.state.cursor);
    if (cx >= this.labelWidth && cx <= this.labelWidth + this.laneWidth) {
      ctx.fillStyle = "#d92d20";
      ctx.fillRect(Math.round(cx) - 1, 0, 2, bottom);
      ctx.beginPath();
      ctx.moveTo(cx - 5, top);
      ctx.lineTo(cx + 5, top);
      ctx.lineTo(cx, top + 7);
      ctx.fill();
    }
  }

  ticks() {
    const [a, b] = this.state.view;
    const step = niceStep((b - a) / Math.max(this.laneWidth / 90, 1));
    const digits = step >= 1 ? 0 : Math.min(Math.ceil(-Math.log10(step) - 1e-9), 6);
    const first = Math.ceil((a - this.state.start) / step) * step + this.state.start;
    const out = [];
    for (let t = first; t <= b + step * 1e-9; t += step) {
      out.push({ x: Math.round(this.x(t)), label: formatDuration(t - this.state.start, digits) });
    }
    return out;
  }

  drawRuler(ctx, top, ticks) {
    ctx.fillStyle = "#f6f7f9";
    ctx.fillRect(0, top, this.width, RULER);
    ctx.fillStyle = "#e3e6eb";
    ctx.fillRect(0, top + RULER - 1, this.width, 1);
    ctx.fillStyle = "#667085";
    ctx.font = "11px system-ui, sans-serif";
    ctx.textBaseline = "middle";
    const caption = `time since start · ${this.layers.length} stream${this.layers.length === 1 ? "" : "s"}`;
    ctx.fillText(ellipsis(ctx, caption, this.labelWidth - 12), 8, top + RULER / 2);
    for (const { x, label } of ticks) {
      ctx.fillStyle = "#c5cbd5";
      ctx.fillRect(x, top + RULER - 6, 1, 6);
      ctx.fillStyle = "#475467";
      ctx.fillText(label, x + 3, top + RULER / 2);
    }
  }

  drawLanes(ctx) {
    ctx.textBaseline = "middle";
    ctx.font = "12px system-ui, sans-serif";
    const laneWidth = this.laneWidth;
    this.layers.forEach((layer, i) => {
      const y = RULER + 4 + i * (LANE + GAP);
      ctx.fillStyle = i % 2 ? "#fafbfc" : "#f4f6f8";
      ctx.fillRect(this.labelWidth, y, laneWidth, LANE);
      ctx.fillStyle = "#344054";
      ctx.fillText(ellipsis(ctx, layer.name, this.labelWidth - 12), 8, y + LANE / 2);
      const counts = layer.counts;
      if (!counts.length || !this.window) return;
      // Bins were computed for this.window; while a new window loads, stretch the old one.
      const [wa, wb] = this.window;
      const binSpan = (wb - wa) / counts.length;
      const max = Math.max(...counts, 1);
      const colour = PALETTE[i % PALETTE.length];
      ctx.fillStyle = colour;
      for (let k = 0; k < counts.length; k++) {
        if (!counts[k]) continue;
        const x0 = this.x(wa + k * binSpan);
        const x1 = this.x(wa + (k + 1) * binSpan);
        if (x1 < this.labelWidth || x0 > this.labelWidth + laneWidth) continue;
        ctx.globalAlpha = 0.3 + (0.7 * Math.log1p(counts[k])) / Math.log1p(max);
        const left = Math.max(x0, this.labelWidth);
        ctx.fillRect(left, y + 2, Math.max(Math.min(x1, this.labelWidth + laneWidth) - left, 1), LANE - 4);
      }
      ctx.globalAlpha = 1;
    });
  }

  bindEvents() {
    const canvas = this.canvas;
    const pos = (event) => {
      const rect = canvas.getBoundingClientRect();
      return { x: event.clientX - rect.left, y: event.clientY - rect.top };
    };
    canvas.addEventListener("pointerdown", (event) => {
      const { x, y } = pos(event);
      canvas.setPointerCapture(event.pointerId);
      const pan = y - canvas.parentElement.scrollTop < RULER || event.shiftKey || event.button === 1 || event.button === 2;
      this.drag = { mode: pan ? "pan" : "select", x0: x, x1: x, moved: false, view: [...this.state.view] };
      if (pan) canvas.classList.add("panning");
      event.preventDefault();
    });
    canvas.addEventListener("pointermove", (event) => {
      const { x } = pos(event);
      this.hover = x >= this.labelWidth ? x : null;
      const drag = this.drag;
      if (!drag) { this.draw(); return; }
      drag.x1 = x;
      drag.moved = drag.moved || Math.abs(x - drag.x0) > CLICK_SLOP;
      if (drag.mode === "pan" && drag.moved) {
        const [a, b] = drag.view;
        const dt = ((drag.x0 - x) / this.laneWidth) * (b - a);
        this.state.setView(a + dt, b + dt);
      }
      this.draw();
    });
    const finish = (event) => {
      const drag = this.drag;
      if (!drag) return;
      this.drag = null;
      canvas.classList.remove("panning");
      const { x } = pos(event);
      if (drag.mode === "select") {
        if (drag.moved) this.state.setSelection(this.t(drag.x0), this.t(x));
        else if (x >= this.labelWidth) this.state.setCursor(this.t(x));
      }
      this.draw();
    };
    canvas.addEventListener("pointerup", finish);
    canvas.addEventListener("pointercancel", () => { this.drag = null; this.draw(); });
    canvas.addEventListener("pointerleave", () => { this.hover = null; this.draw(); });
    canvas.addEventListener("contextmenu", (event) => event.preventDefault());
    canvas.addEventListener("dblclick", () => this.state.setView(this.state.start, this.state.end));
    canvas.addEventListener("wheel", (event) => {
      const { x } = pos(event);
      if (x < this.labelWidth) return; // over the stream names the wheel scrolls the list
      event.preventDefault();
      const around = this.t(x);
      if (Math.abs(event.deltaX) > Math.abs(event.deltaY)) {
        const [a, b] = this.state.view;
        this.state.pan((event.deltaX / this.laneWidth) * (b - a));
      } else {
        this.state.zoom(Math.exp(event.deltaY * 0.0015), around);
      }
    }, { passive: false });
    canvas.addEventListener("keydown", (event) => {
      const [a, b] = this.state.view;
      const step = (b - a) / 50;
      if (event.key === "ArrowRight") this.state.setCursor(this.state.cursor + step);
      else if (event.key === "ArrowLeft") this.state.setCursor(this.state.cursor - step);
      else if (event.key === "+" || event.key === "=") this.state.zoom(0.7, this.state.cursor);
      else if (event.key === "-") this.state.zoom(1 / 0.7, this.state.cursor);
      else return;
      event.preventDefault();
    });
  }
}

function niceStep(raw) {
  const power = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * power >= raw) return m * power;
  return 10 * power;
}

function ellipsis(ctx, text, width) {
  if (ctx.measureText(text).width <= width) return text;
  let cut = text;
  while (cut.length > 1 && ctx.measureText(`${cut}…`).width > width) cut = cut.slice(0, -1);
  return `${cut}…`;
}
