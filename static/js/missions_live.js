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
  const fenceLayer = L.layerGroup().addTo(map);
  const droneLayer = L.layerGroup().addTo(map);
  let fitted = false;
  let pending = null;
  let lastLog = null;
  const progress = new Map();

  /* The organisation's geofence: inclusion zones outlined, exclusion zones filled red. */
  function drawFence(fence) {
    if (!fence) return;
    for (const p of fence.polygons || []) {
      const style = p.inclusion ? { color: "#16a34a", weight: 2, fill: false } : { color: "#dc2626", weight: 1, fillOpacity: 0.2 };
      L.polygon(p.polygon, style).addTo(fenceLayer);
    }
    for (const c of fence.circles || []) {
      const style = c.inclusion ? { color: "#16a34a", weight: 2, fill: false } : { color: "#dc2626", weight: 1, fillOpacity: 0.2 };
      L.circle(c.circle.center, Object.assign({ radius: c.circle.radius }, style)).addTo(fenceLayer);
    }
  }
  drawFence(config.fence);

  /* Each drone live: its icon (state colour, heading arrow, altitude), its home and the
     track flown while the page is open. */
  const drones = new Map();
  function droneIcon(live) {
    const p = live.position || {};
    const alt = p.alt === null || p.alt === undefined ? "" : ` · ${Math.round(p.alt)} m`;
    return M.droneIcon(live, `${live.drone_id}${alt}`);
  }
  function showDrone(live) {
    const p = live.position;
    let d = drones.get(live.drone_id);
    if (!d) {
      d = { track: L.polyline([], { color: M.colourFor(live.drone_id), weight: 2, opacity: 0.7 }).addTo(droneLayer) };
      drones.set(live.drone_id, d);
    }
    if (live.home && !d.home) {
      const home = L.divIcon({ className: "home-marker", html: "H", iconSize: [18, 18] });
      d.home = L.marker(live.home, { icon: home, title: `home of ${live.drone_id}` }).addTo(droneLayer);
    }
    if (!p || p.lat === null || p.lat === undefined) return;
    if (!d.marker) {
      d.marker = L.marker([p.lat, p.lon], { icon: droneIcon(live), title: live.drone_id, zIndexOffset: 1000 }).addTo(droneLayer);
      // Selecting a drone on the map plays its live video (static/js/missions_video.js).
      d.marker.on("click", () => window.dispatchEvent(new CustomEvent("skyhive:select-drone", { detail: live.drone_id })));
    } else { d.marker.setLatLng([p.lat, p.lon]); d.marker.setIcon(droneIcon(live)); }
    d.state = live.state;
    const points = d.track.getLatLngs();
    const last = points[points.length - 1];
    if (!last || last.lat !== p.lat || last.lng !== p.lon) d.track.addLatLng([p.lat, p.lon]);
  }

  /* A progress bar per drone: steps done of its share, time still needed, battery now and
     at the end (and its margin over the reserve), from the server's estimate. */
  function percentText(v) { return v === null || v === undefined ? "–" : `${Math.round(v * 100)} %`; }
  function durationText(s) {
    if (s === null || s === undefined) return "–";
    const m = Math.floor(s / 60), r = Math.round(s % 60);
    return m ? `${m} min ${String(r).padStart(2, "0")} s` : `${r} s`;
  }
  function batteryText(p, margin) {
    if (p.battery_at_end === null || p.battery_at_end === undefined) {
      return `battery ${percentText(p.battery)} (drain not measured yet)`;
    }
    const sign = margin >= 0 ? "+" : "";
    return `battery ${percentText(p.battery)} → ${percentText(p.battery_at_end)} at the end ` +
      `(${sign}${Math.round(margin * 100)} % over the ${Math.round(config.reserve * 100)} % reserve)`;
  }

  function renderProgress() {
    const list = document.getElementById("progress-list");
    const items = [];
    for (const [droneId, p] of progress) {
      const share = p.steps_total ? p.steps_done / p.steps_total : 0;
      const margin = p.battery_margin;
      const tight = margin !== null && margin !== undefined && margin < 0;
      const item = document.createElement("li");
      item.className = "progress-item";
      item.dataset.drone = droneId;
      M.fill(item, `<div class="progress-head"><span class="swatch" data-bg="${M.colourFor(droneId)}"></span><strong>${M.escapeHtml(droneId)}</strong>` +
        ` <span class="muted">${M.escapeHtml(p.assignment_status)}</span> <span class="steps">${p.steps_done} / ${p.steps_total} steps</span></div>` +
        `<div class="progress-bar" role="progressbar" aria-valuemin="0" aria-valuemax="${p.steps_total}" aria-valuenow="${p.steps_done}"><span data-width="${(share * 100).toFixed(1)}%"></span></div>` +
        `<div class="progress-figures"><span class="time-left">${durationText(p.time_remaining_s)} left</span>` +
        `<span>${Math.round(p.remaining_m)} m to fly</span>` +
        `<span class="battery-end${tight ? " tight" : ""}">${batteryText(p, margin)}</span></div>`);
      items.push(item);
    }
    if (items.length) list.replaceChildren(...items);
    if (lastLog) renderSteps(lastLog);
  }

  function render(log) {
    const status = document.getElementById("mission-status");
    status.textContent = log.mission.status;
    status.className = `badge ${log.mission.status}`;
    planLayer.clearLayers();
    pathLayer.clearLayers();
    const plan = log.steps.filter((s) => s.command === "navigate").map((s) => [s.params.lat, s.params.lon]);
    if (plan.length) {
      L.polyline(plan, { color: "#999", weight: 1, dashArray: "4 4" }).addTo(planLayer);
      if (!fitted) { M.fitTo(map, plan); fitted = true; }
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
      const swatch = `<span class="swatch" data-bg="${M.colourFor(a.drone_id)}"></span>`;
      const state = a.held && ["sent", "accepted"].includes(a.status) ? `${a.status} (holding)` : a.status;
      M.fill(row, `<td>${swatch}${M.escapeHtml(a.drone_id)}</td><td>${a.reason}</td><td class="assignment">${state}</td>` +
        `<td class="done">${done.length} / ${mine.size}</td><td>${last ? `#${last.index} ${M.escapeHtml(last.command)}` : "–"}</td>`);
      body.append(row);
    }
  }

  /* The steps around each drone's current one (a few before, more after); the rest folded
     into "… n steps" rows, all of them one click away. */
  let showAll = false;
  const BEFORE = 2, AFTER = 5;
  function currentSteps(log) {
    const current = new Set();
    for (const p of progress.values()) if (p.current_step !== null && p.current_step !== undefined) current.add(p.current_step);
    if (!current.size) {
      const next = log.steps.find((s) => s.status !== "completed" && s.status !== "superseded");
      if (next) current.add(next.index);
    }
    return current;
  }
  function renderSteps(log) {
    lastLog = log;
    const body = document.querySelector("#step-table tbody");
    const current = currentSteps(log);
    const positions = log.steps.map((s, i) => (current.has(s.index) ? i : -1)).filter((i) => i >= 0);
    const near = (i) => positions.some((c) => i >= c - BEFORE && i <= c + AFTER);
    const rows = [];
    let folded = 0;
    const fold = () => {
      if (!folded) return;
      const gap = document.createElement("tr");
      gap.className = "step-gap";
      gap.innerHTML = `<td colspan="5">… ${folded} step${folded === 1 ? "" : "s"}</td>`;
      rows.push(gap);
      folded = 0;
    };
    log.steps.forEach((s, i) => {
      if (!showAll && positions.length && !near(i)) { folded += 1; return; }
      fold();
      const row = document.createElement("tr");
      row.dataset.index = s.index;
      row.className = `step-${s.status}${current.has(s.index) ? " step-current" : ""}`;
      row.innerHTML = `<td>${s.index}</td><td>${M.escapeHtml(s.command)}</td><td class="status">${s.status}</td>` +
        `<td class="drone">${M.escapeHtml(s.drone_id || "–")}</td><td class="duration">${M.seconds(s.duration_s)}</td>`;
      rows.push(row);
    });
    fold();
    body.replaceChildren(...rows);
    const done = log.steps.filter((s) => s.status === "completed" || s.status === "superseded").length;
    document.getElementById("steps-summary").textContent = `${done} of ${log.steps.length} steps done.`;
    const toggle = document.getElementById("steps-toggle");
    toggle.textContent = showAll ? "around the current steps" : `show all ${log.steps.length}`;
    toggle.setAttribute("aria-expanded", String(showAll));
  }
  document.getElementById("steps-toggle").addEventListener("click", () => { showAll = !showAll; if (lastLog) renderSteps(lastLog); });

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

  // Reads answer out of order under load: only the newest one asked for is drawn.
  let refreshes = 0;
  async function refresh() {
    pending = null;
    const asked = ++refreshes;
    let log;
    try { log = await M.api("GET", config.logApi); } catch (error) { return; /* next push retries */ }
    if (asked === refreshes) render(log);
  }

  async function refreshPictures() {
    let rows = [];
    try { rows = await M.api("GET", `${config.missionApi}pictures/`); } catch (error) { return; }
    pictureLayer.clearLayers();
    // The OpenDroneMap download is offered as soon as there is a picture to put in it.
    document.getElementById("odm-links").hidden = rows.length === 0;
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
    if (message.type === "progress") {
      for (const d of message.drones) {
        progress.set(d.progress.drone_id, d.progress);
        if (d.live && d.live.drone_id) showDrone(d.live);
      }
      renderProgress();
      return;
    }
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
  // As for the log: the newest answer (a read, or a pause's or resume's own) decides.
  let heldAsked = 0;
  async function syncHeld() {
    if (!pause && !resume) return;
    const asked = ++heldAsked;
    let mission;
    try { mission = await M.api("GET", config.missionApi); } catch (error) { return; /* next push retries */ }
    if (asked === heldAsked) showHeld(anyHeld(mission));
  }
  for (const button of [pause, resume]) {
    if (!button) continue;
    button.addEventListener("click", async () => {
      const box = document.getElementById("mission-error");
      button.disabled = true;
      try {
        const asked = ++heldAsked;
        const mission = await M.api("POST", `${config.missionApi}${button.dataset.action}/`);
        if (asked === heldAsked) showHeld(anyHeld(mission));
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
  window.skyhiveMission = {
    map, refresh,
    progress(id) { return progress.get(id) || null; },
    fenceShapes() { return fenceLayer.getLayers().length; },
    droneState(id) { const d = drones.get(id); return d ? d.state : null; },
    dronePosition(id) { const d = drones.get(id); return d && d.marker ? d.marker.getLatLng() : null; },
  };
})();
