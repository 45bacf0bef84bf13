// The mission log viewer's time: one cursor over the mission's events (stamped with Unix
// seconds), a replay, each drone's place at the cursor on the map, and the recordings of
// the mission's flights (GET /api/v1/missions/{id}/video/) in step with the cursor, one
// card per drone — the single-log viewer's own TimeState, Replay and VideoPanel.

import { Replay } from "./logs/replay.js";
import { formatDuration, TimeState } from "./logs/state.js";
import { VideoPanel } from "./logs/video.js";

const config = JSON.parse(document.getElementById("viewer-config").textContent);
const root = document.getElementById("log-time");
const part = (name) => root.querySelector(`[data-part="${name}"]`);
const slider = part("cursor");
let current = null;

/** Each drone's positions in time order, [ts, lat, lon], from the log's events. */
function tracksOf(log) {
  const tracks = new Map();
  for (const e of log.events) {
    if (!e.drone_id || !e.position || typeof e.ts !== "number" || (e.type && e.type !== "step")) continue;
    if (!tracks.has(e.drone_id)) tracks.set(e.drone_id, []);
    tracks.get(e.drone_id).push([e.ts, e.position.lat, e.position.lon]);
  }
  for (const track of tracks.values()) track.sort((a, b) => a[0] - b[0]);
  return tracks;
}

/** Where a drone was at t: between its two reports around t, in proportion to the time;
 *  before its first report it is not shown, after its last it stays there. */
export function positionAt(track, t) {
  if (!track.length || t < track[0][0]) return null;
  let lo = 0;
  let hi = track.length - 1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (track[mid][0] <= t) lo = mid;
    else hi = mid - 1;
  }
  const a = track[lo];
  const b = track[lo + 1];
  if (!b || b[0] === a[0]) return [a[1], a[2]];
  const f = (t - a[0]) / (b[0] - a[0]);
  return [a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f];
}

class MissionTime {
  constructor(log, missionId) {
    let first = Infinity;
    let last = -Infinity;
    for (const e of log.events) {
      if (typeof e.ts !== "number") continue;
      first = Math.min(first, e.ts);
      last = Math.max(last, e.ts);
    }
    this.root = root;
    this.state = new TimeState(first, last);
    this.replay = new Replay(this, { playButton: root.querySelector('[data-action="play"]'), speedSelect: part("speed") });
    this.tracks = tracksOf(log);
    this.layer = L.layerGroup().addTo(window.skyhiveLogViewer.map);
    this.markers = new Map();
    this.panels = [];
    slider.min = "0";
    slider.max = String(this.state.end - this.state.start);
    this.state.on("cursor", ({ source }) => this.show(source));
    this.show("load");
    if (missionId) this.loadVideo(missionId);
  }

  show(source) {
    const t = this.state.cursor;
    if (source !== "slider") slider.value = String(t - this.state.start);
    part("clock").textContent = `t = ${formatDuration(this.state.rel(t), 1)}`;
    part("wall").textContent = new Date(t * 1000).toISOString().replace("T", " ").replace("Z", " UTC");
    for (const [drone, track] of this.tracks) {
      const at = positionAt(track, t);
      let marker = this.markers.get(drone);
      if (!at) {
        if (marker) { marker.remove(); this.markers.delete(drone); }
        continue;
      }
      if (!marker) {
        const colour = window.SkyhiveMissions.colourFor(drone);
        marker = L.circleMarker(at, { radius: 7, color: "#000", weight: 2, fillColor: colour, fillOpacity: 1, className: "drone-at-cursor" })
          .bindTooltip(drone).addTo(this.layer);
        this.markers.set(drone, marker);
      } else {
        marker.setLatLng(at);
      }
    }
  }

  async loadVideo(missionId) {
    const url = config.videoUrl.replace(config.placeholder, missionId);
    const response = await fetch(url, { credentials: "same-origin", headers: { Accept: "application/json" } });
    if (!response.ok || current !== this) return;
    const byDrone = new Map();
    for (const r of (await response.json()).recordings) {
      if (!byDrone.has(r.drone)) byDrone.set(r.drone, []);
      byDrone.get(r.drone).push(r);
    }
    const template = document.getElementById("mission-video-card");
    for (const [drone, recordings] of byDrone) {
      const card = template.content.firstElementChild.cloneNode(true);
      card.dataset.drone = drone;
      card.querySelector('[data-part="video-drone"]').textContent = drone;
      part("videos").append(card);
      const panel = new VideoPanel(card, this, null);
      panel.use(recordings);
      this.panels.push(panel);
    }
    root.dataset.videos = String(this.panels.length);
  }

  close() {
    this.replay.pause();
    this.layer.remove();
    for (const panel of this.panels) panel.video.removeAttribute("src");
    part("videos").replaceChildren();
  }
}

function open({ log, mission }) {
  if (current) current.close();
  current = null;
  delete root.dataset.videos;
  const stamped = log.events.filter((e) => typeof e.ts === "number");
  root.hidden = stamped.length < 2;
  if (root.hidden) return;
  current = new MissionTime(log, mission);
  window.skyhiveLogViewer.time = current;
}

slider.addEventListener("input", () => {
  if (current) current.state.setCursor(current.state.start + Number(slider.value), "slider");
});
const actions = {
  play: () => current && current.replay.toggle(),
  stop: () => current && current.replay.stop(),
  rewind: () => current && current.replay.rewind(),
};
root.addEventListener("click", (event) => {
  const button = event.target.closest("[data-action]");
  if (button && actions[button.dataset.action]) actions[button.dataset.action]();
});
// The single-log viewer's keys: Space plays or pauses, Home rewinds.
document.addEventListener("keydown", (event) => {
  if (!current || root.hidden || event.target.closest("input, select, textarea")) return;
  if (event.key === " ") { event.preventDefault(); actions.play(); }
  if (event.key === "Home") { event.preventDefault(); actions.rewind(); }
});
window.addEventListener("skyhive:mission-log", (event) => open(event.detail));
if (window.skyhiveLogViewer && window.skyhiveLogViewer.last) open(window.skyhiveLogViewer.last);
