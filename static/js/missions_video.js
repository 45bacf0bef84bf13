/* The mission page's live video: selecting a drone of the mission (its row in the drone
   list, or its marker on the map) plays that drone's stream in the video card with its
   age, through the same player and the same portal endpoints as the drone page
   (static/js/live_video.js), so a viewer gets a session only for a drone of their own
   organisation. */
(function () {
  "use strict";

  function start() {
    var card = document.getElementById("mission-video");
    var list = document.getElementById("progress-list");
    if (!card || !list || !card.skyhivePlayer) return;
    var player = card.skyhivePlayer;
    var pattern = card.dataset.videoUrlPattern;
    var selected = null;

    // Rows are rebuilt on every progress push: mark them again each time.
    function mark() {
      var items = list.querySelectorAll("[data-drone]");
      for (var i = 0; i < items.length; i++) {
        var item = items[i];
        item.tabIndex = 0;
        item.setAttribute("role", "button");
        item.title = "Show this drone's live video";
        item.classList.toggle("selected", item.dataset.drone === selected);
        item.setAttribute("aria-pressed", item.dataset.drone === selected ? "true" : "false");
      }
    }

    function select(droneId) {
      if (!droneId) return;
      selected = droneId;
      card.dataset.drone = droneId;
      var name = card.querySelector('[data-video="drone"]');
      if (name) name.textContent = droneId;
      player.watch(pattern.replace("__drone__", encodeURIComponent(droneId)));
      mark();
    }

    list.addEventListener("click", function (event) {
      var item = event.target.closest("[data-drone]");
      if (item) select(item.dataset.drone);
    });
    list.addEventListener("keydown", function (event) {
      var item = event.target.closest("[data-drone]");
      if (item && (event.key === "Enter" || event.key === " ")) { event.preventDefault(); select(item.dataset.drone); }
    });
    window.addEventListener("skyhive:select-drone", function (event) { select(event.detail); });
    new MutationObserver(mark).observe(list, { childList: true });
    mark();
  }

  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", start);
  else start();
})();
