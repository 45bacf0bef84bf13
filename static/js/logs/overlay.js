// Two logs on one time axis (aligned at each one's take-off, or at its start, and the
// second shifted by hand), the same series of both in one plot; and their parameters'
// differences, with each other or with the reference set of the first log's model.
// GET /api/v1/logs/{a}/compare/?with={b}, /series/, /parameters/?against=.

import { escapeHtml, getJSON, send } from "./api.js";

const root = document.getElementById("overlay");
const api = root.dataset.api;
const ids = [root.dataset.a, root.dataset.b];
const colours = ["#2358d6", "#c4320a"];
const els = {
  form: document.getElementById("overlay-form"),
  path: document.getElementById("overlay-path"),
  list: document.getElementById("overlay-series"),
  align: document.getElementById("overlay-align"),
  offset: document.getElementById("overlay-offset"),
  takeoff: document.getElementById("overlay-takeoff"),
  error: document.getElementById("overlay-error"),
  plot: document.getElementById("overlay-plot"),
};
let comparison = null;
let chart = null;

function showError(message) {
  els.error.textContent = message;
  els.error.hidden = !message;
}

/** Seconds of each log's clock at the shared axis' zero. */
function zeros() {
  const offset = Number(els.offset.value) || 0;
  return comparison.logs.map((log, i) => {
    const start = log.start ?? 0;
    const shift = els.align.value === "takeoff" ? log.takeoff.t : 0;
    return start + shift - (i === 1 ? offset : 0);
  });
}

/** One x column for both series: the union of their times, each series null elsewhere. */
function merge(a, b) {
  const points = [];
  a.t.forEach((t, i) => points.push([t, a.v[i], undefined]));
  b.t.forEach((t, i) => points.push([t, undefined, b.v[i]]));
  points.sort((p, q) => p[0] - q[0]);
  return [points.map((p) => p[0]), points.map((p) => (p[1] === undefined ? null : p[1])), points.map((p) => (p[2] === undefined ? null : p[2]))];
}

// Reads answer out of order under load: only the newest plot, and the newest parameters,
// asked for are drawn.
let drawsAsked = 0;
let parametersAsked = 0;

async function draw(event) {
  event?.preventDefault();
  const path = els.path.value.trim();
  if (!path) return;
  const asked = ++drawsAsked;
  showError("");
  try {
    const [za, zb] = zeros();
    const bodies = await Promise.all(ids.map((id) => getJSON(`${api}${id}/series/`, { path, points: 2000 })));
    if (asked !== drawsAsked) return;
    const shifted = bodies.map((body, i) => ({ t: body.t.map((t) => t - [za, zb][i]), v: body.v }));
    const columns = merge(shifted[0], shifted[1]);
    chart?.destroy();
    els.plot.replaceChildren();
    chart = new uPlot(
      {
        width: Math.max(els.plot.clientWidth, 320),
        height: 300,
        scales: { x: { time: false } },
        series: [
          { label: els.align.value === "takeoff" ? "s since take-off" : "s since start" },
          ...comparison.logs.map((log, i) => ({ label: `${i ? "B" : "A"} ${path} [${bodies[i].unit}]`, stroke: colours[i], width: 1.3, spanGaps: true, points: { show: false } })),
        ],
        axes: [{ label: "s", font: "11px system-ui" }, { font: "11px system-ui", size: 54 }],
      },
      columns,
      els.plot,
    );
    els.plot.dataset.series = String(chart.series.length - 1);
    els.plot.dataset.points = bodies.map((b) => b.t.length).join(",");
    els.plot.dataset.from = String(columns[0][0] ?? "");
  } catch (err) {
    if (asked === drawsAsked) showError(err.message);
  }
}

async function start() {
  try {
    comparison = await getJSON(`${api}${ids[0]}/compare/`, { with: ids[1] });
  } catch (err) {
    showError(err.message);
    return;
  }
  els.list.replaceChildren(...comparison.series.map((path) => Object.assign(document.createElement("option"), { value: path })));
  els.takeoff.textContent = comparison.logs
    .map((log, i) => `${i ? "B" : "A"} took off at ${log.takeoff.t.toFixed(2)} s (${log.takeoff.source})`)
    .join(" · ");
  if (!comparison.series.length) {
    showError("These two logs record no series in common.");
    return;
  }
  // The vibration metric first (what a comparison of two flights most often asks), then
  // an accelerometer, then whatever both recorded first.
  els.path.value =
    comparison.series.find((p) => /vibration/i.test(p)) || comparison.series.find((p) => /accel/i.test(p)) || comparison.series[0];
  els.form.addEventListener("submit", draw);
  els.align.addEventListener("change", draw);
  els.offset.addEventListener("change", draw);
  draw();
}

// --- parameters ---

const table = document.getElementById("param-diff");
const summary = document.getElementById("param-summary");

function cell(value) {
  return value === null || value === undefined ? '<td class="muted">—</td>' : `<td>${escapeHtml(value)}</td>`;
}

async function parameters(against) {
  const asked = ++parametersAsked;
  table.hidden = true;
  summary.textContent = "Reading the parameters…";
  try {
    const body = await getJSON(`${api}${ids[0]}/parameters/`, { against });
    if (asked !== parametersAsked) return;
    document.getElementById("param-b").textContent = body.b.kind === "reference" ? `Reference (${body.b.name || "saved"})` : "B";
    table.tBodies[0].innerHTML = body.differences
      .map((d) => `<tr data-change="${d.change}"><th scope="row">${escapeHtml(d.name)}</th>${cell(d.a)}${cell(d.b)}</tr>`)
      .join("");
    summary.textContent = `${body.differences.length} differ, ${body.same} the same (${body.a.source} against ${body.b.source}).`;
    table.hidden = !body.differences.length;
  } catch (err) {
    if (asked === parametersAsked) summary.textContent = err.message;
  }
}

for (const button of document.querySelectorAll("[data-against]")) {
  button.addEventListener("click", () => parameters(button.dataset.against));
}
document.getElementById("save-reference")?.addEventListener("click", async () => {
  try {
    await send("POST", `${api}${ids[0]}/reference/`);
    summary.textContent = "Saved as the reference of A's model.";
  } catch (err) {
    summary.textContent = err.message;
  }
});

start();
