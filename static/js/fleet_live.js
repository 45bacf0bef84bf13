/* Live fleet state over /ws/fleet/: a snapshot (drones in full, or compact marker rows for
   a big fleet), then per drone only the fields that changed. Shared by the fleet page and
   the drone page, with the formatting both use. Reconnects with backoff. */
(function () {
  "use strict";

  /* onSnapshot runs after each snapshot is merged (after a reconnection too). */
  function connect(config, onChange, onStatus, onOther, onSnapshot) {
    const drones = new Map();
    for (const d of config.drones || []) drones.set(d.drone_id, d);
    let delay = 500;

    function merge(update) {
      const merged = Object.assign({}, drones.get(update.drone_id) || {}, update);
      drones.set(update.drone_id, merged);
      onChange(merged, update);
    }

    function fromMarkerRow(fields, values) {
      const row = {};
      fields.forEach((name, i) => { row[name] = values[i]; });
      return { drone_id: row.drone_id, state: row.state, online: row.state !== "lost_link", position: { lat: row.lat, lon: row.lon, alt: row.alt } };
    }

    function open() {
      const scheme = location.protocol === "https:" ? "wss" : "ws";
      const socket = new WebSocket(`${scheme}://${location.host}${config.socketPath}`);
      socket.onopen = () => { delay = 500; onStatus && onStatus(true); };
      socket.onmessage = (event) => {
        let message;
        try { message = JSON.parse(event.data); } catch (e) { return; }
        if (message.type === "snapshot") {

          (message.drones || []).forEach(merge);
          for (const values of message.markers || []) merge(fromMarkerRow(message.fields, values));
          if (onSnapshot) onSnapshot(message);
        } else if (message.type === "drone" && message.drone) merge(message.drone);
        else if (onOther) onOther(message);
      };
      socket.onclose = () => {
        onStatus && onStatus(false);
        setTimeout(open, delay);
        delay = Math.min(delay * 2, 10000);
      };
    }

    open();
    return drones;
  }

  const dash = "–";
  const known = (v) => v !== null && v !== undefined;

  function percent(battery) {
    if (!battery || !known(battery.remaining)) return dash;
    return `${Math.round(battery.remaining * 100)} %`;
  }

  function duration(seconds) {
    if (!known(seconds)) return dash;
    const s = Math.max(0, Math.round(seconds));
    if (s < 60) return `${s} s`;
    if (s < 3600) return `${Math.floor(s / 60)} min`;
    return `${Math.floor(s / 3600)} h ${String(Math.floor((s % 3600) / 60)).padStart(2, "0")}`;
  }

  function batteryText(drone) {
    const left = drone.battery_time_left_s;
    return known(left) ? `${percent(drone.battery)} · ${duration(left)} left` : percent(drone.battery);
  }

  function position(p) {
    if (!p) return dash;
    return `${p.lat.toFixed(6)}, ${p.lon.toFixed(6)}`;
  }

  function altitude(p) {
    return p && known(p.alt) ? `${Number(p.alt).toFixed(1)} m` : dash;
  }

  function speed(value) {
    return known(value) ? `${Number(value).toFixed(1)} m/s` : dash;
  }

  const COMPASS = ["N", "NE", "E", "SE", "S", "SW", "W", "NW"];
  function heading(value) {
    if (!known(value)) return dash;
    return `${Math.round(value)}° ${COMPASS[Math.round(value / 45) % 8]}`;
  }

  function clock(iso) {
    if (!iso) return "never";
    const d = new Date(iso);
    return isNaN(d) ? iso : d.toLocaleTimeString();
  }

  /* How long since the last heartbeat, as "3 s ago". */
  function age(iso, now) {
    if (!iso) return "never";
    const t = Date.parse(iso);
    if (isNaN(t)) return iso;
    return `${duration(Math.max(0, ((now || Date.now()) - t) / 1000))} ago`;
  }

  function missionStep(mission) {
    if (!mission) return dash;
    return !known(mission.index) ? mission.mission_id : String(mission.index);
  }

  function clockText(fc) {
    if (!fc || !known(fc.clock_offset_s)) return { text: dash, trusted: true };
    return { text: `${fc.clock_offset_s} s from the ground's`, trusted: fc.clock_trusted !== false };
  }

  const STATE_LABELS = { lost_link: "lost link", low_battery: "low battery", returning: "returning", airborne: "airborne", armed: "armed", on_ground: "on ground" };
  function stateLabel(state) { return STATE_LABELS[state] || state || dash; }

  function escapeHtml(text) {
    return String(text).replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
  }

  window.SkyhiveLive = {
    connect, percent, duration, batteryText, position, altitude, speed, heading, clock, age,
    missionStep, clockText, stateLabel, escapeHtml,
  };
})();
