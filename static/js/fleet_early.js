/* The fleet page's first script, loaded before the styles and the map scripts: open the
   live socket and ask for the first table page, so the handshake, the snapshot and the
   page are on their way while the browser parses the rest. The page's scripts take them
   over (SkyhiveEarly). The paths come from the script element's data attributes. */
(function () {
  "use strict";
  performance.mark("fleet:early");
  const data = document.currentScript.dataset;
  const path = data.socketPath;
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const early = { path, messages: [], socket: null, table: null };
  try {
    early.socket = new WebSocket(`${scheme}://${location.host}${path}`);
    early.socket.onmessage = (event) => { early.messages.push(event); };
    early.socket.addEventListener("open", () => performance.mark("fleet:socket-open"), { once: true });
  } catch (e) { early.socket = null; }
  early.tableUrl = `${data.tableUrl}?page=1`;
  early.table = fetch(early.tableUrl, { credentials: "same-origin", headers: { Accept: "application/json" } });
  early.table.catch(() => {});
  window.SkyhiveEarly = early;
})();
