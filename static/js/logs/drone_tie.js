// A log's page: an operator names the drone that flew the log, which puts its figures in
// that drone's trends (POST /api/v1/logs/{id}/drone/).

import { csrfToken } from "./api.js";

const form = document.getElementById("drone-tie");
if (form) {
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const drone = form.elements.drone.value || null;
    const response = await fetch(form.dataset.api, {
      method: "POST",
      credentials: "same-origin",
      headers: { "Content-Type": "application/json", "X-CSRFToken": csrfToken(), Accept: "application/json" },
      body: JSON.stringify({ drone }),
    });
    if (response.ok) {
      location.reload();
    } else {
      const body = await response.json().catch(() => ({}));
      window.alert(body.error || `The server answered ${response.status}.`);
    }
  });
}
