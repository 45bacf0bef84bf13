/* The fleet page: every drone on a Leaflet map (clustered, so thousands stay fluid) with
   its state, heading and altitude, and a paged, searchable table; both follow the live
   updates. */
(function () {
  "use strict";
  const config = JSON.parse(document.getElementById("fleet-config").textContent);
  const live = window.SkyhiveLive;
  // The cluster needs a maximum zoom even when no tile layer sets one (offline, no tiles).
  const map = SkyhiveMap.create("fleet-map", { zoomControl: true, maxZoom: 19 });
  map.setView([38.7369, -9.1427], 13);
  // States from least to most urgent: a cluster takes the colour of its most urgent drone.
  const URGENCY = ["on_ground", "armed", "airborne", "returning", "low_battery", "lost_link"];
  const readiness = new Set();
  let snapshotSeen = false;
  let fitted = false;
  const positions = new Map(); // drone id → [lon, lat, urgency]: what the cluster index holds
  const shown = new Map(); // key (drone id or "c" + cluster id) → the marker on the map
  const layer = L.layerGroup().addTo(map);
  // No clusters below zoom 3 (a continent) nor above 15 (closer, every drone in view is
  // drawn): fewer levels to index.
  const MIN_CLUSTER_ZOOM = 3, MAX_CLUSTER_ZOOM = 15;
  function clusterIndex(maxZoom) {
    return new Supercluster({
      radius: 45,
      minZoom: MIN_CLUSTER_ZOOM,
      maxZoom,
      map: (props) => ({ u: props.u }),
      reduce: (acc, props) => { if (props.u > acc.u) acc.u = props.u; },
    });
  }
  let index = clusterIndex(MAX_CLUSTER_ZOOM);
  let indexZoom = MAX_CLUSTER_ZOOM; // the highest zoom the current index clusters
  let indexed = false; // the index has been loaded once
  let quickDrawn = false; // the first snapshot was drawn (from a partial index)
  let generation = 0; // a new index numbers its clusters anew: their markers are redrawn

  function iconKey(drone) {
    const p = drone.position || {};
    const h = drone.heading === null || drone.heading === undefined ? "" : Math.round(drone.heading / 5) * 5;
    return `${drone.state}|${h}|${p.alt === null || p.alt === undefined ? "" : Math.round(p.alt)}`;
  }

  function icon(drone) {
    const p = drone.position || {};
    const alt = p.alt === null || p.alt === undefined ? "" : ` · ${Math.round(p.alt)} m`;
    // Built through the DOM: the page's Content-Security-Policy refuses style attributes.
    const body = document.createElement("div");
    body.innerHTML = `<span class="dot"></span><span class="label">${live.escapeHtml(drone.drone_id)}${alt}</span>`;
    if (drone.heading !== null && drone.heading !== undefined) {
      const arrow = document.createElement("span");
      arrow.className = "arrow";
      arrow.style.transform = `rotate(${Math.round(drone.heading)}deg)`;
      body.prepend(arrow);
    }
    return L.divIcon({
      className: `drone-marker state-${drone.state || "lost_link"}`,
      html: body,
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

  function droneMarker(drone) {
    const p = drone.position;
    const marker = L.marker([p.lat, p.lon], { icon: icon(drone), title: drone.drone_id, keyboard: false });
    marker.iconKey = iconKey(drone);
    marker.on("click", () => { location.href = droneUrl(drone.drone_id); });
    marker.on("mouseover", () => {
      const now = live.drones.get(drone.drone_id);
      if (now) marker.bindTooltip(tooltip(now)).openTooltip();
    });
    return marker;
  }

  function clusterMarker(feature) {
    const n = feature.properties.point_count;
    const state = URGENCY[feature.properties.u] || "on_ground";
    const [lon, lat] = feature.geometry.coordinates;
    const marker = L.marker([lat, lon], {
      icon: L.divIcon({ className: `drone-cluster state-${state}`, html: `<span>${n}</span>`, iconSize: [36, 36] }),
      title: `${n} drones`,
    });
    marker.on("click", () => map.setView([lat, lon], Math.min(index.getClusterExpansionZoom(feature.id), 18)));
    return marker;
  }

  /* Only what is in view becomes a marker: clusters, and the drones standing alone. */
  function render() {
    if (!indexed) return;
    const b = map.getBounds().pad(0.25);
    // A partial index has nothing above its zoom: its closest clusters stand in meanwhile.
    const zoom = Math.min(Math.round(map.getZoom()), indexZoom < MAX_CLUSTER_ZOOM ? indexZoom : Infinity);
    const wanted = new Set();
    for (const f of index.getClusters([b.getWest(), b.getSouth(), b.getEast(), b.getNorth()], zoom)) {
      const cluster = f.properties.cluster;
      const key = cluster ? `c${generation}:${f.id}:${f.properties.point_count}:${f.properties.u}` : f.properties.id;
      wanted.add(key);
      if (shown.has(key)) continue;
      const drone = cluster ? null : live.drones.get(key);
      const marker = cluster ? clusterMarker(f) : drone && droneMarker(drone);
      if (marker) { shown.set(key, marker); layer.addLayer(marker); }
    }
    for (const [key, marker] of shown) {
      if (!wanted.has(key)) { layer.removeLayer(marker); shown.delete(key); }
    }
  }

  // The index is rebuilt at most this often while drones move (10 000 take ~0.1 s).
  let reindexTimer = null;
  let reindexEvery = 1000;
  function reindex() {
    reindexTimer = null;
    const started = performance.now();
    if (!fitted && positions.size) fit();
    const features = [];
    for (const [id, [lon, lat, u]] of positions) {
      features.push({ type: "Feature", properties: { id, u }, geometry: { type: "Point", coordinates: [lon, lat] } });
    }
    // The first draw clusters only the levels up to the view's zoom (about half the work:
    // the closest levels cost the most); the full index follows when the page is idle.
    const zoom = Math.max(MIN_CLUSTER_ZOOM, Math.round(map.getZoom()));
    const first = snapshotSeen && !quickDrawn && zoom < MAX_CLUSTER_ZOOM;
    if (snapshotSeen) quickDrawn = true;
    const maxZoom = first ? zoom : MAX_CLUSTER_ZOOM;
    if (maxZoom !== indexZoom) { index = clusterIndex(maxZoom); indexZoom = maxZoom; generation += 1; }
    indexed = false;
    index.load(features);
    indexed = true;
    if (first) whenIdle(() => scheduleReindex(true));
    else reindexEvery = Math.max(1000, 10 * (performance.now() - started));
    render();
    if (snapshotSeen) markReady("markers");
  }
  function whenIdle(task) {
    if (window.requestIdleCallback) requestIdleCallback(task, { timeout: 1000 });
    else setTimeout(task, 200);
  }
  function scheduleReindex(now) {
    if (now) { clearTimeout(reindexTimer); reindex(); return; }
    if (!reindexTimer) reindexTimer = setTimeout(reindex, reindexEvery);
  }

  function fit() {
    fitted = true;
    let south = 90, north = -90, west = 180, east = -180;
    for (const [lon, lat] of positions.values()) {
      south = Math.min(south, lat); north = Math.max(north, lat);
      west = Math.min(west, lon); east = Math.max(east, lon);
    }
    // Without animation: the first index is built for the zoom the view lands on.
    if (positions.size === 1) map.setView([south, west], 16, { animate: false });
    else map.fitBounds(L.latLngBounds([south, west], [north, east]).pad(0.1), { maxZoom: 17, animate: false });
  }

  function updateMarker(drone) {
    const p = drone.position;
    if (!p || p.lat === null || p.lat === undefined) return;
    const u = Math.max(0, URGENCY.indexOf(drone.state));
    const before = positions.get(drone.drone_id);
    positions.set(drone.drone_id, [p.lon, p.lat, u]);
    const marker = shown.get(drone.drone_id);
    if (marker) {
      // A drone drawn on its own follows at once; clusters catch up at the next re-index.
      const at = marker.getLatLng();
      if (at.lat !== p.lat || at.lng !== p.lon) marker.setLatLng([p.lat, p.lon]);
      const key = iconKey(drone);
      if (key !== marker.iconKey) { marker.iconKey = key; marker.setIcon(icon(drone)); }
    }
    if (!before || before[0] !== p.lon || before[1] !== p.lat || before[2] !== u) scheduleReindex();
  }
  map.on("moveend", render);

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
      ready: fitToFly(drone),
    };
  }

  /* Whether the drone may fly: why it is not airworthy, and its pre-flight checklist. */
  const CHECKLIST = { none: "not run", failed: "failed", passed: "passed", expired: "expired" };
  function fitToFly(drone) {
    const r = drone.readiness;
    if (!r) return "–";
    const air = r.airworthy
      ? `<span class="airworthy">airworthy</span>`
      : `<span class="not-airworthy">not airworthy: ${live.escapeHtml(r.reasons.join("; "))}</span>`;
    const c = r.checklist || {};
    const shown = `checklist ${CHECKLIST[c.status] || live.escapeHtml(String(c.status))}${c.required ? "" : " (not required)"}`;
    const url = `/checklists/drones/${encodeURIComponent(drone.drone_id)}/`;
    return `${air}<br><a class="checklist-${live.escapeHtml(String(c.status))}" href="${url}">${shown}</a>`;
  }

  const LABELS = { state: "State", alt: "Alt.", speed: "Speed", heading: "Heading", battery: "Battery", mission: "Mission · step", link: "Link", ready: "Fit to fly" };

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

  /* The first page the page's head already asked for, when that is the page wanted. */
  function tableResponse(url) {
    const early = window.SkyhiveEarly;
    if (early && early.table && early.tableUrl === url) {
      const response = early.table;
      early.table = null;
      return response;
    }
    return fetch(url, { credentials: "same-origin", headers: { Accept: "application/json" } });
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
      const response = await tableResponse(`${config.tableUrl}?${params}`);
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
    performance.mark("fleet:table");
    markReady("table");
  }

  /* The page is usable once the first table page is drawn and every drone of the first
     snapshot is on the map: noted on <html data-fleet-ready> in ms since navigation start
     (for the benchmark and tests). */
  function markReady(part) {
    readiness.add(part);
    const root = document.documentElement;
    if (readiness.has("table") && readiness.has("markers") && !root.dataset.fleetReady) {
      root.dataset.fleetReady = String(performance.now());
    }
  }

  let searchTimer = null;
  form.addEventListener("submit", (event) => event.preventDefault());  // Enter only filters
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
  }, null, () => {
    snapshotSeen = true;
    scheduleReindex(true); // the snapshot is drawn at once
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

  // For tests and the console: where each drone's marker is, and what it shows.
  window.skyhiveFleet = {
    markerPosition(id) { const p = positions.get(id); return p ? { lat: p[1], lng: p[0] } : null; },
    markerIds() { return Array.from(positions.keys()); },
    markerState(id) { const d = live.drones.get(id); return positions.has(id) && d ? d.state : null; },
    markerHtml(id) { const d = live.drones.get(id); return d && positions.has(id) ? icon(d).options.html.innerHTML : null; },
    shownMarkers() { return shown.size; },
    clusterZoom() { return indexZoom; },
    map,
  };
})();
