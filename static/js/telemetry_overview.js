/* The telemetry overview's drones, live: each row's link badge and battery follow the
   drone's heartbeats over /ws/fleet/ (this page's drones only, only what changed). */
(function () {
  "use strict";
  const config = JSON.parse(document.getElementById("overview-config").textContent);
  const live = window.SkyhiveLive;
  if (!document.querySelector("#telemetry-overview tr[data-drone]")) return;

  function show(drone) {
    const row = document.querySelector(`#telemetry-overview tr[data-drone="${CSS.escape(drone.drone_id)}"]`);
    if (!row) return;
    const badge = row.querySelector('[data-field="online"]');
    if (badge && drone.online !== undefined) {
      badge.textContent = drone.online ? "online" : "offline";
      badge.className = `badge ${drone.online ? "ok" : "off"}`;
    }
    const battery = row.querySelector('[data-field="battery"]');
    const remaining = drone.battery ? drone.battery.remaining : null;
    if (battery && remaining !== null && remaining !== undefined) {
      battery.innerHTML = `<meter min="0" max="1" low="0.25" high="0.5" optimum="1" value="${Number(remaining)}"></meter> ${live.percent(drone.battery)}`;
    }
  }

  live.connect(config, show);
})();
