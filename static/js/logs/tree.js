// Every value at the selected time, as a tree of the log's groups.

import { escapeHtml, getJSON } from "./api.js";
import { formatNumber } from "./plots.js";
import { throttle } from "./state.js";

export class ValuesTree {
  constructor(el, filter, viewer) {
    this.el = el;
    this.filter = filter;
    this.viewer = viewer;
    this.closed = new Set();
    this.controller = null;
    this.values = null;
    this.load = throttle((t) => this.fetch(t), 120);
    viewer.state.on("cursor", ({ t }) => this.load(t));
    filter.addEventListener("input", () => this.applyFilter());
    // A click on a value adds its quantity to the multi-plot (or takes it out again).
    el.addEventListener("click", (event) => {
      const row = event.target.closest(".row");
      if (!row || !viewer.setPlotPaths) return;
      const paths = viewer.plotPaths();
      const path = row.dataset.path;
      viewer.setPlotPaths(paths.includes(path) ? paths.filter((p) => p !== path) : [...paths, path]);
    });
    el.addEventListener("toggle", (event) => {
      const path = event.target.dataset?.group;
      if (path === undefined) return;
      if (event.target.open) this.closed.delete(path);
      else this.closed.add(path);
    }, true);
    this.fetch(viewer.state.cursor);
  }

  async fetch(t) {
    this.controller?.abort();
    this.controller = new AbortController();
    try {
      const body = await getJSON(`${this.viewer.api}values/`, { t }, { signal: this.controller.signal });
      this.values = body.values;
      this.render(body.t);
    } catch (err) {
      if (err.name !== "AbortError") this.viewer.warn(`Values: ${err.message}`);
    }
  }

  render(t) {
    const units = this.viewer.units;
    const html = [];
    const walk = (node, prefix) => {
      for (const [name, entry] of Object.entries(node)) {
        const path = prefix ? `${prefix}/${name}` : name;
        if (entry && typeof entry === "object" && !("value" in entry && "t" in entry)) {
          const open = this.closed.has(path) ? "" : " open";
          html.push(`<details data-group="${escapeHtml(path)}"${open}><summary>${escapeHtml(name)}</summary>`);
          walk(entry, path);
          html.push("</details>");
        } else {
          const unit = units.get(path)?.unit || "";
          let value = '<span class="v none">–</span>';
          let title = `${path}: not recorded yet`;
          if (entry) {
            const shown = typeof entry.value === "number" ? formatNumber(entry.value) : String(entry.value);
            const label = entry.label ? ` (${escapeHtml(entry.label)})` : "";
            value = `<span class="v" data-value="${escapeHtml(entry.value)}">${escapeHtml(shown)}${label}${unit ? `<span class="u">${escapeHtml(unit)}</span>` : ""}</span>`;
            const clock = units.get(path)?.time_source === "board" ? "on-board clock" : "recorder clock";
            title = `${path} — sample at ${(entry.t - this.viewer.state.start).toFixed(3)} s (${clock}); click to plot`;
          }
          html.push(`<div class="row" data-path="${escapeHtml(path)}" title="${escapeHtml(title)}"><span class="k">${escapeHtml(name)}</span>${value}</div>`);
        }
      }
    };
    walk(this.values || {}, "");
    this.el.innerHTML = html.join("");
    this.el.dataset.t = String(t);
    this.applyFilter();
  }

  applyFilter() {
    const needle = this.filter.value.trim().toLowerCase();
    for (const row of this.el.querySelectorAll(".row")) {
      row.hidden = Boolean(needle) && !row.dataset.path.toLowerCase().includes(needle);
    }
    for (const group of [...this.el.querySelectorAll("details")].reverse()) {
      group.hidden = Boolean(needle) && !group.querySelector(".row:not([hidden])");
      if (needle && !group.hidden) group.open = true;
    }
  }
}
