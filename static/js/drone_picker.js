/* The one drone picker: any <input data-drone-picker> suggests the organisation's drones
   as the user types, a page at a time from the fleet table API (so it works the same with
   10 or 10 000 drones). data-drone-picker may name filters, e.g. "online". The chosen id
   lands in the input; a "change" event tells the page. */
(function () {
  "use strict";
  const TABLE_URL = "/fleet/table/";
  const LIMIT = 12;
  let seq = 0;

  function enhance(input) {
    const list = document.createElement("datalist");
    list.id = `drone-picker-${++seq}`;
    input.setAttribute("list", list.id);
    input.setAttribute("autocomplete", "off");
    input.after(list);
    let timer = null, asked = 0;

    async function suggest() {
      const ask = ++asked;
      const params = new URLSearchParams({ q: input.value.trim(), page_size: String(LIMIT) });
      if (input.dataset.dronePicker) params.set("filter", input.dataset.dronePicker);
      let data;
      try {
        const response = await fetch(`${TABLE_URL}?${params}`, { credentials: "same-origin", headers: { Accept: "application/json" } });
        if (!response.ok) return;
        data = await response.json();
      } catch (error) { return; }
      if (ask !== asked) return; // a newer search is on its way
      list.replaceChildren(...data.results.map((d) => {
        const option = document.createElement("option");
        option.value = d.drone_id;
        const state = window.SkyhiveLive ? window.SkyhiveLive.stateLabel(d.state) : d.state;
        option.label = `${d.name ? `${d.name} · ` : ""}${state}`;
        return option;
      }));
      input.dataset.matches = String(data.count);
    }

    input.addEventListener("input", () => { clearTimeout(timer); timer = setTimeout(suggest, 150); });
    input.addEventListener("focus", () => { if (!list.children.length) suggest(); });
  }

  document.querySelectorAll("input[data-drone-picker]").forEach(enhance);
  window.SkyhiveDronePicker = { enhance };
})();
