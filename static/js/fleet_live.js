/* Live fleet state over /ws/fleet/: a snapshot, then one message per change.
   Shared by the fleet map and the drone page. Reconnects with backoff. */
(function () {
  "use strict";

  function connect(config, onChange, onStatus) {
    const drones = new Map();
    for (const d of config.drones || []) drones.set(d.drone_id, d);
    let delay = 500;

    function merge(update) {
      const merged = Object.assign({}, drones.get(update.drone_id) || {}, update);
      drones.set(update.drone_id, merged);
      onChange(merged);
    }

    function open() {
      const scheme = location.protocol === "https:" ? "wss" : "ws";
      const socket = new WebSocket(`${scheme}://${location.host}${config.socketPath}`);
      socket.onopen = () => { delay = 500; onStatus && onStatus(true); };
      socket.onmessage = (event) => {
        let message;
        try { message = JSON.parse(event.data); } catch (e) { return; }
        if (message.type === "snapshot") message.drones.forEach(merge);
        else if (message.type === "drone" && message.drone) merge(message.drone);
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

  function percent(battery) {
    if (!battery || battery.remaining === null || battery.remaining === undefined) return "–";
    return `${Math.round(battery.remaining * 100)} %`;
  }

  function position(p) {
    if (!p) return "–";
    return `${p.lat.toFixed(6)}, ${p.lon.toFixed(6)}`;
  }

  function clock(iso) {
    if (!iso) return "never";
    const d = new Date(iso);
    return isNaN(d) ? iso : d.toLocaleTimeString();
  }

  function missionStep(mission) {
    if (!mission) return "–";
    return mission.index === null || mission.index === undefined ? mission.mission_id : String(mission.index);
  }

  window.SkyhiveLive = { connect, percent, position, clock, missionStep };
})();
