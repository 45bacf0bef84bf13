// The flight paths on a map (every GPS track: several drones in a mission log), or the
// trajectory estimated from velocity and yaw on a plain metric plane when the log has no
// GPS; a marker per path follows the time cursor, the selected interval is highlighted.

import { escapeHtml, getJSON } from "./api.js";
import { PALETTE } from "./state.js";

export function lastIndexAtOrBefore(times, t) {
  let lo = 0;
  let hi = times.length - 1;
  if (hi < 0 || t < times[0]) return -1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (times[mid] <= t) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

export class MapView {
  constructor(el, viewer, { title, note }) {
    this.el = el;
    this.viewer = viewer;
    this.title = title;
    this.note = note;
    this.paths = [];
    this.load();
  }

  async load() {
    let track;
    try {
      track = await getJSON(`${this.viewer.api}track/`, { points: 3000 });
    } catch (err) {
      this.viewer.warn(`Map: ${err.message}`);
      return;
    }
    if (!track.source) {
      this.el.innerHTML = '<p class="lv-missing">No position in this log: neither GPS nor velocity with yaw.</p>';
      this.el.style.height = "auto";
      return;
    }
    let tracks;
    if (track.source === "gps") {
      this.title.textContent = "Map";
      this.note.textContent = track.tracks.length > 1 ? `GPS · ${track.tracks.length} tracks` : "GPS";
      this.map = window.SkyhiveMap.create(this.el, { zoomSnap: 0.25 });
      tracks = track.tracks.map((one) => ({ name: one.name, t: one.t, points: one.lat.map((lat, i) => [lat, one.lon[i]]) }));
    } else {
      this.title.textContent = "Trajectory";
      this.note.textContent = `estimated, no GPS · ${track.unit || "units"} from the start, north up`;
      this.map = L.map(this.el, { crs: L.CRS.Simple, minZoom: -30, maxZoom: 10, zoomSnap: 0.25, attributionControl: false });
      // x is north and y is west (logs/analysis.py): north up, east to the right.
      tracks = [{ name: "estimated", t: track.t, points: track.x.map((x, i) => [x ?? 0, -(track.y[i] ?? 0)]) }];
    }
    const bounds = L.latLngBounds([]);
    tracks.forEach((one, i) => {
      const colour = PALETTE[i % PALETTE.length];
      const line = L.polyline(one.points, { color: colour, weight: 2.5, opacity: 0.85 }).addTo(this.map);
      if (tracks.length > 1) line.bindTooltip(escapeHtml(one.name), { sticky: true });
      const part = L.polyline([], { color: "#f79009", weight: 5, opacity: 0.9 }).addTo(this.map);
      L.circleMarker(one.points[0], { radius: 4, color: "#17803d", fillOpacity: 1 }).bindTooltip(`${escapeHtml(one.name)}: start`).addTo(this.map);
      const marker = L.circleMarker(one.points[0], { radius: 7, color: "#fff", weight: 2, fillColor: tracks.length > 1 ? colour : "#d92d20", fillOpacity: 1 })
        .bindTooltip(escapeHtml(one.name))
        .addTo(this.map);
      bounds.extend(line.getBounds());
      this.paths.push({ ...one, line, part, marker });
    });
    if (bounds.isValid()) this.map.fitBounds(bounds.pad(0.15), { animate: false, maxZoom: 18 });
    new ResizeObserver(() => this.map.invalidateSize()).observe(this.el);
    this.viewer.state.on("cursor", () => this.moveMarkers());
    this.viewer.state.on("selection", () => this.showSelection());
    this.moveMarkers();
    this.showSelection();
    this.el.dataset.tracks = String(this.paths.length);
  }

  moveMarkers() {
    for (const path of this.paths) {
      const i = lastIndexAtOrBefore(path.t, this.viewer.state.cursor);
      path.marker.setLatLng(path.points[Math.max(i, 0)]);
      path.marker.setStyle({ opacity: i < 0 ? 0.35 : 1, fillOpacity: i < 0 ? 0.35 : 1 });
    }
  }

  showSelection() {
    const selection = this.viewer.state.selection;
    for (const path of this.paths) {
      if (!selection) { path.part.setLatLngs([]); continue; }
      const from = Math.max(lastIndexAtOrBefore(path.t, selection[0]), 0);
      const to = Math.max(lastIndexAtOrBefore(path.t, selection[1]), 0);
      path.part.setLatLngs(path.points.slice(from, to + 1));
    }
  }
}
