/* Published UAS geographical zones on every map (map_base.js adds them to each): fetched
   from /api/v1/zones/ for the area in view, styled by restriction, each with a popup
   naming the zone, its altitude band and when it applies. Leaflet only, nothing fetched
   from elsewhere. */
(function () {
  "use strict";

  const API = "/api/v1/zones/";
  const STYLES = {
    prohibited: { color: "#b91c1c", fillColor: "#ef4444", fillOpacity: 0.18, weight: 2 },
    authorisation_required: { color: "#b45309", fillColor: "#f59e0b", fillOpacity: 0.15, weight: 2, dashArray: "6 4" },
    conditional: { color: "#1d4ed8", fillColor: "#3b82f6", fillOpacity: 0.1, weight: 1, dashArray: "2 4" },
  };
  const LABELS = {
    prohibited: "Prohibited",
    authorisation_required: "Authorisation required",
    conditional: "Conditional",
  };

  function text(value) {
    const span = document.createElement("span");
    span.textContent = value == null ? "" : String(value);
    return span.innerHTML;
  }

  function popup(p) {
    const lines = [
      `<strong class="zone-name">${text(p.name)}</strong> <span class="zone-id">${text(p.identifier)}</span>`,
      `<span class="zone-restriction">${text(LABELS[p.restriction] || p.restriction)}</span>`,
      `<span class="zone-band">${text(p.band)}</span>`,
      `<span class="zone-when">${text(p.applicability_text)}${p.applies_now ? "" : " (not now)"}</span>`,
    ];
    if (p.message) lines.push(`<span class="zone-message">${text(p.message)}</span>`);
    lines.push(`<span class="zone-source">${text(p.source)}${p.organisation ? "" : " · site-wide"}</span>`);
    return lines.join("<br>");
  }

  // A zone as the server gave it: one that differs in anything is drawn anew.
  function keyOf(feature) {
    return JSON.stringify([feature.id, feature.geometry, feature.properties]);
  }

  function boxOf(map) {
    const b = map.getBounds().pad(0.5);
    return [b.getWest(), b.getSouth(), b.getEast(), b.getNorth()].map((v) => v.toFixed(6)).join(",");
  }

  /* The zones layer of one map: redrawn for the area in view after each move. */
  function add(map) {
    if (!map.getPane("skyhive-zones")) {
      const pane = map.createPane("skyhive-zones");
      pane.style.zIndex = 350; // above the grid (250), below the page's own shapes (400)
    }
    const layer = L.geoJSON(null, {
      pane: "skyhive-zones",
      style: (f) => STYLES[f.properties.restriction] || STYLES.conditional,
      onEachFeature: (f, l) => {
        l.bindPopup(popup(f.properties));
        l.options.zoneId = f.id;
        l.options.zoneKey = keyOf(f);
      },
    }).addTo(map);
    let pending = null;
    let asked = 0;
    /* Only what changed is redrawn: a zone drawn already stays as it is, with its popup
       open if it was (opening one near the edge pans the map, which asks again). */
    function draw(features) {
      const wanted = new Map();
      for (const f of features) {
        const key = keyOf(f);
        wanted.set(key, (wanted.get(key) || []).concat([f]));
      }
      layer.eachLayer((l) => {
        const same = wanted.get(l.options.zoneKey);
        if (same && same.length) same.pop();
        else layer.removeLayer(l);
      });
      layer.addData({ type: "FeatureCollection", features: Array.from(wanted.values()).flat() });
    }
    function load() {
      const ask = ++asked;
      fetch(`${API}?bbox=${boxOf(map)}`, { credentials: "same-origin", headers: { Accept: "application/json" } })
        .then((r) => (r.ok ? r.json() : null))
        .then((body) => {
          if (!body || ask !== asked) return;
          draw(body.features);
          map.getContainer().dataset.zones = String(body.features.length);
          map.getContainer().dataset.zonesDrawn = String(ask);
        })
        .catch(() => {});
    }
    map.skyhiveZones = layer;
    map.whenReady(load);
    map.on("moveend", () => {
      clearTimeout(pending);
      pending = setTimeout(load, 250);
    });
    return layer;
  }

  window.SkyhiveZones = { add, popup };
})();
