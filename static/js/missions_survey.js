/* Survey planning from a camera on the planner page: camera presets (the drone's own camera
   preselected), overlaps and ground resolution or height → spacings, height and the
   estimates per drone; and the organisation's drones on the planner map. */
(function () {
  "use strict";
  const M = window.SkyhiveMissions;
  const config = JSON.parse(document.getElementById("planner-config").textContent);
  const $ = (id) => document.getElementById(id);
  const CUSTOM = "__custom__";
  let carried = {};

  function camera() {
    if ($("survey-preset").value !== CUSTOM) return $("survey-preset").value;
    return {
      sensor_width_mm: Number($("survey-sensor-w").value),
      sensor_height_mm: Number($("survey-sensor-h").value),
      focal_length_mm: Number($("survey-focal").value),
      image_width_px: Number($("survey-image-w").value),
      image_height_px: Number($("survey-image-h").value),
    };
  }

  function request(vertices, drone) {
    const body = {
      vertices, camera: camera(),
      overlap: Number($("survey-overlap").value) / 100,
      sidelap: Number($("survey-sidelap").value) / 100,
      speed_m_s: Number($("survey-speed").value),
    };
    if ($("survey-mode").value === "gsd") body.gsd_cm = Number($("survey-gsd").value);
    else body.height_m = Number($("survey-height").value);
    if (drone) body.drones = [drone];
    return body;
  }

  function minutes(seconds) {
    const m = Math.floor(seconds / 60), s = Math.round(seconds % 60);
    return `${m} min ${String(s).padStart(2, "0")} s`;
  }

  function row(term, value, cls) {
    const dt = document.createElement("dt");
    dt.textContent = term;
    const dd = document.createElement("dd");
    dd.textContent = value;
    if (cls) dd.className = cls;
    $("survey-result").append(dt, dd);
  }

  function show(planned) {
    const g = planned.geometry, total = planned.total;
    $("survey-result").replaceChildren();
    row("Height", `${g.height_m.toFixed(1)} m`);
    row("Ground resolution", `${g.gsd_cm.toFixed(2)} cm/px`);
    row("Footprint", `${g.footprint_width_m.toFixed(1)} × ${g.footprint_height_m.toFixed(1)} m`);
    row("Line spacing", `${g.line_spacing_m.toFixed(1)} m`);
    row("Photo spacing", `${g.photo_spacing_m.toFixed(1)} m`);
    row("Distance", `${(total.distance_m / 1000).toFixed(2)} km`);
    row("Flight time", minutes(total.flight_time_s));
    row("Photos", String(total.photos));
    for (const share of planned.drones) {
      const used = `${share.battery_pct.toFixed(0)} % of a full battery`;
      const end = share.battery_at_end_pct === null ? "" : `, ${share.battery_at_end_pct.toFixed(0)} % left at the end`;
      row(`Battery (${share.drone})`, used + end, share.enough === false ? "survey-short" : "");
    }
  }

  async function plan(vertices, drone) {
    try {
      const planned = await M.api("POST", config.surveyUrl, request(vertices, drone));
      show(planned);
      return planned;
    } catch (error) {
      $("survey-result").replaceChildren();
      throw error;
    }
  }

  function changed() {
    document.dispatchEvent(new CustomEvent("skyhive:survey-change"));
  }

  function choosePreset() {
    const drone = $("drone-choice").value;
    const preset = carried[drone] || Object.values(carried)[0];
    if (preset) $("survey-preset").value = preset;
    $("survey-custom").hidden = $("survey-preset").value !== CUSTOM;
  }

  async function loadCameras() {
    const answer = await M.api("GET", config.camerasUrl);
    carried = answer.drones || {};
    const select = $("survey-preset");
    for (const c of answer.presets) {
      select.add(new Option(`${c.name} (${c.sensor_width_mm}×${c.sensor_height_mm} mm, ${c.focal_length_mm} mm)`, c.name));
    }
    select.add(new Option("Custom camera…", CUSTOM));
    choosePreset();
  }

  // The organisation's drones where they are: the planner picks areas near them.
  async function drawDrones() {
    const planner = window.skyhivePlanner;
    if (!planner || !config.dronesUrl) return;
    const answer = await M.api("GET", config.dronesUrl);
    const drones = Array.isArray(answer) ? answer : answer.results || [];
    const layer = L.layerGroup().addTo(planner.map);
    for (const d of drones) {
      if (!d.position) continue;
      L.circleMarker([d.position.lat, d.position.lon], {
        radius: 7, color: d.online ? M.colourFor(d.drone_id) : "#888", weight: 2, fillOpacity: 0.6,
        className: "planner-drone",
      }).bindTooltip(d.drone_id + (d.online ? "" : " (offline)")).addTo(layer);
    }
  }

  $("survey-enabled").addEventListener("change", () => {
    $("survey-fields").hidden = !$("survey-enabled").checked;
    changed();
  });
  $("survey-mode").addEventListener("change", () => {
    const gsd = $("survey-mode").value === "gsd";
    $("survey-gsd-label").hidden = !gsd;
    $("survey-height-label").hidden = gsd;
    changed();
  });
  $("survey-preset").addEventListener("change", () => {
    $("survey-custom").hidden = $("survey-preset").value !== CUSTOM;
    changed();
  });
  $("drone-choice").addEventListener("change", () => {
    choosePreset();
    if ($("survey-enabled").checked) changed();
  });
  for (const id of ["survey-overlap", "survey-sidelap", "survey-gsd", "survey-height", "survey-speed",
    "survey-sensor-w", "survey-sensor-h", "survey-focal", "survey-image-w", "survey-image-h"]) {
    $(id).addEventListener("change", changed);
  }

  window.skyhiveSurvey = { active: () => $("survey-enabled").checked, plan };
  loadCameras().catch(() => null);
  drawDrones().catch(() => null);
})();
