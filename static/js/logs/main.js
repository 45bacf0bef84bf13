// Entry point of a log's page and of the comparison page.

import { send } from "./api.js";
import { applyHash, followView } from "./permalink.js";
import { LogViewer } from "./viewer.js";

const viewers = [...document.querySelectorAll("[data-log-viewer]")].map((root) => new LogViewer(root));
window.logViewers = viewers;
for (const viewer of viewers) viewer.start();

// One log's page: the address (and the share box) carries the view, to open it again.
if (viewers.length === 1) {
  viewers[0].addEventListener("interactive", () => {
    applyHash(viewers[0]);
    followView(viewers[0], document.getElementById("share-url"));
  });
  // A health check's link on this page moves the viewer to its moment and plot.
  window.addEventListener("hashchange", () => {
    if (!viewers[0].state) return;
    applyHash(viewers[0]);
    viewers[0].root.querySelector(".lv-multi")?.scrollIntoView({ block: "center" });
  });
}

// Comparison: a cursor moved in one log moves the others to the same time since start.
const link = document.getElementById("link-cursors");
if (link) {
  let relaying = false;
  for (const viewer of viewers) {
    viewer.addEventListener("interactive", () => {
      viewer.state.on("cursor", ({ t, source }) => {
        if (!link.checked || relaying || source === "link") return;
        relaying = true;
        const since = t - viewer.state.start;
        for (const other of viewers) {
          if (other !== viewer && other.state) other.state.setCursor(other.state.start + since, "link");
        }
        relaying = false;
      });
    });
  }
}

for (const button of document.querySelectorAll("[data-copy]")) {
  button.addEventListener("click", async () => {
    const input = document.querySelector(button.dataset.copy);
    input.select();
    try {
      await navigator.clipboard.writeText(input.value);
    } catch {
      document.execCommand("copy");
    }
    button.textContent = "Copied";
    setTimeout(() => { button.textContent = "Copy link"; }, 1500);
  });
}

for (const button of document.querySelectorAll("[data-delete]")) {
  button.addEventListener("click", async () => {
    if (!window.confirm("Delete this log and its processed data for everyone in the organisation?")) return;
    try {
      await send("DELETE", button.dataset.delete);
      location.assign(button.dataset.then);
    } catch (err) {
      window.alert(err.message);
    }
  });
}
