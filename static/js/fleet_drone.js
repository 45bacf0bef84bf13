/* The drone page: live status, and a form per command posted to the commands API. */
(function () {
  "use strict";
  const config = JSON.parse(document.getElementById("fleet-config").textContent);
  const live = window.SkyhiveLive;
  const droneId = config.drones[0].drone_id;
  const csrf = document.querySelector('meta[name="csrf-token"]').content;
  const result = document.getElementById("command-result");

  function show(drone) {
    if (drone.drone_id !== droneId) return;
    const badge = document.getElementById("drone-state");
    badge.textContent = drone.online ? "online" : "offline";
    badge.className = `badge ${drone.online ? "ok" : "off"}`;
    const field = (name) => document.querySelector(`#drone-status [data-field="${name}"]`);
    const set = (name, text) => { const el = field(name); if (el) el.textContent = text; };
    set("armed", drone.armed ? "yes" : "no");
    set("airborne", drone.airborne ? "yes" : "no");
    set("flight_mode", drone.flight_mode || "–");
    const state = field("state");
    if (state) state.innerHTML = `<span class="state-badge state-${drone.state}">${live.stateLabel(drone.state)}</span>`;
    const b = drone.battery;
    const volts = b && b.voltage !== null && b.voltage !== undefined ? ` (${Number(b.voltage).toFixed(2)} V)` : "";
    set("battery", `${live.batteryText(drone)}${volts}`);
    const p = drone.position;
    set("position", p ? `${live.position(p)}, ${Number(p.alt).toFixed(1)} m` : "no fix");
    set("alt", live.altitude(p));
    set("speed", live.speed(drone.ground_speed));
    set("heading", live.heading(drone.heading));
    missionId = drone.mission ? drone.mission.mission_id : null;
    set("mission", drone.mission ? `${drone.mission.mission_id} step ${live.missionStep(drone.mission)}` : "–");
    const clock = field("clock");
    if (clock) {
      const c = live.clockText(drone.fc);
      clock.textContent = c.text;
      if (!c.trusted) clock.insertAdjacentHTML("beforeend", ' <span class="badge off">not trusted</span>');
    }
    set("last_seen", live.clock(drone.last_seen));
  }

  /* Recent commands: each new command on top, its outcome filled in when it ends. */
  const history = document.getElementById("command-history");
  function showCommand(message) {
    if (message.type !== "command" || message.drone_id !== droneId || !history) return;
    const c = message.command;
    let item = history.querySelector(`[data-command-id="${c.id}"]`);
    if (!item) {
      item = document.createElement("li");
      item.dataset.commandId = c.id;
      history.querySelectorAll(".empty").forEach((e) => e.remove());
      history.prepend(item);
      while (history.children.length > 20) history.lastElementChild.remove();
    }
    item.dataset.outcome = c.outcome;
    const at = c.sent_at ? new Date(c.sent_at).toLocaleTimeString([], { hour12: false }) : "";
    item.textContent = `${at} ${c.command} — ${c.outcome_label}${c.user ? ` by ${c.user}` : ""}${c.error ? `: ${c.error}` : ""}`;
  }

  live.connect(config, show, null, showCommand);

  // The mission the drone reports flying, for Resume; kept current by the live updates.
  let missionId = config.drones[0].mission ? config.drones[0].mission.mission_id : null;

  function params(form) {
    const out = {};
    for (const input of form.querySelectorAll("input")) {
      if (input.dataset.confirmTyped !== undefined) continue;
      if (input.type === "checkbox") { if (input.checked) out[input.name] = true; continue; }
      if (input.value === "") continue;
      out[input.name] = input.dataset.type === "text" ? input.value : Number(input.value);
    }
    return out;
  }

  /* A command that starts the motors is sent only once the drone's id has been typed. */
  function confirmed(form, command) {
    const typed = form.querySelector("input[data-confirm-typed]");
    if (!typed || typed.value.trim() === typed.dataset.confirmTyped) return true;
    result.textContent = `${command}: not sent. Type ${typed.dataset.confirmTyped} to confirm.`;
    result.dataset.status = "error";
    typed.focus();
    return false;
  }

  async function resumeMission() {
    if (!missionId) {
      result.textContent = "resume: the drone is not flying a mission.";
      result.dataset.status = "error";
      return;
    }
    const response = await fetch(`/api/v1/missions/${encodeURIComponent(missionId)}/resume/`, {
      method: "POST",
      credentials: "same-origin",
      headers: { "X-CSRFToken": csrf, Accept: "application/json" },
    });
    const body = await response.json().catch(() => ({}));
    result.textContent = response.ok ? "resume: the mission carries on" : `resume: ${response.status} ${body.error || ""}`;
    result.dataset.status = response.ok ? "ok" : "error";
  }

  async function send(form) {
    const command = form.dataset.command;
    if (!confirmed(form, command)) return;
    if (form.dataset.confirm && !window.confirm(form.dataset.confirm)) return;
    const buttons = form.querySelectorAll("button");
    buttons.forEach((b) => { b.disabled = true; });
    result.textContent = `${command}: waiting for ${droneId}…`;
    try {
      const response = await fetch(config.commandUrl, {
        method: "POST",
        credentials: "same-origin",
        headers: { "Content-Type": "application/json", "X-CSRFToken": csrf, Accept: "application/json" },
        body: JSON.stringify({ command, params: params(form) }),
      });
      const body = await response.json().catch(() => ({ error: response.statusText }));
      if (response.ok) {
        const verdict = body.ok ? "ok" : `refused: ${body.error}`;
        result.textContent = `${command}: ${verdict}\n${JSON.stringify(body.result || {}, null, 2)}`;
      } else {
        result.textContent = `${command}: ${response.status} ${body.error || ""}`;
      }
      result.dataset.status = response.ok && body.ok ? "ok" : "error";
    } catch (error) {
      result.textContent = `${command}: ${error}`;
      result.dataset.status = "error";
    } finally {
      buttons.forEach((b) => { b.disabled = false; });
    }
  }

  for (const form of document.querySelectorAll("form[data-command]")) {
    form.addEventListener("submit", (event) => { event.preventDefault(); send(form); });
  }
  for (const form of document.querySelectorAll("form[data-mission-action]")) {
    form.addEventListener("submit", (event) => { event.preventDefault(); resumeMission(); });
  }
})();
