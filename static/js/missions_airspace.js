/* The planner's view of the shared airspace and the ground: the other drones'
   reservations on the map, the leg of this plan that would meet one (from the ground's
   check), and the plan's height profile over the imported terrain. */
(function () {
  "use strict";
  const M = window.SkyhiveMissions;
  const planner = window.skyhivePlanner;
  const config = JSON.parse(document.getElementById("planner-config").textContent);
  const $ = (id) => document.getElementById(id);
  const SVG = "http://www.w3.org/2000/svg";
  const RESERVATIONS_EVERY_MS = 10000;
  const CHECK_AFTER_MS = 600;
  if (!planner) return;

  const reservedLayer = L.layerGroup().addTo(planner.map);
  const conflictLayer = L.layerGroup().addTo(planner.map);
  const positions = {};

  function clock(iso) {
    return new Date(iso).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit" });
  }

  function drawReservations(answer) {
    reservedLayer.clearLayers();
    for (const r of answer.reservations || []) {
      for (const leg of r.legs) {
        const band = `${leg.band_m[0].toFixed(0)}–${leg.band_m[1].toFixed(0)} m`;
        L.polyline([leg.start, leg.end], { color: "#e08a00", weight: 6, opacity: 0.5, className: "reserved-leg" })
          .bindTooltip(`${r.drone_id}: ${band}, ${clock(leg.window[0])}–${clock(leg.window[1])}`)
          .addTo(reservedLayer);
      }
    }
  }

  async function loadReservations() {
    if (!config.reservationsUrl) return;
    try {
      drawReservations(await M.api("GET", config.reservationsUrl));
    } catch (error) {
      reservedLayer.clearLayers();
    }
  }

  async function loadDrones() {
    if (!config.dronesUrl) return;
    const answer = await M.api("GET", config.dronesUrl);
    for (const d of Array.isArray(answer) ? answer : answer.results || []) {
      positions[d.drone_id] = d.position ? [d.position.lat, d.position.lon] : null;
    }
  }

  /* A drone's last known position: from the list loaded with the page once it is in,
     else (a drone beyond its first page) asked for on its own; null when it has none. */
  async function dronePosition(id) {
    await dronesLoaded;
    if (!(id in positions) && config.dronesUrl) {
      try {
        const d = await M.api("GET", `${config.dronesUrl}${encodeURIComponent(id)}/`);
        positions[id] = d.position ? [d.position.lat, d.position.lon] : null;
      } catch (error) {
        return null;
      }
    }
    return positions[id] || null;
  }

  function showConflicts(conflicts) {
    conflictLayer.clearLayers();
    const box = $("airspace-conflicts");
    box.querySelector("ul").replaceChildren(...conflicts.map((c) => {
      L.polyline(c.leg, { color: "#c33", weight: 5, className: "conflicting-leg" }).bindTooltip(c.message).addTo(conflictLayer);
      L.circleMarker(c.at, { radius: 6, color: "#c33", className: "conflict-point" }).addTo(conflictLayer);
      const item = document.createElement("li");
      item.textContent = c.message;
      return item;
    }));
    box.hidden = !conflicts.length;
  }

  function svg(name, attributes) {
    const element = document.createElementNS(SVG, name);
    for (const [key, value] of Object.entries(attributes)) element.setAttribute(key, String(value));
    return element;
  }

  // Runs of consecutive known values (the ground has none where no terrain is imported).
  function runs(xs, ys) {
    const found = [];
    let run = [];
    xs.forEach((x, i) => {
      if (ys[i] === null) { if (run.length) found.push(run); run = []; } else run.push([x, ys[i]]);
    });
    if (run.length) found.push(run);
    return found;
  }

  // The height on a polyline of [distance, height] corners at distance d.
  function heightAt(corners, d) {
    for (let i = 1; i < corners.length; i++) {
      const [d0, h0] = corners[i - 1], [d1, h1] = corners[i];
      if (d <= d1 || i === corners.length - 1) return d1 > d0 ? h0 + ((h1 - h0) * (Math.min(d, d1) - d0)) / (d1 - d0) : h1;
    }
    return corners[0][1];
  }

  /* A leg flown while a climb is under way: the height the drone has surely reached along
     it (dashed, `data-edge` its corners in metres), the band up to the level path shaded,
     and the lowest clearance on it marked; red where the terrain check refuses it. */
  function drawSlant(chart, slant, minimum, x, y) {
    const mark = slant.refused ? " refused" : "";
    const edge = slant.edge.map(([d, h]) => `${x(d)},${y(h)}`).join(" ");
    const level = `${x(slant.to_m)},${y(slant.level_m[1])} ${x(slant.from_m)},${y(slant.level_m[0])}`;
    chart.append(svg("polygon", { points: `${edge} ${level}`, class: `profile-slant-band${mark}` }));
    const line = svg("polyline", { points: edge, class: `profile-slant${mark}`, "data-step": slant.index, "data-edge": JSON.stringify(slant.edge) });
    const title = svg("title", {});
    title.textContent = slantText(slant, minimum);
    line.append(title);
    chart.append(line);
    if (slant.lowest_at_m === null) return;
    const at = svg("circle", { cx: x(slant.lowest_at_m), cy: y(heightAt(slant.edge, slant.lowest_at_m)), r: 3, class: `profile-slant-lowest${mark}` });
    chart.append(at);
  }

  // "Step 2 flown while climbing: at least 12 m above ground at 0.15 km; climbing out to
  // 0.04 km; refused: below the minimum of 30 m".
  function slantText(slant, minimum) {
    const km = (d) => `${(d / 1000).toFixed(2)} km`;
    let text = `Step ${slant.index} flown while climbing`;
    const lowest = slant.lowest_clearance_m;
    if (lowest !== null) text += lowest >= 0 ? `: at least ${lowest.toFixed(0)} m above ground` : `: as much as ${(-lowest).toFixed(0)} m below ground`;
    if (lowest !== null) text += ` at ${km(slant.lowest_at_m)}`;
    if (slant.climbing_out_to_m !== null) {
      const rise = slant.climb_out_rise_m;
      text += `; climbing out to ${km(slant.climbing_out_to_m)}` + (rise !== null && rise > 0 ? `, over terrain up to ${rise.toFixed(1)} m above where the climb began` : "");
    }
    if (!slant.refused) return text;
    const low = lowest !== null && lowest < minimum;
    return text + (low ? `; refused: below the minimum of ${minimum} m` : "; refused: climbing out, the terrain rises above where the climb began");
  }

  function listSlants(profile) {
    const list = $("height-profile-slants");
    const slants = (profile && profile.slants) || [];
    list.replaceChildren(...slants.map((slant) => {
      const item = document.createElement("li");
      item.textContent = slantText(slant, profile.minimum_clearance_m);
      if (slant.refused) item.classList.add("refused");
      item.dataset.step = slant.index;
      return item;
    }));
    list.hidden = !slants.length;
  }

  function drawProfile(profile) {
    const figure = $("height-profile");
    const chart = $("height-profile-chart");
    chart.replaceChildren();
    listSlants(profile);
    if (!profile || profile.distance_m.length < 2) { figure.hidden = true; return; }
    const W = 600, H = 170, PAD = 18;
    const ground = profile.ground_m.filter((g) => g !== null);
    const low = Math.min(0, ...ground), high = Math.max(1, ...profile.height_m, ...ground);
    const length = Math.max(1, profile.distance_m[profile.distance_m.length - 1]);
    const x = (d) => (PAD + (d / length) * (W - 2 * PAD)).toFixed(1);
    const y = (h) => (H - PAD - ((h - low) / (high - low)) * (H - 2 * PAD)).toFixed(1);
    for (const run of runs(profile.distance_m, profile.ground_m)) {
      const top = run.map(([d, g]) => `${x(d)},${y(g)}`).join(" ");
      const base = `${x(run[run.length - 1][0])},${y(low)} ${x(run[0][0])},${y(low)}`;
      chart.append(svg("polygon", { points: `${top} ${base}`, class: "profile-ground" }));
    }
    for (const slant of profile.slants || []) drawSlant(chart, slant, profile.minimum_clearance_m, x, y);
    const flight = profile.distance_m.map((d, i) => `${x(d)},${y(profile.height_m[i])}`).join(" ");
    chart.append(svg("polyline", { points: flight, class: "profile-flight" }));
    for (const step of profile.steps) {
      const dot = svg("circle", { cx: x(step.distance_m), cy: y(step.height_m), r: 2.5, class: "profile-step" });
      const title = svg("title", {});
      title.textContent = `Step ${step.index}: ${step.height_m} m above home`;
      dot.append(title);
      chart.append(dot);
    }
    const label = svg("text", { x: PAD, y: 12, class: "profile-label" });
    label.textContent = `${high.toFixed(0)} m`;
    chart.append(label);
    const clearance = profile.distance_m.map((d, i) => (profile.ground_m[i] === null ? null : profile.height_m[i] - profile.ground_m[i]));
    const known = clearance.filter((c) => c !== null);
    $("height-profile-summary").textContent = `${(length / 1000).toFixed(2)} km, highest ${Math.max(...profile.height_m).toFixed(0)} m above home` +
      (known.length ? `, lowest ${Math.min(...known).toFixed(0)} m above the terrain` : ", no terrain imported under it");
    figure.hidden = false;
  }

  function show(answer) {
    drawProfile(answer.profile);
    showConflicts(answer.conflicts || []);
  }

  // A changed plan is checked again shortly after the last change. Only the newest
  // answer is drawn (Send's own check counts as one), so an older one never hides it.
  let timer = null;
  let checksAsked = 0;
  document.addEventListener("skyhive:steps-changed", () => {
    clearTimeout(timer);
    timer = setTimeout(async () => {
      const asked = ++checksAsked;
      const steps = planner.steps;
      if (!steps.length) { drawProfile(null); showConflicts([]); return; }
      let answer = null;
      try {
        answer = await M.api("POST", config.checkUrl, { steps, drone: $("drone-choice").value || null });
      } catch (error) { /* no profile is drawn */ }
      if (asked !== checksAsked) return;
      if (answer) show(answer);
      else drawProfile(null);
    }, CHECK_AFTER_MS);
  });
  document.addEventListener("skyhive:plan-checked", (event) => { checksAsked++; show(event.detail); });
  $("drone-choice").addEventListener("change", () => document.dispatchEvent(new CustomEvent("skyhive:steps-changed")));

  const dronesLoaded = loadDrones().catch(() => null);
  window.skyhiveAirspace = { dronePosition, reload: loadReservations };
  loadReservations();
  setInterval(loadReservations, RESERVATIONS_EVERY_MS);
})();
