// The log's health report at the top of the viewer: each automatic check with its
// coloured status, figure and reason, and a link to the moment and plot that show it
// (GET /api/v1/logs/{id}/checks/; docs/log-checks.md).

import { escapeHtml, getJSON } from "./api.js";
import { formatNumber } from "./plots.js";

/** A figure to three significant digits (a status row has room for little more). */
function short(v) {
  return typeof v === "number" && Number.isFinite(v) ? formatNumber(Number(v.toPrecision(3))) : "";
}

const LABELS = {
  vibration: "Vibration",
  clipping: "Clipping",
  gps: "GPS",
  battery_sag: "Battery sag",
  rc_loss: "RC loss",
  motor_imbalance: "Motors",
  estimator: "Estimator",
  failsafe: "Failsafe",
  cpu_load: "CPU load",
  logging_dropouts: "Logging gaps",
};
const STATUS = {
  pass: { badge: "ok", text: "pass" },
  warning: { badge: "warn", text: "warning" },
  fail: { badge: "bad", text: "fail" },
  not_checked: { badge: "off", text: "not checked" },
};
const ORDER = { fail: 0, warning: 1, pass: 2, not_checked: 3 };

export class HealthReport {
  constructor(root, viewer) {
    this.root = root;
    this.viewer = viewer;
    this.load();
  }

  async load() {
    this.root.hidden = false;
    try {
      const report = await getJSON(`${this.viewer.api}checks/`);
      this.render(report.checks);
    } catch (err) {
      this.root.querySelector("[data-part=health-body]").innerHTML = `<p class="error">The checks could not be read: ${escapeHtml(err.message)}</p>`;
    }
  }

  render(checks) {
    const counts = { fail: 0, warning: 0, pass: 0, not_checked: 0 };
    for (const c of checks) counts[c.status] += 1;
    const summary = this.root.querySelector("[data-part=health-summary]");
    summary.textContent = [
      counts.fail && `${counts.fail} failed`,
      counts.warning && `${counts.warning} warning${counts.warning > 1 ? "s" : ""}`,
      `${counts.pass} passed`,
      counts.not_checked && `${counts.not_checked} not checked`,
    ].filter(Boolean).join(" · ");
    const rows = [...checks].sort((a, b) => ORDER[a.status] - ORDER[b.status]).map((c) => {
      const status = STATUS[c.status] || STATUS.not_checked;
      const value = c.value == null ? "" : `${short(c.value)}${c.unit ? ` ${escapeHtml(c.unit)}` : ""}`;
      const at = c.t == null ? "" : `<a href="${escapeHtml(c.link)}" data-check-link="${escapeHtml(c.name)}" title="Open the plot at this moment">at ${formatNumber(c.t)} s</a>`;
      const plot = c.t == null && c.series.length ? `<a href="${escapeHtml(c.link)}" data-check-link="${escapeHtml(c.name)}">plot</a>` : "";
      return `<li class="lv-check ${status.badge}" data-check="${escapeHtml(c.name)}" data-status="${escapeHtml(c.status)}">
        <span class="badge ${status.badge}">${status.text}</span>
        <strong>${escapeHtml(LABELS[c.name] || c.name)}</strong>
        <span class="lv-check-value">${value}</span>
        <span class="lv-check-at">${at}${plot}</span>
        <span class="lv-check-reason">${escapeHtml(c.reason)}</span></li>`;
    });
    this.root.querySelector("[data-part=health-body]").innerHTML = `<ul class="lv-checks">${rows.join("")}</ul>`;
    this.root.dataset.loaded = "true";
  }
}
