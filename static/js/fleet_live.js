/* Live fleet state over /ws/fleet/: a snapshot (drones in full, or compact marker rows for
   a big fleet), then per drone only the fields that changed. Shared by the fleet page and
   the drone page, with the formatting both use. Reconnects with backoff. */
(function () {
  "use strict";

  /* A socket the page opened before its scripts loaded (see the fleet page's head), if it
     is for this path: taken once, with the messages that came before anyone listened. */
  function earlySocket(path) {
    const early = window.SkyhiveEarly;
    if (!early || !early.socket || early.path !== path) return null;
    const taken = { socket: early.socket, messages: early.messages };
    early.socket = null;
    return taken;
  }

  /* The map's columns of a big fleet's snapshot, as drones (only what a marker needs). */
  function fromColumns(markers, each) {
    const c = markers.columns, states = markers.states;
    const ids = c.drone_id, lat = c.lat, lon = c.lon, alt = c.alt, state = c.state;
    for (let i = 0; i < ids.length; i++) {
      const s = states[state[i]];
      each({ drone_id: ids[i], state: s, online: s !== "lost_link", position: { lat: lat[i], lon: lon[i], alt: alt[i] } });
    }
  }

  /* onSnapshot runs after each snapshot is merged (after a reconnection too). */
  function connect(config, onChange, onStatus, onOther, onSnapshot) {
    const drones = new Map();
    for (const d of config.drones || []) drones.set(d.drone_id, d);
    let delay = 500;

    function merge(update) {
      const before = drones.get(update.drone_id);
      const merged = before ? Object.assign({}, before, update) : update;
      drones.set(update.drone_id, merged);
      onChange(merged, update);
    }

    function receive(event) {
      let message;
      try { message = JSON.parse(event.data); } catch (e) { return; }
      if (message.type === "snapshot") {
        (message.drones || []).forEach(merge);
        if (message.markers && message.markers.columns) fromColumns(message.markers, merge);
        performance.mark("fleet:snapshot");
        if (onSnapshot) onSnapshot(message);
      } else if (message.type === "drone" && message.drone) merge(message.drone);
      else if (onOther) onOther(message);
    }

    function listen(socket) {
      socket.onopen = () => { delay = 500; onStatus && onStatus(true); };
      socket.onmessage = receive;
      socket.onclose = () => {
        onStatus && onStatus(false);
        setTimeout(open, delay);
        delay = Math.min(delay * 2, 10000);
      };
    }

    function open() {
      const scheme = location.protocol === "https:" ? "wss" : "ws";
      listen(new WebSocket(`${scheme}://${location.host}${config.socketPath}`));
    }

    const early = earlySocket(config.socketPath);
    // Taken over once the caller has its state in hand (after this returns); until then the
    // head's handler keeps queueing, so no message is lost or reordered.
    if (early) {
      setTimeout(() => {
        listen(early.socket);
        early.messages.splice(0).forEach(receive); // and lets them go
        if (early.socket.readyState === WebSocket.OPEN) early.socket.onopen();
        else if (early.socket.readyState > WebSocket.OPEN) early.socket.onclose();
      }, 0);
    } else open();
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
