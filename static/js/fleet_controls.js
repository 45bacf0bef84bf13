/* The fleet table's one-click controls: Hold, Return home and Land, each posted to the
   drone's commands API; the drone's answer is shown in its row. None starts a motor, so
   none asks for a confirmation. */
(function () {
  "use strict";
  const meta = document.querySelector('meta[name="csrf-token"]');
  const csrf = meta ? meta.content : "";

  async function send(button) {
    const row = button.closest("tr[data-drone]");
    const droneId = row.dataset.drone;
    const command = button.dataset.command;
    const out = row.querySelector(".control-result");
    button.disabled = true;
    out.textContent = `${command}…`;
    try {
      const response = await fetch(`/api/v1/drones/${encodeURIComponent(droneId)}/commands/`, {
        method: "POST",
        credentials: "same-origin",
        headers: { "Content-Type": "application/json", "X-CSRFToken": csrf, Accept: "application/json" },
        body: JSON.stringify({ command, params: {} }),
      });
      const body = await response.json().catch(() => ({}));
      const ok = response.ok && body.ok;
      out.textContent = ok ? `${command}: ok` : `${command}: ${body.error || response.status}`;
      out.dataset.status = ok ? "ok" : "error";
    } catch (error) {
      out.textContent = `${command}: ${error}`;
      out.dataset.status = "error";
    } finally {
      button.disabled = false;
    }
  }

  // Rows come and go with the table's pages and searches: one listener on the table.
  const table = document.getElementById("drone-table");
  if (table) {
    table.addEventListener("click", (event) => {
      const button = event.target.closest("button[data-command]");
      if (button && table.contains(button)) send(button);
    });
  }
})();
