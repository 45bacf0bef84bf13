/* The fleet table's one-click controls: Hold, Return home and Land, each posted to the
   drone's commands API; the drone's answer is shown in its row. None starts a motor, so
   none asks for a confirmation up front; should the ground answer that a move goes beyond
   the envelope's defaults (409 confirmation_required), it is sent again only once the
   drone's id has been typed. */
(function () {
  "use strict";
  const meta = document.querySelector('meta[name="csrf-token"]');
  const csrf = meta ? meta.content : "";

  async function post(droneId, command, confirmed) {
    const request = { command, params: {} };
    if (confirmed) request.confirm_beyond_defaults = true;
    const response = await fetch(`/api/v1/drones/${encodeURIComponent(droneId)}/commands/`, {
      method: "POST",
      credentials: "same-origin",
      headers: { "Content-Type": "application/json", "X-CSRFToken": csrf, Accept: "application/json" },
      body: JSON.stringify(request),
    });
    return [response, await response.json().catch(() => ({}))];
  }

  /* The drone's answer goes to its row as the table is then: the table redraws its rows
     every few seconds, so the row clicked may be gone by the time the drone answers. */
  function show(droneId, text, status) {
    const row = Array.from(table.querySelectorAll("tr[data-drone]")).find((r) => r.dataset.drone === droneId);
    const out = row && row.querySelector(".control-result");
    if (!out) return;
    out.textContent = text;
    if (status) out.dataset.status = status;
    else delete out.dataset.status;
  }

  async function send(button) {
    const droneId = button.closest("tr[data-drone]").dataset.drone;
    const command = button.dataset.command;
    button.disabled = true;
    show(droneId, `${command}…`, null);
    try {
      let [response, body] = await post(droneId, command, false);
      if (response.status === 409 && body.code === "confirmation_required") {
        const typed = window.prompt(`${body.error}\nType ${droneId} to send ${command} anyway.`);
        if ((typed || "").trim() === droneId) [response, body] = await post(droneId, command, true);
      }
      const ok = response.ok && body.ok;
      show(droneId, ok ? `${command}: ok` : `${command}: ${body.error || response.status}`, ok ? "ok" : "error");
    } catch (error) {
      show(droneId, `${command}: ${error}`, "error");
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
