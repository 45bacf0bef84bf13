/* The Mission Planner: three clicked corners → coverage from the API → an editable,
   drag-and-drop step list → create and start the mission. */
(function () {
  "use strict";
  const M = window.SkyhiveMissions;
  const config = JSON.parse(document.getElementById("planner-config").textContent);
  const $ = (id) => document.getElementById(id);

  // Parameter forms per step command (docs/protocol.md): name, kind, default.
  const PARAMS = {
    arm: [], land: [], takepic: [], rebuildtelemetry: [],
    disarm: [["force", "bool", false]],
    resetfc: [["force", "bool", false]],
    takeoff: [["altitude", "number", 10]],
    changeN: [["value", "number", 5]],
    changeE: [["value", "number", 5]],
    altitude: [["value", "number", 2]],
    navigate: [["lat", "number", 0], ["lon", "number", 0], ["altitude_delta", "number", 0]],
    objrequest: [["value", "text", "AttitudeActual"]],
    wait_for_flight: [["horizontal_tolerance", "number", 2], ["vertical_tolerance", "number", 2]],
    sleep: [["value", "number", 2]],
    virtualalarm: [["level", ["CRITICAL", "OUT_MEASURE"], "CRITICAL"], ["message", "text", ""]],
    sense: [["sensor", "text", "CO2"]],
  };

  const map = M.makeMap("planner-map", config);
  map.setView(config.center, 18);
  const layer = L.layerGroup().addTo(map);
  const fenceLayer = L.layerGroup().addTo(map);
  // Legs the envelope refuses (the straight line between two targets crosses the fence).
  const legLayer = L.layerGroup().addTo(map);
  let vertices = [];
  let area = null;
  let steps = [];
  // What the operator agreed to holds for the plan as it was then (its steps and the
  // coverage request they came from): a changed plan is a new mission, whose agreements
  // and draft do not carry over, while the same plan computed again keeps them.
  // CONFIRM typed for steps beyond the envelope's defaults:
  let confirmedFor = null;
  // Legs whose terrain clearance could not be checked were shown, and Send pressed again:
  let terrainSeenFor = null;
  // The mission already created for the plan, { id, plan } (a refused start is retried on it):
  let draft = null;
  // Each coverage request is numbered; only the newest one's answer is applied.
  let coverageAsked = 0;
  // The newest coverage request, awaited by Send (a field left by clicking Send asks again).
  let coverage = Promise.resolve();
  // One send at a time: a second press while one is checked would create a second mission.
  let sending = false;

  function planKey() {
    return JSON.stringify({ steps, request: (area && area.request) || null });
  }

  function showError(message) {
    const box = $("planner-error");
    box.textContent = message || "";
    box.hidden = !message;
  }

  function intermediateAction() {
    const kind = $("intermediate-action").value;
    const value = $("action-param").value;
    if (!kind) return null;
    if (kind === "takepic") return "takepic";
    if (kind === "sleep") return { command: "sleep", params: { value: Number(value) } };
    return { command: "sense", params: { sensor: value } };
  }

  function defaults(command) {
    const params = {};
    for (const [name, , value] of PARAMS[command] || []) params[name] = value;
    return params;
  }

  function actionSteps(action) {
    if (action === "takepic") return [{ command: "takepic", params: {} }];
    return action ? [{ command: action.command, params: { ...action.params } }] : [];
  }

  /* A terrain-following path (from the ground): every point climbs or descends to its
     height above home at its leg's speed; only the coverage's waypoints take the action. */
  function followedSteps(altitude, action) {
    let height = altitude;
    for (const p of area.followed) {
      const delta = Math.round((p.height_m - height) * 1000) / 1000;
      steps.push({ command: "navigate", params: { lat: p.lat, lon: p.lon, altitude_delta: delta, speed: p.speed_m_s } });
      steps.push({ command: "wait_for_flight", params: { horizontal_tolerance: 2, vertical_tolerance: 2 } });
      if (p.waypoint) steps.push(...actionSteps(action));
      height += delta;
    }
    steps.push({ command: "land", params: {} });
    renderSteps();
  }

  function buildSteps() {
    if (!area) return;
    const altitude = Number($("altitude").value);
    const action = intermediateAction();
    steps = [{ command: "arm", params: {} }, { command: "takeoff", params: { altitude } }];
    if (area.followed) { followedSteps(altitude, action); return; }
    for (const [lat, lon] of area.waypoints) {
      steps.push({ command: "navigate", params: { lat, lon, altitude_delta: 0 } });
      steps.push({ command: "wait_for_flight", params: { horizontal_tolerance: 2, vertical_tolerance: 2 } });
      if (action === "takepic") steps.push({ command: "takepic", params: {} });
      else if (action) steps.push({ command: action.command, params: { ...action.params } });
    }
    steps.push({ command: "land", params: {} });
    renderSteps();
  }

  function paramInput(step, name, kind) {
    const value = step.params[name];
    let input;
    if (Array.isArray(kind)) {
      input = document.createElement("select");
      for (const option of kind) input.add(new Option(option, option, false, option === value));
    } else {
      input = document.createElement("input");
      if (kind === "bool") { input.type = "checkbox"; input.checked = Boolean(value); }
      else { input.type = kind === "number" ? "number" : "text"; input.step = "any"; input.value = value ?? ""; }
    }
    input.name = name;
    input.addEventListener("change", () => {
      step.params[name] = kind === "bool" ? input.checked : kind === "number" ? Number(input.value) : input.value;
    });
    const label = document.createElement("label");
    label.className = "param";
    label.append(`${name} `, input);
    return label;
  }

  // One line for the whole list: the long list itself is one click away.
  function summarise() {
    const navigations = steps.filter((s) => s.command === "navigate").length;
    const photos = steps.filter((s) => s.command === "takepic").length;
    const parts = [`${steps.length} steps`];
    if (navigations) parts.push(`${navigations} waypoints`);
    if (photos) parts.push(`${photos} photos`);
    $("step-summary").textContent = steps.length ? parts.join(" · ") : "none yet";
  }

  function renderSteps() {
    summarise();
    document.dispatchEvent(new CustomEvent("skyhive:steps-changed"));
    const list = $("step-list");
    list.replaceChildren();
    steps.forEach((step, i) => {
      const item = document.createElement("li");
      item.className = "step";
      item.draggable = true;
      item.dataset.index = String(i);
      const command = document.createElement("select");
      command.className = "command";
      command.setAttribute("aria-label", `Command of step ${i}`);
      for (const name of Object.keys(PARAMS)) command.add(new Option(name, name, false, name === step.command));
      command.addEventListener("change", () => { step.command = command.value; step.params = defaults(step.command); renderSteps(); });
      const remove = document.createElement("button");
      remove.type = "button";
      remove.className = "link remove";
      remove.textContent = "✕";
      remove.title = "Remove this step";
      remove.addEventListener("click", () => { steps.splice(i, 1); renderSteps(); });
      const handle = document.createElement("span");
      handle.className = "handle";
      handle.textContent = "⠿";
      item.append(handle, command);
      for (const [name, kind] of PARAMS[step.command] || []) item.append(paramInput(step, name, kind));
      item.append(remove);
      item.addEventListener("dragstart", (event) => { event.dataTransfer.setData("text/plain", String(i)); item.classList.add("dragging"); });
      item.addEventListener("dragend", () => item.classList.remove("dragging"));
      item.addEventListener("dragover", (event) => event.preventDefault());
      item.addEventListener("drop", (event) => {
        event.preventDefault();
        const from = Number(event.dataTransfer.getData("text/plain"));
        if (Number.isNaN(from) || from === i) return;
        const [moved] = steps.splice(from, 1);
        steps.splice(i, 0, moved);
        renderSteps();
      });
      list.append(item);
    });
  }

  function drawArea() {
    layer.clearLayers();
    vertices.forEach((v, i) => L.marker(v, { title: "ABC"[i] }).addTo(layer).bindTooltip("ABC"[i], { permanent: true }));
    $("vertex-count").textContent = String(vertices.length);
    if (!area) { $("waypoint-count").textContent = "0"; $("area").textContent = "–"; return; }
    const [a, b, c] = vertices;
    const d = [a[0] + (c[0] - b[0]), a[1] + (c[1] - b[1])];
    L.polygon([a, b, c, d], { color: "#555", weight: 1, fillOpacity: 0.05 }).addTo(layer);
    L.polyline(area.waypoints, { color: "#1f77b4", weight: 2 }).addTo(layer);
    area.waypoints.forEach((p, i) => L.circleMarker(p, { radius: 3, color: i === 0 ? "#2ca02c" : "#1f77b4", className: "waypoint" }).addTo(layer));
    $("waypoint-count").textContent = String(area.waypoints.length);
    $("area").textContent = area.area_m2.toFixed(0);
  }

  // Terrain following: heights are placed above the ground at the envelope's home,
  // else the chosen drone's position, else the first corner.
  let envelopeHome = null;
  async function followSpec() {
    if (!$("follow-terrain").checked) return null;
    await envelopeLoaded;
    const airspace = window.skyhiveAirspace;
    const chosen = $("drone-choice").value;
    const drone = !envelopeHome && chosen && airspace ? await airspace.dronePosition(chosen) : null;
    return { home: envelopeHome || drone || vertices[0], tolerance_m: Number($("follow-tolerance").value) };
  }

  // With a camera survey switched on, the spacings and the height come from the camera.
  async function areaFor(points, asked) {
    const survey = window.skyhiveSurvey;
    const body = { vertices: points, step_distance: Number($("step-distance").value), altitude: Number($("altitude").value) };
    if (survey && survey.active()) {
      const planned = await survey.plan(points, $("drone-choice").value || null);
      if (asked !== coverageAsked) return null; // an older survey does not rewrite the form
      $("altitude").value = planned.geometry.height_m.toFixed(1);
      $("step-distance").value = planned.coverage.step_distance.toFixed(1);
      $("intermediate-action").value = "takepic";
      if (!$("follow-terrain").checked) return planned.coverage;
      Object.assign(body, { step_distance: planned.coverage.step_distance, line_spacing: planned.line_spacing,
                            altitude: planned.geometry.height_m });
    }
    const following = await followSpec();
    if (following) body.terrain_following = following;
    const answer = await M.api("POST", config.coverageUrl, body);
    if (following) answer.request = body;
    return answer;
  }

  function requestCoverage() {
    coverage = computeCoverage();
    return coverage;
  }

  /* Send works on the plan as the form shows it: it waits for the coverage asked for last,
     and for any asked for meanwhile. */
  async function coverageSettled() {
    let awaited;
    do {
      awaited = coverage;
      await awaited;
    } while (awaited !== coverage);
  }

  async function computeCoverage() {
    if (vertices.length !== 3) return;
    const asked = ++coverageAsked;
    showError("");
    let answer = null;
    let failure = null;
    try {
      answer = await areaFor(vertices, asked);
    } catch (error) {
      failure = error;
    }
    if (asked !== coverageAsked) return; // a newer request (or a new area) answers instead
    area = answer;
    if (failure) showError(failure.message);
    else buildSteps();
    drawArea();
  }

  map.on("click", (event) => {
    if (vertices.length === 3) { vertices = []; area = null; coverageAsked++; }
    vertices.push([event.latlng.lat, event.latlng.lng]);
    drawArea();
    requestCoverage();
  });
  $("clear-area").addEventListener("click", () => { vertices = []; area = null; steps = []; coverageAsked++; renderSteps(); drawArea(); });
  $("step-distance").addEventListener("change", requestCoverage);
  document.addEventListener("skyhive:survey-change", requestCoverage);
  $("altitude").addEventListener("change", () => (area && area.followed ? requestCoverage() : area ? buildSteps() : null));
  // Without a home in the envelope, terrain heights are placed above the chosen drone.
  $("drone-choice").addEventListener("change", () => (area && area.followed && !envelopeHome ? requestCoverage() : null));
  for (const id of ["follow-terrain", "follow-tolerance"]) {
    $(id).addEventListener("change", () => {
      $("follow-tolerance-label").hidden = !$("follow-terrain").checked;
      requestCoverage();
    });
  }
  $("intermediate-action").addEventListener("change", () => {
    const kind = $("intermediate-action").value;
    $("action-param-label").hidden = !(kind === "sleep" || kind === "sense");
    $("action-param-name").textContent = kind === "sense" ? "Sensor" : "Seconds";
    $("action-param").value = kind === "sense" ? "CO2" : "2";
    if (area) buildSteps();
  });
  $("action-param").addEventListener("change", () => (area ? buildSteps() : null));
  $("add-step").addEventListener("click", () => {
    $("step-details").open = true;
    const command = $("new-step-command").value;
    steps.push({ command, params: defaults(command) });
    renderSteps();
  });

  // The organisation's geofence: inclusion zones green, exclusion zones red.
  function drawFence(fence) {
    fenceLayer.clearLayers();
    const style = (inclusion) => ({ color: inclusion ? "#2a7" : "#c33", weight: 2, fillOpacity: 0.08, interactive: false });
    (fence.polygons || []).forEach((p) => L.polygon(p.polygon, style(p.inclusion !== false)).addTo(fenceLayer));
    (fence.circles || []).forEach((c) => L.circle(c.circle.center, { radius: c.circle.radius, ...style(c.inclusion !== false) }).addTo(fenceLayer));
  }
  // Terrain heights are asked for only once it is known whether the envelope has a home.
  const envelopeLoaded = M.api("GET", config.envelopeUrl).then((envelope) => {
    envelopeHome = envelope.home || null;
    drawFence(envelope.geoFence);
  }).catch(() => null);

  /* Ask the ground which steps the envelope refuses and mark them (an offending leg is
     drawn in red on the map too); which steps go beyond the envelope's defaults. */
  async function checkEnvelope(drone) {
    const answer = await M.api("POST", config.checkUrl, { steps, drone });
    document.dispatchEvent(new CustomEvent("skyhive:plan-checked", { detail: answer }));
    drawFence(answer.envelope.geoFence);
    legLayer.clearLayers();
    const items = Array.from($("step-list").children);
    items.forEach((item) => { item.classList.remove("outside-envelope", "beyond-defaults"); item.removeAttribute("title"); });
    (answer.beyond_defaults || []).forEach((v) => {
      const item = items[v.index];
      if (item) { item.classList.add("beyond-defaults"); item.title = v.message; }
    });
    answer.violations.forEach((v) => {
      const item = items[v.index];
      if (item) { item.classList.remove("beyond-defaults"); item.classList.add("outside-envelope"); item.title = v.message; }
      if (v.leg) L.polyline(v.leg, { color: "#c33", weight: 4, dashArray: "6 4", className: "offending-leg" }).addTo(legLayer).bindTooltip(`Step ${v.index}: ${v.message}`);
    });
    // The marks are in the step list: open it so they are seen.
    if (answer.violations.length || (answer.beyond_defaults || []).length) $("step-details").open = true;
    if (answer.violations.length) {
      const first = answer.violations[0];
      showError(`Outside the flight envelope (${answer.violations.length} step(s) marked). Step ${first.index}: ${first.message}`);
    }
    showTerrainWarnings(answer.terrain_warnings || []);
    // Only where terrain is imported is a leg without it worth stopping for.
    return { inside: answer.violations.length === 0, beyond: answer.beyond_defaults || [],
             unchecked: answer.terrain_imported ? (answer.terrain_warnings || []).length : 0 };
  }

  /* Where no terrain (or a void) lies under a leg, or under home, its clearance is not
     checked: say so, step by step, before anything is sent. */
  function showTerrainWarnings(warnings) {
    const box = $("terrain-warnings");
    const list = box.querySelector("ul");
    list.replaceChildren(...warnings.map((w) => {
      const item = document.createElement("li");
      item.textContent = w.step === null ? w.message : `Step ${w.step}: ${w.message}`;
      return item;
    }));
    box.hidden = !warnings.length;
  }

  /* Steps beyond the envelope's defaults (allowed by raised limits) are sent only once
     CONFIRM has been typed; the mission and its start then carry the confirmation. */
  function askBeyondDefaults(message) {
    $("beyond-defaults-message").textContent = `${message} Type CONFIRM to send anyway.`;
    $("beyond-defaults-typed").value = "";
    $("beyond-defaults").hidden = false;
    $("beyond-defaults-typed").focus();
  }
  $("beyond-defaults-send").addEventListener("click", () => {
    if ($("beyond-defaults-typed").value.trim() !== "CONFIRM") {
      showError("Not sent: type CONFIRM to fly beyond the envelope's defaults.");
      return;
    }
    confirmedFor = planKey();
    $("beyond-defaults").hidden = true;
    $("planner-form").requestSubmit();
  });
  $("beyond-defaults-cancel").addEventListener("click", () => {
    $("beyond-defaults").hidden = true;
    showError("Not sent.");
  });

  async function createAndStart(drone, plan) {
    const confirm = confirmedFor === plan ? { confirm_beyond_defaults: true } : {};
    if (!draft || draft.plan !== plan) {
      const body = { name: $("mission-name").value, altitude: Number($("altitude").value), steps, ...confirm };
      if (area && area.followed) {
        // The ground builds a terrain-following mission itself, from the same request.
        const r = area.request;
        delete body.steps;
        body.altitude = r.altitude;
        body.coverage = { vertices: r.vertices, step_distance: r.step_distance, line_spacing: r.line_spacing,
                          intermediate_action: intermediateAction(), terrain_following: r.terrain_following };
      } else if (area) {
        body.extensibility = { vertices, vectors: area.vectors, step_distance: area.step_distance,
                               intermediate_action: intermediateAction() };
      }
      draft = { id: (await M.api("POST", config.createUrl, body)).id, plan };
    }
    try {
      await M.api("POST", config.startUrl.replace(config.placeholder, draft.id), { drone, ...confirm });
    } catch (error) {
      if (error.code === "confirmation_required") { askBeyondDefaults(error.message); return; }
      showError(`Saved as a draft, not started: ${error.message}`);
      return;
    }
    location.href = config.missionUrl.replace(config.placeholder, draft.id);
  }

  $("planner-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    if (sending) return;
    sending = true;
    $("send-mission").disabled = true;
    try {
      await coverageSettled();
      if (vertices.length === 3 && !area) return; // the area's coverage failed: its error is shown
      await send();
    } finally {
      sending = false;
      $("send-mission").disabled = false;
    }
  });

  async function send() {
    showError("");
    if (!steps.length) { showError("Click three corners or add steps first."); return; }
    const drone = $("drone-choice").value || null;
    const plan = planKey();
    let checked;
    try {
      checked = await checkEnvelope(drone);
    } catch (error) {
      showError(error.message);
      return;
    }
    if (planKey() !== plan) {
      showError("The plan changed while it was being checked: press Send again to check and send it as it is now.");
      return;
    }
    if (!checked.inside) return;
    if (checked.unchecked && terrainSeenFor !== plan) {
      terrainSeenFor = plan;
      showError("The terrain clearance of some legs cannot be checked (listed below); press Send again to fly them under the envelope's other limits.");
      return;
    }
    if (checked.beyond.length && confirmedFor !== plan) {
      const first = checked.beyond[0];
      askBeyondDefaults(`${checked.beyond.length} step(s) go beyond the envelope's defaults (marked). Step ${first.index}: ${first.message}`);
      return;
    }
    try {
      await createAndStart(drone, plan);
    } catch (error) {
      if (error.code === "confirmation_required") askBeyondDefaults(error.message);
      else showError(error.message);
    }
  }


  // For tests and the console.
  window.skyhivePlanner = { map, get steps() { return steps; }, get area() { return area; }, get vertices() { return vertices; } };
})();
