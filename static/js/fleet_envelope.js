/* The flight-envelope page: the limits in a form, the geofence drawn on the map; admins
   save with PUT (a 400 names the bad field and the stored envelope stays in force). */
(function () {
  "use strict";
  const config = JSON.parse(document.getElementById("envelope-config").textContent);
  const form = document.getElementById("envelope-form");
  const status = document.getElementById("envelope-status");
  const csrf = document.querySelector('meta[name="csrf-token"]').content;
  const limits = ["max_height", "max_distance", "min_move_height", "battery_reserve"];
  const map = SkyhiveMap.create("envelope-map");
  map.setView([38.7369, -9.1427], 13);
  const drawn = L.layerGroup().addTo(map);
  document.getElementById("envelope-export").href = config.apiUrl + "plan/";

  function draw(fence, home) {
    drawn.clearLayers();
    const bounds = [];
    const style = (inclusion) => ({ color: inclusion ? "#2a7" : "#c33", weight: 2, fillOpacity: 0.1 });
    (fence.polygons || []).forEach((p) => {
      const layer = L.polygon(p.polygon, style(p.inclusion !== false)).addTo(drawn);
      bounds.push(layer.getBounds());
    });
    (fence.circles || []).forEach((c) => {
      const layer = L.circle(c.circle.center, { radius: c.circle.radius, ...style(c.inclusion !== false) }).addTo(drawn);
      bounds.push(layer.getBounds());
    });
    if (home) {
      L.circleMarker(home, { radius: 6, color: "#25c" }).bindTooltip("home").addTo(drawn);
      bounds.push(L.latLngBounds([home, home]));
    }
    if (bounds.length) map.fitBounds(bounds.reduce((a, b) => a.extend(b)), { padding: [20, 20], maxZoom: 17 });
  }

  function show(envelope) {
    limits.forEach((name) => { form.elements[name].value = envelope[name]; });
    form.elements.home.value = envelope.home ? envelope.home.join(", ") : "";
    form.elements.geoFence.value = JSON.stringify(envelope.geoFence, null, 2);
    draw(envelope.geoFence, envelope.home);
  }

  function body() {
    const data = {};
    limits.forEach((name) => { data[name] = Number(form.elements[name].value); });
    const home = form.elements.home.value.trim();
    if (home) data.home = home.split(",").map(Number);
    data.geoFence = JSON.parse(form.elements.geoFence.value || "{}");
    return data;
  }

  async function save(data) {
    const response = await fetch(config.apiUrl, {
      method: "PUT",
      credentials: "same-origin",
      headers: { "Content-Type": "application/json", "X-CSRFToken": csrf, Accept: "application/json" },
      body: JSON.stringify(data),
    });
    const answer = await response.json();
    if (!response.ok) {
      status.textContent = answer.error || `Refused (${response.status}).`;
      return;
    }
    show(answer);
    status.textContent = "Saved; the drones get it now.";
  }

  form.addEventListener("submit", (event) => {
    event.preventDefault();
    try {
      save(body());
    } catch (error) {
      status.textContent = `geoFence: ${error.message}`;
    }
  });
  form.elements.plan.addEventListener("change", async () => {
    const file = form.elements.plan.files[0];
    if (!file) return;
    try {
      const plan = JSON.parse(await file.text());
      form.elements.geoFence.value = JSON.stringify(plan.geoFence || {}, null, 2);
      const home = plan.mission && plan.mission.plannedHomePosition;
      if (home) form.elements.home.value = `${home[0]}, ${home[1]}`;
      draw(plan.geoFence || {}, home ? home.slice(0, 2) : null);
      status.textContent = "Fence loaded from the plan; save to put it in force.";
    } catch (error) {
      status.textContent = `The file is not a .plan: ${error.message}`;
    }
  });
  form.elements.geoFence.addEventListener("change", () => {
    try {
      draw(JSON.parse(form.elements.geoFence.value || "{}"), null);
    } catch (error) {
      status.textContent = `geoFence: ${error.message}`;
    }
  });
  /* The form is closed until the stored envelope is in it: what an admin typed or
     imported before then would be overwritten by it, and Save would store the old one. */
  const fields = Array.from(form.elements);
  fields.forEach((element) => { element.disabled = true; });
  status.textContent = "Loading the envelope…";
  fetch(config.apiUrl, { credentials: "same-origin", headers: { Accept: "application/json" } })
    .then((response) => {
      if (!response.ok) throw new Error(`the server answered ${response.status}`);
      return response.json();
    })
    .then((envelope) => {
      show(envelope);
      if (config.editable) fields.forEach((element) => { element.disabled = false; });
      status.textContent = config.editable ? "" : "Only organisation admins change the envelope.";
    })
    .catch((error) => { status.textContent = `The envelope could not be loaded (${error.message}): reload the page.`; });
})();
