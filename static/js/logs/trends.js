// The trends pages: each drone's (or each check's) figures over its flights, drawn from
// the page's own JSON (GET /api/v1/logs/trends/ gives the same), with the newest point
// and the drift limit marked.

const data = JSON.parse(document.getElementById("trend-data").textContent);

function seconds(iso) {
  return Date.parse(iso) / 1000;
}

function draw(el, points, drift) {
  if (!points.length || typeof uPlot === "undefined") return;
  const x = points.map((p) => seconds(p.at));
  const y = points.map((p) => p.value);
  const series = [{}, { label: points[0].unit || "value", stroke: "#2358d6", width: 1.5, points: { show: true, size: 4 } }];
  const columns = [x, y];
  const limit = drift.find((d) => d.basis === "own") || drift[0];
  if (limit) {
    series.push({ label: "limit", stroke: "#b54708", dash: [4, 4], width: 1, points: { show: false } });
    columns.push(x.map(() => limit.limit));
  }
  el.replaceChildren();
  new uPlot(
    {
      width: Math.max(el.clientWidth, 240),
      height: 120,
      legend: { show: false },
      scales: { x: { time: true } },
      series,
      axes: [{ font: "10px system-ui", size: 28 }, { font: "10px system-ui", size: 44 }],
    },
    columns,
    el,
  );
  el.dataset.points = String(points.length);
}

for (const el of document.querySelectorAll("[data-trend-drone]")) {
  const drone = data.drones[Number(el.dataset.trendDrone)];
  if (drone) draw(el, drone.points, drone.drift);
}
for (const el of document.querySelectorAll("[data-trend-check]")) {
  const check = data.checks[el.dataset.trendCheck];
  if (check) draw(el, check.points, check.drift);
}
