/* The panic button: the phone's position goes to the platform, which
   sends the nearest available drone; this page follows it until it hovers overhead. */
(function () {
  "use strict";
  const M = window.SkyhiveMissions;
  const config = JSON.parse(document.getElementById("panic-config").textContent);
  const $ = (id) => document.getElementById(id);
  const STAGES = { arm: "arming", takeoff: "climbing", wait_for_flight: "climbing", navigate: "flying to you" };

  function fail(message) {
    $("panic-error").textContent = message;
    $("panic-error").hidden = !message;
    $("call-drone").disabled = false;
  }

  function stageOf(mission) {
    if (mission.status === "completed") return "hovering over you";
    if (mission.status !== "running") return mission.status;
    const steps = mission.steps;
    const current = steps.find((s) => s.status === "started") || steps.find((s) => s.status === "pending");
    if (!current) return "hovering over you";
    // The second wait is the arrival over the caller.
    if (current.command === "wait_for_flight" && current.index > 2) return "flying to you";
    return STAGES[current.command] || current.command;
  }

  async function follow(missionId, caller) {
    let mission;
    try { mission = await M.api("GET", config.missionApi.replace(config.placeholder, missionId)); }
    catch (error) { setTimeout(() => follow(missionId, caller), 1000); return; }
    const droneId = mission.assignments.length ? mission.assignments[mission.assignments.length - 1].drone : null;
    $("panic-drone").textContent = droneId || "–";
    $("panic-stage").textContent = stageOf(mission);
    if (droneId) {
      try {
        const drone = await M.api("GET", config.droneApi.replace("__DRONE__", encodeURIComponent(droneId)));
        if (drone.position) {
          $("panic-distance").textContent = `${M.distance(caller, [drone.position.lat, drone.position.lon]).toFixed(1)} m`;
          $("panic-altitude").textContent = `${(drone.position.alt ?? 0).toFixed(1)} m`;
        }
      } catch (error) { /* keep the last values */ }
    }
    $("panic-state").textContent = mission.status === "completed"
      ? "The drone is hovering above you." : `Drone ${droneId || ""} is on its way.`;
    if (["running", "paused"].includes(mission.status) || mission.status === "completed") {
      setTimeout(() => follow(missionId, caller), 1000);
    } else {
      fail(`The call ended: ${mission.status}.`);
    }
  }

  $("call-drone").addEventListener("click", () => {
    fail("");
    $("call-drone").disabled = true;
    if (!navigator.geolocation) { fail("This browser cannot tell where you are."); return; }
    $("panic-state").textContent = "Finding where you are…";
    navigator.geolocation.getCurrentPosition(async (where) => {
      const caller = [where.coords.latitude, where.coords.longitude];
      try {
        const mission = await M.api("POST", config.panicUrl, { lat: caller[0], lon: caller[1], organisation: config.organisation });
        $("panic-progress").hidden = false;
        $("panic-state").textContent = "A drone is coming.";
        follow(mission.id, caller);
      } catch (error) {
        fail(error.message);
      }
    }, (error) => fail(`Your position is needed: ${error.message}`), { enableHighAccuracy: true, timeout: 15000 });
  });
})();
