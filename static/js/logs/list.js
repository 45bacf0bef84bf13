// The Logs list: drag and drop or pick files, upload each with a progress bar, then follow
// its processing over the log's websocket until it is ready (or says why it failed).

import { csrfToken, escapeHtml, humanBytes, watchProgress } from "./api.js";

const zone = document.getElementById("upload");
if (zone) {
  const input = document.getElementById("log-file");
  const dropzone = document.getElementById("dropzone");
  const list = document.getElementById("uploads");
  const api = zone.dataset.api;
  const limit = Number(zone.dataset.limit);

  // The server takes at most UPLOAD_MAX_CONCURRENT uploads of one user at once (429
  // beyond): the other files wait here for a free place.
  const concurrent = Math.max(1, Number(zone.dataset.concurrent) || 1);
  const waiting = [];
  let running = 0;
  const next = () => {
    while (running < concurrent && waiting.length) {
      running += 1;
      uploadOne(waiting.shift(), () => { running -= 1; next(); });
    }
  };
  const start = (files) => { waiting.push(...files); next(); };
  input.addEventListener("change", () => { start(input.files); input.value = ""; });
  for (const type of ["dragenter", "dragover"]) {
    dropzone.addEventListener(type, (event) => { event.preventDefault(); dropzone.classList.add("dragging"); });
  }
  for (const type of ["dragleave", "drop"]) {
    dropzone.addEventListener(type, (event) => { event.preventDefault(); dropzone.classList.remove("dragging"); });
  }
  dropzone.addEventListener("drop", (event) => start(event.dataTransfer.files));

  function uploadOne(file, done) {
    const item = document.createElement("li");
    item.innerHTML = `<span class="name" title="${escapeHtml(file.name)}">${escapeHtml(file.name)}</span>
      <progress max="1" value="0" aria-label="Progress of ${escapeHtml(file.name)}"></progress>
      <span class="state">Uploading…</span>`;
    list.prepend(item);
    const bar = item.querySelector("progress");
    const state = item.querySelector(".state");
    const fail = (message) => {
      item.classList.add("failed");
      bar.value = 1;
      state.textContent = message;
      state.classList.add("error");
    };
    if (file.size > limit) {
      fail(`Too large: ${humanBytes(file.size)}, over the limit of ${humanBytes(limit)}.`);
      done();
      return;
    }
    const form = new FormData();
    form.append("organisation", zone.dataset.organisation);
    form.append("file", file);
    const xhr = new XMLHttpRequest();
    xhr.open("POST", api);
    xhr.setRequestHeader("X-CSRFToken", csrfToken());
    xhr.setRequestHeader("Accept", "application/json");
    xhr.upload.addEventListener("progress", (event) => {
      if (!event.lengthComputable) return;
      bar.value = event.loaded / event.total;
      state.textContent = `Uploading… ${Math.round((100 * event.loaded) / event.total)} % of ${humanBytes(event.total)}`;
    });
    xhr.addEventListener("error", () => fail("The upload was interrupted; try again."));
    xhr.addEventListener("loadend", done);
    xhr.addEventListener("load", () => {
      let body = {};
      try { body = JSON.parse(xhr.responseText); } catch { /* not JSON: use the status */ }
      if (xhr.status !== 201) {
        fail(body.error || `The server refused the file (${xhr.status}).`);
        return;
      }
      const page = body.url;
      item.dataset.log = body.id;
      bar.value = 0;
      state.textContent = "Processing… 0 %";
      watchProgress(`/ws/logs/${body.id}/`, `${api}${body.id}/`, (event) => {
        if (event.status === "processing") {
          bar.value = Number(event.progress) || 0;
          state.textContent = `Processing… ${Math.round(bar.value * 100)} %`;
        } else if (event.status === "ready") {
          bar.value = 1;
          item.classList.add("ready");
          state.innerHTML = `Ready — <a href="${escapeHtml(page)}">open the log</a>`;
          refreshList();
        } else {
          fail(event.error || "The file could not be processed.");
          refreshList();
        }
      });
    });
    xhr.send(form);
  }
}

/** Replace the table with the server's current one, so finished uploads appear in it.
    Several uploads finish together: only the newest table asked for replaces it. */
let listsAsked = 0;
async function refreshList() {
  const asked = ++listsAsked;
  const response = await fetch(location.href, { credentials: "same-origin" });
  if (!response.ok) return;
  const text = await response.text();
  if (asked !== listsAsked) return;
  const fresh = new DOMParser().parseFromString(text, "text/html").getElementById("log-list");
  const current = document.getElementById("log-list");
  if (fresh && current) {
    current.replaceWith(fresh);
    bindCompare();
  }
}

// Compare: enabled once two to four ready logs are ticked.
function bindCompare() {
  const compareForm = document.getElementById("compare-form");
  if (!compareForm) return;
  const button = document.getElementById("compare-button");
  const update = () => {
    const ticked = compareForm.querySelectorAll('input[name="pick"]:checked').length;
    button.disabled = ticked < 2 || ticked > 4;
    button.textContent = ticked >= 2 ? `Compare ${ticked} logs` : "Compare selected";
  };
  compareForm.addEventListener("change", update);
  update();
}

bindCompare();
