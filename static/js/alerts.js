/* Alerts an operator cannot miss: a banner on every page and, once allowed, a browser
   notification, for each alert of the current organisation (CRITICAL alarms, replacements,
   drones lost, missions completed or failed). Dismissed alerts stay dismissed. */
(function () {
  "use strict";
  const banner = document.getElementById("alert-banner");
  if (!banner) return;
  const list = document.getElementById("alert-list");
  const notifyButton = document.getElementById("alert-notify");
  const KEY = "skyhive-dismissed-alerts";
  const seen = new Set();
  let retry = 1000;
  // The socket's first message (the alerts still open) has come.
  let recentSeen = false;

  function dismissed() {
    try { return new Set(JSON.parse(localStorage.getItem(KEY) || "[]")); } catch (e) { return new Set(); }
  }

  function dismiss(id, item) {
    const ids = dismissed();
    ids.add(id);
    localStorage.setItem(KEY, JSON.stringify(Array.from(ids).slice(-200)));
    item.remove();
    banner.hidden = list.children.length === 0;
  }

  function notify(alert) {
    if (!("Notification" in window) || Notification.permission !== "granted") return;
    try { new Notification(`Skyhive: ${alert.title}`, { body: alert.detail || "", tag: alert.id }); } catch (e) { /* not allowed here */ }
  }

  function show(alert, fresh) {
    if (seen.has(alert.id) || dismissed().has(alert.id)) return;
    seen.add(alert.id);
    const item = document.createElement("li");
    item.className = `alert alert-${alert.severity}`;
    item.dataset.kind = alert.kind;
    const time = new Date(alert.at).toLocaleTimeString([], { hour12: false });
    const text = document.createElement("span");
    text.textContent = `${time} · ${alert.title}${alert.detail ? " — " + alert.detail : ""}`;
    const close = document.createElement("button");
    close.type = "button";
    close.className = "link alert-dismiss";
    close.textContent = "Dismiss";
    close.setAttribute("aria-label", `Dismiss: ${alert.title}`);
    close.addEventListener("click", () => dismiss(alert.id, item));
    item.append(text, close);
    list.prepend(item);
    banner.hidden = false;
    if (fresh) notify(alert);
  }

  function connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const socket = new WebSocket(`${scheme}://${location.host}/ws/alerts/?org=${encodeURIComponent(banner.dataset.org)}`);
    socket.addEventListener("open", () => { retry = 1000; });
    socket.addEventListener("message", (event) => {
      const message = JSON.parse(event.data);
      if (message.type === "recent") {
        message.alerts.slice().reverse().forEach((a) => show(a, false));
        recentSeen = true;
      }
      else if (message.type === "alert") show(message.alert, true);
    });
    socket.addEventListener("close", (event) => {
      if (event.code >= 4400 && event.code < 4500) return;  // not allowed: do not insist
      setTimeout(connect, retry);
      retry = Math.min(retry * 2, 30000);
    });
  }

  if ("Notification" in window && Notification.permission === "default") {
    notifyButton.hidden = false;
    notifyButton.addEventListener("click", () => {
      Notification.requestPermission().then(() => { notifyButton.hidden = true; });
    });
  }
  // For tests and the console: what is shown, and whether the socket has said what is open.
  window.skyhiveAlerts = { get shown() { return Array.from(seen); }, get recentSeen() { return recentSeen; } };
  connect();
})();
