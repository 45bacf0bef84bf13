// The spectrum of the plotted quantities: their power spectral density (Welch, from
// GET /api/v1/logs/{id}/spectrum/) over the selected interval, else the visible window,
// drawn on a logarithmic axis against frequency.

import { escapeHtml, getJSON } from "./api.js";
import { formatAxis, formatNumber } from "./plots.js";

export class SpectrumView {
  constructor(card, viewer) {
    this.card = card;
    this.viewer = viewer;
    this.el = card.querySelector("[data-part=spectrum]");
    this.note = card.querySelector("[data-part=spectrum-note]");
    this.u = null;
  }

  async show(lines) {
    this.card.hidden = false;
    const state = this.viewer.state;
    const [start, end] = state.selection || state.view;
    const paths = lines.slice(0, 6).map((l) => l.path);
    if (!paths.length) {
      this.note.textContent = "Tick a quantity to see its spectrum.";
      return;
    }
    this.note.textContent = "Computing…";
    try {
      const body = await getJSON(`${this.viewer.api}spectrum/`, { series: paths.join(","), start, end });
      this.draw(body.series, lines);
      const first = body.series[0];
      this.note.textContent = `${formatNumber(end - start)} s from ${formatNumber(start - state.start)} s · ${formatNumber(first.fs)} Hz · ${first.segments} of ${first.segments_available} segments`;
      this.card.dataset.loaded = "true";
    } catch (err) {
      this.note.innerHTML = `<span class="error">${escapeHtml(err.message)}</span>`;
    }
  }

  draw(series, lines) {
    const freq = series[0].frequency;
    // Each series on the first one's frequencies (they differ only if the rates do).
    const data = [freq, ...series.map((s) => freq.map((f) => valueAt(s, f)))];
    this.u?.destroy();
    this.u = new uPlot(
      {
        width: Math.max(this.el.clientWidth, 200),
        height: 220,
        scales: { x: { time: false }, y: { distr: 3 } },
        series: [
          { label: "Hz", value: (u, v) => (v == null ? "–" : formatNumber(v)) },
          ...series.map((s, i) => ({ label: `${s.path} [${s.unit}]`, stroke: lines[i]?.color || "#2358d6", width: 1.2, points: { show: false }, value: (u, v) => (v == null ? "–" : formatNumber(v)) })),
        ],
        axes: [
          { label: "Hz", labelSize: 16, font: "11px system-ui", labelFont: "11px system-ui", grid: { stroke: "#eef0f3" } },
          // A log axis ticks every digit of each decade; only the decades are labelled.
          { font: "11px system-ui", size: 54, values: (u, ticks) => (ticks || []).map((t) => (Number.isInteger(Math.round(Math.log10(t) * 1e6) / 1e6) ? formatAxis(t) : "")), grid: { stroke: "#eef0f3" } },
        ],
      },
      data,
      this.el,
    );
  }
}

function valueAt(s, f) {
  const df = s.frequency[1] - s.frequency[0];
  const i = Math.round(f / df);
  const v = s.psd[i];
  return typeof v === "number" && v > 0 ? v : null;
}
