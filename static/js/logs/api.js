// Small helpers shared by the Logs pages: JSON requests, CSRF, progress over a websocket.

export function csrfToken() {
  const match = document.cookie.match(/(?:^|;\s*)csrftoken=([^;]+)/);
  return match ? decodeURIComponent(match[1]) : "";
}

export class ApiError extends Error {
  constructor(message, status) {
    super(message);
    this.status = status;
  }
}

export async function getJSON(url, params = {}, { signal } = {}) {
  const query = new URLSearchParams();
  for (const [key, value] of Object.entries(params)) {
    if (value !== undefined && value !== null && value !== "") query.set(key, value);
  }
  const full = query.toString() ? `${url}?${query}` : url;
  const response = await fetch(full, { credentials: "same-origin", signal, headers: { Accept: "application/json" } });
  const body = await response.json().catch(() => ({}));
  if (!response.ok) throw new ApiError(body.error || `The server answered ${response.status}.`, response.status);
  return body;
}

export async function send(method, url) {
  const response = await fetch(url, {
    method,
    credentials: "same-origin",
    headers: { "X-CSRFToken": csrfToken(), Accept: "application/json" },
  });
  if (!response.ok) {
    const body = await response.json().catch(() => ({}));
    throw new ApiError(body.error || `The server answered ${response.status}.`, response.status);
  }
}

export function wsUrl(path) {
  return `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}${path}`;
}

/** Follow a log's processing: websocket events, with polling of the API as a fallback.
 * onEvent gets {status, progress, error}; returns a function that stops watching. */
export function watchProgress(wsPath, apiUrl, onEvent) {
  let done = false;
  let socket = null;
  let timer = null;
  const deliver = (event) => {
    if (done) return;
    onEvent(event);
    if (event.status && event.status !== "processing") stop();
  };
  const poll = async () => {
    if (done) return;
    try {
      const body = await getJSON(apiUrl);
      deliver({ status: body.status, progress: body.progress, error: body.error });
    } catch (err) {
      if (err.status === 404) deliver({ status: "deleted", error: "This log was deleted." });
    }
    // Keep polling only while the socket is not delivering.
    if (!done && (!socket || socket.readyState !== WebSocket.OPEN)) timer = setTimeout(poll, 1500);
  };
  const stop = () => {
    done = true;
    clearTimeout(timer);
    if (socket && socket.readyState <= 1) socket.close();
  };
  try {
    socket = new WebSocket(wsUrl(wsPath));
    socket.onmessage = (message) => deliver(JSON.parse(message.data));
    socket.onclose = () => { if (!done) poll(); };
  } catch {
    poll();
  }
  // A progress event may be missed while the socket connects; one early poll closes the gap.
  timer = setTimeout(poll, 2500);
  return stop;
}

export function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
}

export function humanBytes(n) {
  const units = ["bytes", "KB", "MB", "GB"];
  let i = 0;
  while (n >= 1024 && i < units.length - 1) { n /= 1024; i += 1; }
  return i ? `${n.toFixed(1)} ${units[i]}` : `${n} bytes`;
}
