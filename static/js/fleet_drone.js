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
    if (window.SkyhiveWind) window.SkyhiveWind.show(drone.fc);
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
    // Only this drone resumes: its companions in the mission hold or fly as they were.
    const response = await fetch(`/api/v1/missions/${encodeURIComponent(missionId)}/resume/`, {
      method: "POST",
      credentials: "same-origin",
      headers: { "Content-Type": "application/json", "X-CSRFToken": csrf, Accept: "application/json" },
      body: JSON.stringify({ drone: droneId }),
    });
    const body = await response.json().catch(() => ({}));
    result.textContent = response.ok ? "resume: the drone carries on with its mission" : `resume: ${response.status} ${body.error || ""}`;
    result.dataset.status = response.ok ? "ok" : "error";
  }

  /* Post one command; a move beyond the envelope's defaults comes back 409
     confirmation_required and is sent again only once the drone's id has been typed. */
  async function post(command, params, buttons, confirmed) {
    buttons.forEach((b) => { b.disabled = true; });
    result.textContent = `${command}: waiting for ${droneId}…`;
    try {
      const body = { command, params };
      if (confirmed) body.confirm_beyond_defaults = true;
      const response = await fetch(config.commandUrl, {
        method: "POST",
        credentials: "same-origin",
        headers: { "Content-Type": "application/json", "X-CSRFToken": csrf, Accept: "application/json" },
        body: JSON.stringify(body),
      });
      const answer = await response.json().catch(() => ({ error: response.statusText }));
      if (response.status === 409 && answer.code === "confirmation_required") {
        askBeyondDefaults(command, params, answer.error);
        result.textContent = `${command}: not sent, waiting for your confirmation.`;
        result.dataset.status = "error";
        return;
      }
      if (response.ok) {
        const verdict = answer.ok ? "ok" : `refused: ${answer.error}`;
        result.textContent = `${command}: ${verdict}\n${JSON.stringify(answer.result || {}, null, 2)}`;
      } else {
        result.textContent = `${command}: ${response.status} ${answer.error || ""}`;
      }
      result.dataset.status = response.ok && answer.ok ? "ok" : "error";
    } catch (error) {
      result.textContent = `${command}: ${error}`;
      result.dataset.status = "error";
    } finally {
      buttons.forEach((b) => { b.disabled = false; });
    }
  }

  const beyond = document.getElementById("beyond-defaults");
  const beyondTyped = document.getElementById("beyond-defaults-typed");
  let pending = null;

  function askBeyondDefaults(command, params, message) {
    pending = { command, params };
    document.getElementById("beyond-defaults-message").textContent = `${command}: ${message}`;
    beyondTyped.value = "";
    beyond.hidden = false;
    beyondTyped.focus();
  }

  if (beyond) {
    document.getElementById("beyond-defaults-send").addEventListener("click", () => {
      if (!pending) return;
      if (beyondTyped.value.trim() !== beyondTyped.dataset.confirmTyped) {
        result.textContent = `${pending.command}: not sent. Type ${beyondTyped.dataset.confirmTyped} to confirm.`;
        result.dataset.status = "error";
        beyondTyped.focus();
        return;
      }
      const { command, params } = pending;
      pending = null;
      beyond.hidden = true;
      post(command, params, beyond.querySelectorAll("button"), true);
    });
    document.getElementById("beyond-defaults-cancel").addEventListener("click", () => {
      if (pending) result.textContent = `${pending.command}: not sent.`;
      pending = null;
      beyond.hidden = true;
    });
  }

  async function send(form) {
    const command = form.dataset.command;
    if (!confirmed(form, command)) return;
    if (form.dataset.confirm && !window.confirm(form.dataset.confirm)) return;
    await post(command, params(form), form.querySelectorAll("button"), false);
  }

  for (const form of document.querySelectorAll("form[data-command]")) {
    form.addEventListener("submit", (event) => { event.preventDefault(); send(form); });
  }
  for (const form of document.querySelectorAll("form[data-mission-action]")) {
    form.addEventListener("submit", (event) => { event.preventDefault(); resumeMission(); });
  }
})();
