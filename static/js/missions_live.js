/* A mission's page, live: the plan and each drone's path on the map, progress per drone,
   steps, events and picture thumbnails, refreshed on every push from /ws/missions/<id>/. */
(function () {
  "use strict";
  const M = window.SkyhiveMissions;
  const config = JSON.parse(document.getElementById("mission-config").textContent);
  const map = M.makeMap("mission-map", config);
  map.setView(config.center, 17);
  const planLayer = L.layerGroup().addTo(map);
  const pathLayer = L.layerGroup().addTo(map);
  const pictureLayer = L.layerGroup().addTo(map);
  let fitted = false;
  let pending = null;

  function render(log) {
    const status = document.getElementById("mission-status");
    status.textContent = log.mission.status;
    status.className = `badge ${log.mission.status}`;
    planLayer.clearLayers();
    pathLayer.clearLayers();
    const plan = log.steps.filter((s) => s.command === "navigate").map((s) => [s.params.lat, s.params.lon]);
    if (plan.length) {
      L.polyline(plan, { color: "#999", weight: 1, dashArray: "4 4" }).addTo(planLayer);
      if (!fitted) { map.fitBounds(L.latLngBounds(plan).pad(0.2)); fitted = true; }
    }
    const paths = new Map();
    for (const event of log.events) {
      if (event.type !== "step" || !event.position || !event.drone_id) continue;
      if (!paths.has(event.drone_id)) paths.set(event.drone_id, []);
      paths.get(event.drone_id).push([event.position.lat, event.position.lon]);
    }
    for (const [drone, points] of paths) {
      const colour = M.colourFor(drone);
      L.polyline(points, { color: colour, weight: 3 }).addTo(pathLayer).bindTooltip(drone);
      L.circleMarker(points[points.length - 1], { radius: 6, color: colour, fillOpacity: 0.9 }).addTo(pathLayer).bindTooltip(drone);
    }
    for (const event of log.events) {
      if ((event.type === "alarm" || event.type === "handover") && event.position) {
        L.marker([event.position.lat, event.position.lon], { title: event.message }).addTo(pathLayer).bindTooltip(M.escapeHtml(event.message));
      }
    }
    renderDrones(log);
    renderSteps(log);
    renderEvents(log);
  }

  function renderDrones(log) {
    const body = document.querySelector("#drone-progress tbody");
    body.replaceChildren();
    for (const a of log.assignments) {
      const mine = new Set([...a.preparation, ...a.step_indexes]);
      const done = log.steps.filter((s) => mine.has(s.index) && s.status === "completed" && s.drone_id === a.drone_id);
      const last = done.sort((x, y) => (x.ended_at || "").localeCompare(y.ended_at || "")).pop();
      const row = document.createElement("tr");
      row.dataset.drone = a.drone_id;
      const swatch = `<span class="swatch" style="background:${M.colourFor(a.drone_id)}"></span>`;
      const state = a.held && ["sent", "accepted"].includes(a.status) ? `${a.status} (holding)` : a.status;
      row.innerHTML = `<td>${swatch}${M.escapeHtml(a.drone_id)}</td><td>${a.reason}</td><td class="assignment">${state}</td>` +
        `<td class="done">${done.length} / ${mine.size}</td><td>${last ? `#${last.index} ${M.escapeHtml(last.command)}` : "–"}</td>`;
      body.append(row);
    }
  }

  function renderSteps(log) {
    const body = document.querySelector("#step-table tbody");
    body.replaceChildren();
    for (const s of log.steps) {
      const row = document.createElement("tr");
      row.dataset.index = s.index;
      row.className = `step-${s.status}`;
      row.innerHTML = `<td>${s.index}</td><td>${M.escapeHtml(s.command)}</td><td class="status">${s.status}</td>` +
        `<td class="drone">${M.escapeHtml(s.drone_id || "–")}</td><td class="duration">${M.seconds(s.duration_s)}</td>`;
      body.append(row);
    }
  }

  function renderEvents(log) {
    const list = document.getElementById("event-list");
    list.replaceChildren();
    for (const e of log.events.slice(-300).reverse()) {
      const item = document.createElement("li");
      item.className = `event-${e.type}`;
      item.textContent = `${(e.at || "").slice(11, 19)} ${e.type} ${e.drone_id || ""} ${e.message || ""}`;
      list.append(item);
    }
  }

  async function refresh() {
    pending = null;
    try { render(await M.api("GET", config.logApi)); } catch (error) { /* next push retries */ }
  }

  async function refreshPictures() {
    let rows = [];
    try { rows = await M.api("GET", `${config.missionApi}pictures/`); } catch (error) { return; }
    pictureLayer.clearLayers();
    const strip = document.getElementById("thumbnails");
    strip.replaceChildren();
    for (const p of rows) {
      const img = `<a href="${p.url}"><img src="${p.thumbnail_url}" alt="${M.escapeHtml(p.name)}" loading="lazy"></a>`;
      strip.insertAdjacentHTML("beforeend", img);
      if (p.lat !== null) {
        const icon = L.divIcon({ className: "thumb-marker", html: `<img src="${p.thumbnail_url}" alt="">`, iconSize: [32, 24] });
        L.marker([p.lat, p.lon], { icon, title: p.name }).addTo(pictureLayer).bindPopup(img);
      }
    }
  }

  function schedule() {
    if (!pending) pending = setTimeout(refresh, 300);
  }

  const live = document.getElementById("live-status");
  M.liveSocket(config.socket, (message) => {
    if (message.type === "picture") refreshPictures();
    if (message.type === "event" && (message.kind === "mission" || message.kind === "operator")) syncHeld();
    schedule();
  }, (up) => { live.textContent = up ? "live" : "reconnecting…"; live.className = `badge ${up ? "ok" : "off"}`; });

  const stop = document.getElementById("stop-mission");
  if (stop) {
    stop.addEventListener("click", async () => {
      if (!confirm("Stop every drone of this mission?")) return;
      const box = document.getElementById("mission-error");
      try { await M.api("POST", `${config.missionApi}stop/`); box.hidden = true; stop.remove(); }
      catch (error) { box.textContent = error.message; box.hidden = false; }
      refresh();
    });
  }
  /* Pause holds every drone of the mission where it is; Resume lets each carry on from its
     step. One click each: neither starts a motor. */
  const pause = document.getElementById("pause-mission");
  const resume = document.getElementById("resume-mission");
  function showHeld(held) {
    if (pause) pause.hidden = held;
    if (resume) resume.hidden = !held;
  }
  /* Resume is offered while the mission is paused or any of its drones holds (a drone
     held from its own page holds alone; its companions fly on). */
  function anyHeld(mission) {
    return mission.held || (mission.assignments || []).some((a) => a.held && ["sent", "accepted"].includes(a.status));
  }
  async function syncHeld() {
    if (!pause && !resume) return;
    try { showHeld(anyHeld(await M.api("GET", config.missionApi))); } catch (error) { /* next push retries */ }
  }
  for (const button of [pause, resume]) {
    if (!button) continue;
    button.addEventListener("click", async () => {
      const box = document.getElementById("mission-error");
      button.disabled = true;
      try {
        const mission = await M.api("POST", `${config.missionApi}${button.dataset.action}/`);
        showHeld(anyHeld(mission));
        box.hidden = true;
      } catch (error) { box.textContent = error.message; box.hidden = false; }
      button.disabled = false;
      refresh();
    });
  }
  /* A draft starts with the nearest available drone. Steps beyond the envelope's defaults
     (409 confirmation_required) start only once CONFIRM has been typed. */
  const start = document.getElementById("start-mission");
  async function startMission(confirmed) {
    const box = document.getElementById("mission-error");
    start.disabled = true;
    try {
      await M.api("POST", `${config.missionApi}start/`, confirmed ? { confirm_beyond_defaults: true } : {});
      location.reload();
      return;
    } catch (error) {
      if (error.code === "confirmation_required") {
        document.getElementById("beyond-defaults-message").textContent = error.message;
        document.getElementById("beyond-defaults-typed").value = "";
        document.getElementById("beyond-defaults").hidden = false;
        box.hidden = true;
      } else { box.textContent = error.message; box.hidden = false; }
    }
    start.disabled = false;
  }
  if (start) {
    start.addEventListener("click", () => startMission(false));
    document.getElementById("beyond-defaults-send").addEventListener("click", () => {
      const box = document.getElementById("mission-error");
      if (document.getElementById("beyond-defaults-typed").value.trim() !== "CONFIRM") {
        box.textContent = "Not started: type CONFIRM to fly beyond the envelope's defaults.";
        box.hidden = false;
        return;
      }
      document.getElementById("beyond-defaults").hidden = true;
      startMission(true);
    });
    document.getElementById("beyond-defaults-cancel").addEventListener("click", () => {
      document.getElementById("beyond-defaults").hidden = true;
    });
  }

  refresh();
  refreshPictures();
  syncHeld();
  window.skyhiveMission = { map, refresh };
})();
