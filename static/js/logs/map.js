// The flight path on a map (GPS), or the trajectory estimated from velocity and yaw on a
// plain metric plane when the log has no GPS; a marker follows the time cursor.

import { getJSON } from "./api.js";

function lastIndexAtOrBefore(times, t) {
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

export { lastIndexAtOrBefore };

export class MapView {
  constructor(el, viewer, { title, note }) {
    this.el = el;
    this.viewer = viewer;
    this.title = title;
    this.note = note;
    this.track = null;
    this.load();
  }

  async load() {
    try {
      this.track = await getJSON(`${this.viewer.api}track/`, { points: 3000 });
    } catch (err) {
      this.viewer.warn(`Map: ${err.message}`);
      return;
    }
    const track = this.track;
    if (!track.source) {
      this.el.innerHTML = '<p class="lv-missing">No position in this log: neither GPS nor velocity with yaw.</p>';
      this.el.style.height = "auto";
      return;
    }
    let points;
    if (track.source === "gps") {
      this.title.textContent = "Map";
      this.note.textContent = "GPS";
      this.map = L.map(this.el, { attributionControl: Boolean(this.viewer.tileUrl), zoomSnap: 0.25 });
      if (this.viewer.tileUrl) {
        L.tileLayer(this.viewer.tileUrl, { attribution: this.viewer.tileAttribution, maxZoom: 19 }).addTo(this.map);
      }
      points = track.lat.map((lat, i) => [lat, track.lon[i]]);
    } else {
      this.title.textContent = "Trajectory";
      this.note.textContent = `estimated, no GPS · ${track.unit || "units"} from the start, north up`;
      this.map = L.map(this.el, { crs: L.CRS.Simple, minZoom: -30, maxZoom: 10, zoomSnap: 0.25, attributionControl: false });
      // x is north and y is west (seed 000, 5.2.1): north up, east to the right.
      points = track.x.map((x, i) => [x ?? 0, -(track.y[i] ?? 0)]);
    }
    this.points = points;
    this.path = L.polyline(points, { color: "#2358d6", weight: 2.5, opacity: 0.85 }).addTo(this.map);
    this.part = L.polyline([], { color: "#f79009", weight: 5, opacity: 0.9 }).addTo(this.map);
    L.circleMarker(points[0], { radius: 5, color: "#17803d", fillOpacity: 1 }).bindTooltip("start").addTo(this.map);
    L.circleMarker(points[points.length - 1], { radius: 5, color: "#475467", fillOpacity: 1 }).bindTooltip("end").addTo(this.map);
    this.marker = L.circleMarker(points[0], { radius: 7, color: "#fff", weight: 2, fillColor: "#d92d20", fillOpacity: 1 }).addTo(this.map);
    this.fit();
    new ResizeObserver(() => this.map.invalidateSize()).observe(this.el);
    this.viewer.state.on("cursor", () => this.moveMarker());
    this.viewer.state.on("selection", () => this.showSelection());
    this.moveMarker();
    this.showSelection();
  }

  fit() {
    const bounds = this.path.getBounds();
    if (bounds.isValid()) this.map.fitBounds(bounds.pad(0.15), { animate: false, maxZoom: 18 });
  }

  moveMarker() {
    const i = lastIndexAtOrBefore(this.track.t, this.viewer.state.cursor);
    this.marker.setLatLng(this.points[Math.max(i, 0)]);
  }

  showSelection() {
    const selection = this.viewer.state.selection;
    if (!selection) { this.part.setLatLngs([]); return; }
    const from = Math.max(lastIndexAtOrBefore(this.track.t, selection[0]), 0);
    const to = Math.max(lastIndexAtOrBefore(this.track.t, selection[1]), 0);
    this.part.setLatLngs(this.points.slice(from, to + 1));
  }
}
