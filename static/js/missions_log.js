/* The mission-log viewer: a dropped file is checked by the server (which says what is
   wrong with a bad one), a stored mission's log is fetched; each drone's path is drawn in
   its own colour with alarms and handovers marked, and the time of each stage listed. */
(function () {
  "use strict";
  const M = window.SkyhiveMissions;
  const config = JSON.parse(document.getElementById("viewer-config").textContent);
  const map = M.makeMap("log-map", config);
  map.setView(config.center, 17);
  const layer = L.layerGroup().addTo(map);
  const $ = (id) => document.getElementById(id);

  function showError(message) {
    $("viewer-error").textContent = message || "";
    $("viewer-error").hidden = !message;
  }

  function markerIcon(kind) {
    return L.divIcon({ className: `log-marker ${kind}`, html: kind === "alarm" ? "!" : "⇄", iconSize: [20, 20], iconAnchor: [10, 10] });
  }

  function stagesOf(log) {
    if (Array.isArray(log.stages) && log.stages.length) return log.stages;
    // Logs from elsewhere: one stage per completed step event.
    return log.events.filter((e) => e.type === "step" && e.status === "completed" && e.duration_s !== undefined)
      .map((e) => ({ drone_id: e.drone_id, stage: e.command || `#${e.index}`, steps: 1, duration_s: e.duration_s }));
  }

  function render(log, storedId = null) {
    showError("");
    layer.clearLayers();
    $("log-title").textContent = log.mission && log.mission.name ? `${log.mission.name} (${log.mission.status || "?"})` : "Mission log";
    const paths = new Map();
    const events = [...log.events].sort((a, b) => a.ts - b.ts);
    for (const e of events) {
      if (!e.position || !e.drone_id || (e.type && e.type !== "step")) continue;
      if (!paths.has(e.drone_id)) paths.set(e.drone_id, []);
      paths.get(e.drone_id).push([e.position.lat, e.position.lon]);
    }
    const bounds = [];
    const legend = $("legend");
    legend.replaceChildren();
    for (const [drone, points] of paths) {
      const colour = M.colourFor(drone);
      L.polyline(points, { color: colour, weight: 3, className: "drone-path" }).addTo(layer).bindTooltip(drone);
      L.circleMarker(points[0], { radius: 5, color: colour, fillColor: "#2ca02c", fillOpacity: 1 }).addTo(layer).bindTooltip(`${drone} start`);
      bounds.push(...points);
      const item = document.createElement("li");
      item.dataset.drone = drone;
      M.fill(item, `<span class="swatch" data-bg="${colour}"></span>${M.escapeHtml(drone)} · ${points.length} positions`);
      legend.append(item);
    }
    let marks = 0;
    for (const e of events) {
      const kind = e.type === "alarm" ? "alarm" : e.type === "handover" ? "handover" : null;
      const position = e.position || (e.data && e.data.position);
      if (!kind || !position) continue;
      L.marker([position.lat, position.lon], { icon: markerIcon(kind), title: e.message || kind }).addTo(layer)
        .bindTooltip(M.escapeHtml(e.message || kind));
      marks += 1;
    }
    M.fitTo(map, bounds);
    const body = document.querySelector("#stage-table tbody");
    body.replaceChildren();
    for (const s of stagesOf(log)) {
      const row = document.createElement("tr");
      M.fill(row, `<td><span class="swatch" data-bg="${M.colourFor(s.drone_id)}"></span>${M.escapeHtml(s.drone_id)}</td>` +
        `<td>${M.escapeHtml(s.stage)}${s.first_index !== undefined ? ` #${s.first_index}–${s.last_index}` : ""}</td><td>${s.steps}</td><td>${M.seconds(s.duration_s)}</td>`);
      body.append(row);
    }
    window.skyhiveLogViewer.shown = { drones: paths.size, marks, stages: body.children.length };
    // The time cursor, replay and recorded video (static/js/missions_log_time.js).
    window.skyhiveLogViewer.last = { log, mission: storedId };
    window.dispatchEvent(new CustomEvent("skyhive:mission-log", { detail: window.skyhiveLogViewer.last }));
  }

  async function openFile(file) {
    const form = new FormData();
    form.append("file", file);
    try { render(await M.api("POST", config.checkUrl, form)); }
    catch (error) { showError(`This file cannot be shown: ${error.message}`); }
  }

  async function openStored(id) {
    if (!id) return;
    try { render(await M.api("GET", config.logUrl.replace(config.placeholder, id)), id); }
    catch (error) { showError(error.message); }
  }

  const zone = $("drop-zone");
  zone.addEventListener("dragover", (event) => { event.preventDefault(); zone.classList.add("over"); });
  zone.addEventListener("dragleave", () => zone.classList.remove("over"));
  zone.addEventListener("drop", (event) => {
    event.preventDefault();
    zone.classList.remove("over");
    if (event.dataTransfer.files.length) openFile(event.dataTransfer.files[0]);
  });
  $("log-file").addEventListener("change", (event) => { if (event.target.files.length) openFile(event.target.files[0]); });
  $("stored-form").addEventListener("submit", (event) => { event.preventDefault(); openStored($("stored-mission").value); });
  window.skyhiveLogViewer = { map, shown: null };
  if (config.mission) openStored(config.mission);
})();
