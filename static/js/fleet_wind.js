/* The drone page's wind card, kept current from the live state's `fc.wind`. */
(function () {
  "use strict";
  const card = document.getElementById("wind");

  function cell(name) {
    return card ? card.querySelector(`[data-wind="${name}"]`) : null;
  }

  function set(name, text) {
    const el = cell(name);
    if (el) el.textContent = text;
  }

  function verdict(wind, limit) {
    const el = cell("verdict");
    if (!el) return;
    const above = wind.speed > limit;
    el.dataset.above = above ? "yes" : "no";
    el.textContent = "";
    if (!above && wind.action !== "return") {
      el.textContent = "within the limit";
      return;
    }
    const badge = document.createElement("span");
    badge.className = "badge off";
    badge.textContent = wind.action === "return"
      ? "returning home: wind above the limit"
      : "above the limit: take-off refused";
    el.appendChild(badge);
  }

  /* `fc` is the drone's flight-controller state; its `wind` is absent when not estimated. */
  function show(fc) {
    if (!card || !fc || !fc.wind) return;
    const wind = fc.wind;
    const limit = Math.min(Number(card.dataset.limit), Number(wind.limit));
    const from = (Math.round(Math.atan2(-wind.east, -wind.north) * 180 / Math.PI) + 360) % 360;
    set("speed", `${Number(wind.speed).toFixed(1)} m/s from ${from}°`);
    set("limit", `${limit} m/s`);
    set("source", wind.source || "flight controller");
    verdict(wind, limit);
  }

  window.SkyhiveWind = { show };
})();
