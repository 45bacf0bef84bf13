/* The fleet page: every drone on a Leaflet map (clustered, so thousands stay fluid) with
   its state, heading and altitude, and a paged, searchable table; both follow the live
   updates. */
(function () {
  "use strict";
  const config = JSON.parse(document.getElementById("fleet-config").textContent);
  const live = window.SkyhiveLive;
  const map = L.map("fleet-map", { zoomControl: true });
  if (config.tileUrl) {
    L.tileLayer(config.tileUrl, { maxZoom: 19, attribution: config.attribution }).addTo(map);
  }
  map.setView([38.7369, -9.1427], 13);
  L.control.scale({ imperial: false }).addTo(map);
  // States from least to most urgent: a cluster takes the colour of its most urgent drone.
  const URGENCY = ["on_ground", "armed", "airborne", "returning", "low_battery", "lost_link"];
  const clusters = L.markerClusterGroup({
    chunkedLoading: true,
    disableClusteringAtZoom: 17,
    showCoverageOnHover: false,
    maxClusterRadius: 50,
    iconCreateFunction(cluster) {
      let worst = 0;
      for (const m of cluster.getAllChildMarkers()) worst = Math.max(worst, URGENCY.indexOf(m.options.state));
      const n = cluster.getChildCount();
      return L.divIcon({ className: `drone-cluster state-${URGENCY[worst]}`, html: `<span>${n}</span>`, iconSize: [36, 36] });
    },
  }).addTo(map);
  const markers = new Map();
  let fitted = false;

  function iconKey(drone) {
    const p = drone.position || {};
    const h = drone.heading === null || drone.heading === undefined ? "" : Math.round(drone.heading / 5) * 5;
    return `${drone.state}|${h}|${p.alt === null || p.alt === undefined ? "" : Math.round(p.alt)}`;
  }

  function icon(drone) {
    const p = drone.position || {};
    const hasHeading = drone.heading !== null && drone.heading !== undefined;
    const arrow = hasHeading ? `<span class="arrow" style="transform: rotate(${Math.round(drone.heading)}deg)"></span>` : "";
    const alt = p.alt === null || p.alt === undefined ? "" : ` · ${Math.round(p.alt)} m`;
    return L.divIcon({
      className: `drone-marker state-${drone.state || "lost_link"}`,
      html: `${arrow}<span class="dot"></span><span class="label">${live.escapeHtml(drone.drone_id)}${alt}</span>`,
      iconSize: [18, 18],
      iconAnchor: [9, 9],
    });
  }

  function tooltip(drone) {
    return `<strong>${live.escapeHtml(drone.drone_id)}</strong> · ${live.stateLabel(drone.state)}<br>` +
      `${live.altitude(drone.position)} · ${live.speed(drone.ground_speed)} · ${live.heading(drone.heading)}<br>` +
      `battery ${live.batteryText(drone)} · step ${live.escapeHtml(live.missionStep(drone.mission))}`;
  }

  function droneUrl(id) { return config.droneUrl.replace("__ID__", encodeURIComponent(id)); }

  function updateMarker(drone) {
    const p = drone.position;
    let marker = markers.get(drone.drone_id);
    if (!p || p.lat === null || p.lat === undefined) return;
    if (!marker) {
      marker = L.marker([p.lat, p.lon], { icon: icon(drone), title: drone.drone_id, state: drone.state });
      marker.iconKey = iconKey(drone);
      marker.on("click", () => { location.href = droneUrl(drone.drone_id); });
      marker.on("mouseover", () => marker.bindTooltip(tooltip(live.drones.get(drone.drone_id) || drone)).openTooltip());
      markers.set(drone.drone_id, marker);
      pendingAdd.push(marker);
      scheduleAdd();
    } else {
      const at = marker.getLatLng();
      if (at.lat !== p.lat || at.lng !== p.lon) marker.setLatLng([p.lat, p.lon]);
      const key = iconKey(drone);
      if (key !== marker.iconKey) {
        const stateChanged = marker.options.state !== drone.state;
        marker.iconKey = key;
        marker.options.state = drone.state;
        marker.setIcon(icon(drone));
        if (stateChanged && marker.__parent) clusters.refreshClusters(marker);
      }
    }
  }

  // Markers arriving together (a snapshot of thousands) go to the cluster in one call.
  const pendingAdd = [];
  let addScheduled = false;
  function scheduleAdd() {
    if (addScheduled) return;
    addScheduled = true;
    setTimeout(() => {
      addScheduled = false;
      const batch = pendingAdd.splice(0);
      clusters.addLayers(batch);
      if (!fitted && markers.size) {
        fitted = true;
        const bounds = L.latLngBounds(Array.from(markers.values(), (m) => m.getLatLng()));
        if (markers.size === 1) map.setView(bounds.getCenter(), 16); else map.fitBounds(bounds.pad(0.1), { maxZoom: 17 });
      }
    }, 0);
  }

  /* ---- the table: one page from the table API, kept live by the socket's diffs ---- */
  const body = document.querySelector("#drone-table tbody");
  const controls = document.getElementById("row-controls");
  const form = document.getElementById("fleet-filters");
  const rows = new Map();
  let page = 1, pages = 1, requestSeq = 0;

  function cells(drone) {
    const mission = drone.mission;
    const missionCell = mission
      ? `<a href="${config.missionUrl.replace("__ID__", encodeURIComponent(mission.mission_id))}" title="${live.escapeHtml(mission.mission_id)}">${live.escapeHtml(String(mission.mission_id).slice(0, 8))}</a> · ${live.escapeHtml(live.missionStep(mission))}`
      : "–";
    return {
      state: `<span class="state-badge state-${drone.state}">${live.stateLabel(drone.state)}</span>`,
      alt: live.altitude(drone.position),
      speed: live.speed(drone.ground_speed),
      heading: live.heading(drone.heading),
      battery: live.batteryText(drone),
      mission: missionCell,
      link: live.age(drone.last_seen),
    };
  }

  const LABELS = { state: "State", alt: "Alt.", speed: "Speed", heading: "Heading", battery: "Battery", mission: "Mission · step", link: "Link" };

  function buildRow(drone) {
    const row = document.createElement("tr");
    row.dataset.drone = drone.drone_id;
    let html = `<td class="drone-id" data-label="Drone"><a href="${droneUrl(drone.drone_id)}">${live.escapeHtml(drone.drone_id)}</a></td>`;
    for (const field of Object.keys(LABELS)) html += `<td data-field="${field}" data-label="${LABELS[field]}"></td>`;
    row.innerHTML = html;
    if (controls) row.append(controls.content.cloneNode(true));
    fillRow(row, drone);
    return row;
  }

  function fillRow(row, drone) {
    const values = cells(drone);
    for (const [field, html] of Object.entries(values)) {
      const cell = row.querySelector(`[data-field="${field}"]`);
      if (cell && cell.innerHTML !== html) cell.innerHTML = html;
    }
    row.dataset.state = drone.state || "";
  }

  async function loadPage() {
    const seq = ++requestSeq;
    const params = new URLSearchParams();
    const q = form.elements.q.value.trim();
    if (q) params.set("q", q);
    const filters = Array.from(form.querySelectorAll("input[name=filter]:checked"), (i) => i.value);
    if (filters.length) params.set("filter", filters.join(","));
    params.set("page", String(page));
    let data;
    try {
      const response = await fetch(`${config.tableUrl}?${params}`, { credentials: "same-origin", headers: { Accept: "application/json" } });
      if (!response.ok) return;
      data = await response.json();
    } catch (error) { return; }
    if (seq !== requestSeq) return; // a newer search is on its way
    pages = data.pages;
    if (page > pages) { page = pages; loadPage(); return; }
    rows.clear();
    const fresh = data.results.map((d) => {
      const merged = live.absorb(d);
      const row = buildRow(merged);
      rows.set(d.drone_id, row);
      return row;
    });
    body.replaceChildren(...fresh);
    document.getElementById("fleet-count").textContent = `${data.count} drone${data.count === 1 ? "" : "s"}`;
    document.getElementById("page-info").textContent = `page ${data.page} of ${data.pages}`;
    document.getElementById("page-prev").disabled = page <= 1;
    document.getElementById("page-next").disabled = page >= pages;
  }

  let searchTimer = null;
  form.addEventListener("input", () => {
    clearTimeout(searchTimer);
    searchTimer = setTimeout(() => { page = 1; loadPage(); }, 200);
  });
  document.getElementById("page-prev").addEventListener("click", () => { if (page > 1) { page -= 1; loadPage(); } });
  document.getElementById("page-next").addEventListener("click", () => { if (page < pages) { page += 1; loadPage(); } });

  function onChange(drone) {
    updateMarker(drone);
    const row = rows.get(drone.drone_id);
    if (row) fillRow(row, drone);
  }

  const status = document.getElementById("live-status");
  live.drones = live.connect(config, onChange, (up) => {
    status.textContent = up ? "live" : "reconnecting…";
    status.className = `badge ${up ? "ok" : "off"}`;
  });
  live.absorb = (drone) => {
    const merged = Object.assign({}, live.drones.get(drone.drone_id) || {}, drone);
    live.drones.set(drone.drone_id, merged);
    updateMarker(merged);
    return merged;
  };
  loadPage();
  // Link ages tick every second; which drones match a filter is asked again now and then.
  setInterval(() => {
    const now = Date.now();
    for (const [id, row] of rows) {
      const drone = live.drones.get(id);
      const cell = row.querySelector('[data-field="link"]');
      if (drone && cell) cell.textContent = live.age(drone.last_seen, now);
    }
  }, 1000);
  setInterval(loadPage, 15000);

  // For tests and the console: where each marker is now, and what it shows.
  window.skyhiveFleet = {
    markerPosition(id) { const m = markers.get(id); return m ? m.getLatLng() : null; },
    markerIds() { return Array.from(markers.keys()); },
    markerState(id) { const m = markers.get(id); return m ? m.options.state : null; },
    markerHtml(id) { const m = markers.get(id); return m ? m.options.icon.options.html : null; },
    map,
    clusters,
  };
})();
