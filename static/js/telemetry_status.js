// Ingest status page: re-read the counters every two seconds.
(function () {
  "use strict";
  const root = document.getElementById("ingest-status");
  if (!root) return;
  const alive = document.getElementById("ingest-alive");
  const reasons = document.getElementById("dropped-reasons");

  function render(status) {
    root.querySelectorAll("[data-key]").forEach((el) => {
      const value = status[el.dataset.key];
      el.textContent = value === null || value === undefined ? "–" : value + (el.dataset.unit || "");
    });
    alive.textContent = status.alive ? "running" : "not running";
    alive.className = "badge " + (status.alive ? "ok" : "bad");
    const entries = Object.entries(status.dropped_messages || {});
    reasons.replaceChildren(...(entries.length ? entries.map(([reason, count]) => {
      const tr = document.createElement("tr");
      for (const text of [reason, count]) {
        const td = document.createElement("td");
        td.textContent = text;
        tr.append(td);
      }
      return tr;
    }) : [Object.assign(document.createElement("tr"), {
      innerHTML: '<td colspan="2" class="empty">Nothing dropped.</td>',
    })]));
  }

  async function poll() {
    try {
      const response = await fetch(root.dataset.url, { credentials: "same-origin" });
      if (response.ok) render(await response.json());
    } catch (err) {
      // The next poll tries again; a network blip is not worth a message.
    }
    setTimeout(poll, 2000);
  }
  setTimeout(poll, 2000);
})();
