/* The fleet page: every drone of the organisation on a Leaflet map and in the table,
   moving as heartbeats arrive. */
(function () {
  "use strict";
  const config = JSON.parse(document.getElementById("fleet-config").textContent);
  const live = window.SkyhiveLive;
  const map = SkyhiveMap.create("fleet-map", { zoomControl: true });
  map.setView([38.7369, -9.1427], 13);
  const markers = new Map();
  let fitted = false;

  function icon(drone) {
    const state = drone.online ? "online" : "offline";
    const armed = drone.armed ? " armed" : "";
    return L.divIcon({
      className: `drone-marker ${state}${armed}`,
      html: `<span class="dot"></span><span class="label">${escapeHtml(drone.drone_id)}</span>`,
      iconSize: [18, 18],
      iconAnchor: [9, 9],
    });
  }

  function tooltip(drone) {
    return `<strong>${escapeHtml(drone.drone_id)}</strong><br>` +
      `${drone.online ? "online" : "offline"} · ${drone.armed ? "armed" : "disarmed"}<br>` +
      `battery ${live.percent(drone.battery)} · step ${escapeHtml(live.missionStep(drone.mission))}`;
  }

  function escapeHtml(text) {
    return String(text).replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
  }

  function updateMarker(drone) {
    const p = drone.position;
    let marker = markers.get(drone.drone_id);
    if (!p) return;
    if (!marker) {
      marker = L.marker([p.lat, p.lon], { icon: icon(drone), title: drone.drone_id }).addTo(map);
      marker.on("click", () => { location.href = config.droneUrl.replace("__ID__", encodeURIComponent(drone.drone_id)); });
      markers.set(drone.drone_id, marker);
    } else {
      marker.setLatLng([p.lat, p.lon]);
      marker.setIcon(icon(drone));
    }
    marker.bindTooltip(tooltip(drone));
    if (!fitted) {
      map.setView([p.lat, p.lon], 16);
      fitted = true;
    }
  }

  function updateRow(drone) {
    const row = document.querySelector(`#drone-table tr[data-drone="${CSS.escape(drone.drone_id)}"]`);
    if (!row) return;
    const set = (field, text) => { const cell = row.querySelector(`[data-field="${field}"]`); if (cell) cell.textContent = text; };
    const badge = row.querySelector('[data-field="state"] .badge');
    if (badge) { badge.textContent = drone.online ? "online" : "offline"; badge.className = `badge ${drone.online ? "ok" : "off"}`; }
    set("battery", live.percent(drone.battery));
    set("armed", drone.armed ? "armed" : "disarmed");
    set("mission", live.missionStep(drone.mission));
    set("position", live.position(drone.position));
    set("last_seen", live.clock(drone.last_seen));
  }

  function onChange(drone) {
    updateMarker(drone);
    updateRow(drone);
  }

  const status = document.getElementById("live-status");
  const drones = live.connect(config, onChange, (up) => {
    status.textContent = up ? "live" : "reconnecting…";
    status.className = `badge ${up ? "ok" : "off"}`;
  });
  drones.forEach(onChange);

  // For tests and the console: where each marker is now.
  window.skyhiveFleet = {
    markerPosition(id) { const m = markers.get(id); return m ? m.getLatLng() : null; },
    markerIds() { return Array.from(markers.keys()); },
  };
})();
