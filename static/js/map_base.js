/* What every map in the portal draws underneath its drones, tracks and fences: the tile
   layer the server announces in base.html (#map-layer: its own /tiles/, or none), a metric
   scale and a latitude/longitude grid drawn locally, so a map without any tile (a field
   with no internet and no imported tiles) still shows where and how big things are.
   Loaded by base.html before the pages' scripts; it needs Leaflet only when called. */
(function () {
  "use strict";

  function layerConfig() {
    const el = document.getElementById("map-layer");
    if (!el) return { url: "" };
    try { return JSON.parse(el.textContent) || { url: "" }; } catch (e) { return { url: "" }; }
  }

  // Grid spacings in degrees, fine to coarse; the finest leaving room for its labels wins.
  const STEPS = [0.00001, 0.00002, 0.00005, 0.0001, 0.0002, 0.0005, 0.001, 0.002, 0.005,
    0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10, 30];

  /* The finest step whose lines are at least `minPx` pixels apart over `span` degrees
     drawn across `px` pixels (longitude labels are wider, so they ask for more room). */
  function gridStep(span, px, minPx) {
    for (const step of STEPS) if ((step / span) * px >= minPx) return step;
    return STEPS[STEPS.length - 1];
  }

  function formatDegrees(value, step, positive, negative) {
    const decimals = Math.max(0, Math.ceil(-Math.log10(step)));
    const text = Math.abs(value).toFixed(decimals);
    return `${text}\u00b0 ${value >= 0 ? positive : negative}`;
  }

  function label(latLng, text, anchor) {
    return L.marker(latLng, {
      interactive: false, keyboard: false, pane: "skyhive-grid",
      icon: L.divIcon({ className: "map-grid-label", html: text, iconSize: null, iconAnchor: anchor }),
    });
  }

  function drawGrid(map, group) {
    group.clearLayers();
    const b = map.getBounds();
    const south = Math.max(b.getSouth(), -85), north = Math.min(b.getNorth(), 85);
    const west = Math.max(b.getWest(), -180), east = Math.min(b.getEast(), 180);
    if (!(north > south && east > west)) return;
    const size = map.getSize();
    const latStep = gridStep(north - south, size.y, 60);
    const lonStep = gridStep(east - west, size.x, 110);
    const style = { pane: "skyhive-grid", color: "#64748b", weight: 1, opacity: 0.35, interactive: false };
    for (let lat = Math.ceil(south / latStep) * latStep; lat <= north; lat += latStep) {
      L.polyline([[lat, west], [lat, east]], style).addTo(group);
      label([lat, west], formatDegrees(lat, latStep, "N", "S"), [-2, 14]).addTo(group);
    }
    for (let lon = Math.ceil(west / lonStep) * lonStep; lon <= east; lon += lonStep) {
      L.polyline([[south, lon], [north, lon]], style).addTo(group);
      // Along the top edge: the bottom corners hold the scale and the attribution.
      label([north, lon], formatDegrees(lon, lonStep, "E", "W"), [-3, -3]).addTo(group);
    }
  }

  function addGrid(map) {
    if (!map.getPane("skyhive-grid")) {
      const pane = map.createPane("skyhive-grid");
      pane.style.zIndex = 250; // above tiles (200), below shapes (400) and markers (600)
      pane.style.pointerEvents = "none";
    }
    const group = L.layerGroup().addTo(map);
    const redraw = () => drawGrid(map, group);
    map.whenReady(redraw);
    map.on("moveend zoomend resize", redraw);
    return group;
  }

  function addTiles(map, config) {
    if (!config.url) {
      map.getContainer().classList.add("map-no-tiles");
      return null;
    }
    const options = { attribution: config.attribution || "", maxZoom: map.getMaxZoom() || 21 };
    if (config.maxNativeZoom !== undefined) options.maxNativeZoom = config.maxNativeZoom;
    if (config.minZoom !== undefined) options.minZoom = config.minZoom;
    // No request for a tile outside the imported area: it could only fail.
    if (config.bounds) options.bounds = L.latLngBounds(config.bounds);
    return L.tileLayer(config.url, options).addTo(map);
  }

  /* Tiles (when there are any), scale and grid on a geographic Leaflet map. */
  function addBase(map) {
    addTiles(map, layerConfig());
    L.control.scale({ imperial: false, maxWidth: 140 }).addTo(map);
    addGrid(map);
    // Published zones (map_zones.js), on every geographic map.
    if (window.SkyhiveZones) window.SkyhiveZones.add(map);
    return map;
  }

  /* L.map(element, options) with the base layers: the one call pages make. */
  function create(element, options) {
    const map = L.map(element, Object.assign({ maxZoom: 21 }, options || {}));
    return addBase(map);
  }

  window.SkyhiveMap = { create, addBase, layerConfig, gridStep };
})();
