/* Shared helpers of the mission pages: the JSON API with CSRF, a Leaflet map with the
   portal's base layers (static/js/map_base.js), colours per drone. */
(function () {
  "use strict";

  function csrfToken() {
    const meta = document.querySelector('meta[name="csrf-token"]');
    return meta ? meta.content : "";
  }

  async function api(method, url, body) {
    const options = { method, headers: { Accept: "application/json", "X-CSRFToken": csrfToken() }, credentials: "same-origin" };
    if (body instanceof FormData) {
      options.body = body;
    } else if (body !== undefined) {
      options.headers["Content-Type"] = "application/json";
      options.body = JSON.stringify(body);
    }
    const response = await fetch(url, options);
    let data = null;
    try { data = await response.json(); } catch (e) { data = null; }
    if (!response.ok) {
      const message = (data && data.error) || `${response.status} ${response.statusText}`;
      const error = new Error(message);
      error.status = response.status;
      error.fields = (data && data.fields) || {};
      error.code = (data && data.code) || null;
      throw error;
    }
    return data;
  }

  function escapeHtml(text) {
    return String(text).replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
  }

  function makeMap(elementId) {
    return SkyhiveMap.create(elementId, { zoomControl: true });
  }

  /* Shows the points with some room around them, never closer than zoom 17 (as the fleet
     map): a plan or track of one point has bounds of no size, which Leaflet would fill
     at the map's maximum zoom, a view some 50 m across in which the zones, fences and
     homes around it are out of sight. Not animated, so the view is final at once. */
  const FIT_MAX_ZOOM = 17;
  function fitTo(map, points) {
    if (!points.length) return;
    map.fitBounds(L.latLngBounds(points).pad(0.2), { maxZoom: FIT_MAX_ZOOM, animate: false });
  }

  const PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2"];
  const assigned = new Map();
  function colourFor(droneId) {
    if (!assigned.has(droneId)) assigned.set(droneId, PALETTE[assigned.size % PALETTE.length]);
    return assigned.get(droneId);
  }

  function seconds(value) {
    return value === null || value === undefined ? "–" : `${Number(value).toFixed(1)} s`;
  }

  /* Great-circle distance in metres (the page only shows it). */
  function distance(a, b) {
    const r = 6371008.8, rad = Math.PI / 180;
    const dLat = (b[0] - a[0]) * rad, dLon = (b[1] - a[1]) * rad;
    const h = Math.sin(dLat / 2) ** 2 + Math.cos(a[0] * rad) * Math.cos(b[0] * rad) * Math.sin(dLon / 2) ** 2;
    return 2 * r * Math.asin(Math.sqrt(h));
  }

  function liveSocket(path, onMessage, onState) {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    let closed = false;
    let socket = null;
    function open() {
      socket = new WebSocket(`${scheme}://${location.host}${path}`);
      socket.onopen = () => onState && onState(true);
      socket.onmessage = (event) => onMessage(JSON.parse(event.data));
      socket.onclose = (event) => {
        onState && onState(false);
        // 4401/4403: not allowed; retrying would not help.
        if (!closed && event.code !== 4401 && event.code !== 4403) setTimeout(open, 2000);
      };
    }
    open();
    return { close() { closed = true; socket && socket.close(); } };
  }

  /* Markup with no style attributes (the page's Content-Security-Policy refuses them):
     colours, widths and turns named in data attributes are set through the DOM instead. */
  function applyDataStyles(root) {
    for (const el of root.querySelectorAll("[data-bg]")) el.style.background = el.dataset.bg;
    for (const el of root.querySelectorAll("[data-width]")) el.style.width = el.dataset.width;
    for (const el of root.querySelectorAll("[data-turn]")) el.style.transform = `rotate(${el.dataset.turn}deg)`;
    return root;
  }

  function fill(element, html) {
    element.innerHTML = html;
    return applyDataStyles(element);
  }

  /* A drone on a map: its state's colour, its heading arrow, its name and altitude. */
  function droneIcon(drone, label) {
    const body = document.createElement("div");
    const turn = drone.heading === null || drone.heading === undefined ? null : Math.round(drone.heading);
    fill(body, `${turn === null ? "" : `<span class="arrow" data-turn="${turn}"></span>`}<span class="dot"></span><span class="label">${escapeHtml(label)}</span>`);
    return L.divIcon({ className: `drone-marker state-${drone.state || "lost_link"}`, html: body, iconSize: [18, 18], iconAnchor: [9, 9] });
  }

  window.SkyhiveMissions = { api, escapeHtml, makeMap, fitTo, colourFor, seconds, distance, liveSocket, fill, droneIcon };
})();
