// Operations page and the status page's "what to watch": render the figures of
// /api/v1/operations/ and re-read them every few seconds. Everything is written with
// textContent: host names and error messages come from outside.
(function () {
  "use strict";
  const root = document.getElementById("ops");
  if (!root) return;
  const refreshMs = 1000 * (Number(root.dataset.refresh) || 5);
  const $ = (id) => document.getElementById(id);

  function el(tag, attrs, ...children) {
    const node = document.createElement(tag);
    for (const [key, value] of Object.entries(attrs || {})) {
      if (key === "className") node.className = value;
      else if (key.startsWith("data-")) node.setAttribute(key, value);
      else node[key] = value;
    }
    for (const child of children) {
      if (child === null || child === undefined) continue;
      node.append(child instanceof Node ? child : String(child));
    }
    return node;
  }

  function clock(ts) {
    return ts ? new Date(ts * 1000).toLocaleTimeString() : "–";
  }

  function ago(ts) {
    if (!ts) return "–";
    const s = Math.max(0, Date.now() / 1000 - ts);
    if (s < 90) return `${Math.round(s)} s ago`;
    if (s < 5400) return `${Math.round(s / 60)} min ago`;
    return `${(s / 3600).toFixed(1)} h ago`;
  }

  function number(value, unit) {
    if (value === null || value === undefined) return "–";
    if (typeof value === "number" && !Number.isInteger(value)) value = value.toFixed(value < 10 ? 2 : 1);
    return unit ? `${value} ${unit}` : String(value);
  }

  function renderWatch(items) {
    const box = $("ops-watch");
    if (!box) return;
    box.replaceChildren(...items.map((item) => el("div", { className: "ops-item", "data-state": item.state, "data-key": item.key },
      el("span", { className: "label" }, item.label),
      el("span", { className: "value" }, item.value === null && !item.readable ? "unreachable" : number(item.value, item.unit)),
      item.detail ? el("span", { className: "detail" }, item.detail) : null,
      el("span", { className: "rule" }, item.rule),
      el("span", { className: "at" }, `read ${clock(item.at)}`),
    )));
  }

  // A dl of label/value pairs, or the reason the source could not be read.
  function kv(id, source, pairs) {
    const dl = $(id);
    if (!dl) return;
    if (!source || source.available === false) {
      dl.replaceChildren(el("dt", {}, "State"), el("dd", { className: "ops-unreachable" }, `unreachable: ${(source && source.error) || "no answer"}`),
        el("dt", {}, "Read at"), el("dd", {}, clock(source && source.at)));
      return;
    }
    const nodes = [];
    for (const [label, value] of pairs) nodes.push(el("dt", {}, label), el("dd", {}, value));
    nodes.push(el("dt", {}, "Read at"), el("dd", {}, clock(source.at)));
    dl.replaceChildren(...nodes);
  }

  // Gone instances stay listed for an hour; hidden unless asked for, so the live ones
  // stay in view after a restart or a deploy.
  function showGone() {
    const box = $("ops-show-gone");
    return Boolean(box && box.checked);
  }

  const goneToggle = $("ops-show-gone");
  if (goneToggle) {
    goneToggle.addEventListener("change", () => {
      document.querySelectorAll("#ops-processes tr.gone").forEach((tr) => { tr.hidden = !goneToggle.checked; });
    });
  }

  function renderProcesses(instances) {
    const table = $("ops-processes");
    if (!table) return;
    const body = table.tBodies[0];
    if (!instances || instances.available === false) {
      body.replaceChildren(el("tr", {}, el("td", { colSpan: 7, className: "ops-unreachable" },
        `Instances unreadable: ${(instances && instances.error) || "no answer"}`)));
      return;
    }
    const rows = [];
    for (const [name, group] of Object.entries(instances.processes)) {
      rows.push(el("tr", { className: "ops-process-row", "data-process": name },
        el("th", { colSpan: 7 }, name, el("span", { className: "sub" }, `${group.alive} alive${group.gone ? `, ${group.gone} gone` : ""}`))));
      if (!group.instances.length) {
        rows.push(el("tr", {}, el("td", {}, ""), el("td", { colSpan: 6, className: "empty" }, "No instance reporting.")));
      }
      for (const inst of group.instances) {
        rows.push(el("tr", { className: inst.alive ? "alive" : "gone", hidden: !inst.alive && !showGone(), "data-instance": inst.instance, "data-process": name },
          el("td", {}, name), el("td", {}, inst.instance), el("td", {}, inst.host || "–"),
          el("td", {}, inst.pid || "–"), el("td", {}, inst.started ? clock(inst.started) : "–"),
          el("td", {}, ago(inst.last_report)),
          el("td", {}, el("span", { className: `badge ${inst.alive ? "ok" : "bad"}` }, inst.alive ? "alive" : "gone"))));
      }
    }
    body.replaceChildren(...rows);
  }

  function renderGateway(g) {
    kv("ops-gateway", g, g && g.available !== false ? [
      ["Received", number(g.received)], ["Handled", number(g.handled)],
      ["Published (commands)", number(g.published)], ["Dropped", number(g.dropped_total)],
    ] : []);
    const body = $("ops-gateway-dropped");
    if (!body) return;
    const entries = Object.entries((g && g.dropped) || {});
    body.replaceChildren(...(entries.length
      ? entries.map(([reason, count]) => el("tr", {}, el("td", {}, reason), el("td", {}, count)))
      : [el("tr", {}, el("td", { colSpan: 2, className: "empty" }, "Nothing dropped."))]));
  }

  function renderIngest(i) {
    kv("ops-ingest", i, i && i.available !== false ? [
      ["Lag", number(i.lag_s, "s")], ["Stored / s", number(i.rate_objects_per_s)],
      ["Instances alive / writing", `${i.instances_alive} / ${i.instances_writing}`], ["Stored objects", number(i.stored_objects)],
      ["Dropped messages", number(i.dropped_total)], ["Buffered rows", number(i.buffer_rows)],
    ] : []);
  }

  function renderQueues(q) {
    kv("ops-queues", q, q && q.available !== false ? [
      ["Command outbox", number(q.outbox)],
      ["Celery queue", q.celery_queue === null ? q.celery_error : number(q.celery_queue)],
      ["Celery tasks running (unacked)", number(q.celery_unacked)],
    ] : []);
  }

  function table(headers, rows) {
    return el("table", { className: "table" },
      el("thead", {}, el("tr", {}, ...headers.map((h) => el("th", {}, h)))),
      el("tbody", {}, ...rows.map((cells) => el("tr", {}, ...cells.map((c) => el("td", {}, c))))));
  }

  function renderBroker(b) {
    const nodesBox = $("ops-broker-nodes");
    const queuesBox = $("ops-broker-queues");
    if (!nodesBox) return;
    const pairs = [];
    if (b && b.kind === "rabbitmq" && b.available !== false) {
      pairs.push(["Cluster", b.cluster || "–"], ["Version", b.version || "–"],
        ["Nodes up / down", `${b.nodes_up} / ${b.nodes_down}`], ["Connections", number(b.connections)],
        ["MQTT session queues", number(b.mqtt_sessions.queues)],
        ["MQTT sessions: ready / unacked", `${b.mqtt_sessions.ready} / ${b.mqtt_sessions.unacked}`]);
    } else if (b && b.available !== false) {
      pairs.push(["Address", b.address], ["Version", b.version || "–"],
        ["Clients connected", number(b.clients_connected)], ["Messages stored", number(b.store_messages ?? b.messages_stored)],
        ["Messages dropped", number(b.messages_dropped)], ["Subscriptions", number(b.subscriptions)],
        ["Shared subscriptions", number(b.shared_subscriptions)], ["Uptime", b.uptime || "–"]);
    }
    kv("ops-broker", b, pairs);
    const endpoints = (b && b.endpoints) || [];
    const nodes = (b && b.nodes) || [];
    nodesBox.replaceChildren(
      ...(endpoints.length ? [el("h3", {}, "Endpoints"), table(["Address", "State", "Node or error"],
        endpoints.map((e) => {
          const state = !e.up ? ["bad", "down"] : e.error ? ["warn", "refuses us"] : ["ok", "up"];
          return [e.address, el("span", { className: `badge ${state[0]}` }, state[1]), e.error || e.node || ""];
        }))] : []),
      ...(nodes.length ? [el("h3", {}, "Cluster nodes"), table(["Node", "State", "Sockets"],
        nodes.map((n) => [n.name, el("span", { className: `badge ${n.running ? "ok" : "bad"}`, "data-node": n.name }, n.running ? "running" : "down"), number(n.sockets_used)]))] : []));
    const queues = (b && b.queues) || [];
    queuesBox.replaceChildren(...(b && b.kind === "rabbitmq" && b.available !== false ? [el("h3", {}, "Queues (skyhive.*)"),
      queues.length ? table(["Queue", "Ready", "Unacked", "Consumers", "Node"],
        queues.map((q) => [q.name, q.ready, q.unacked, q.consumers, q.node || "–"]))
        : el("p", { className: "empty" }, "No skyhive.* queue yet.")] : []));
  }

  function render(figures) {
    renderWatch(figures.watch || []);
    renderProcesses(figures.instances);
    renderGateway(figures.gateway);
    renderIngest(figures.ingest);
    renderQueues(figures.queues);
    renderBroker(figures.broker);
    const kind = $("ops-broker-kind");
    if (kind) kind.textContent = figures.broker_kind;
    const updated = $("ops-updated");
    if (updated) {
      updated.dataset.generatedAt = figures.generated_at;
      updated.textContent = `Updated ${clock(figures.generated_at)} · refreshes every ${refreshMs / 1000} s`;
      updated.classList.remove("error");
    }
  }

  async function poll() {
    try {
      const response = await fetch(root.dataset.url, { credentials: "same-origin", headers: { accept: "application/json" } });
      if (response.ok) render(await response.json());
      else throw new Error(`HTTP ${response.status}`);
    } catch (err) {
      const updated = $("ops-updated");
      if (updated) {
        updated.textContent = `Figures not refreshed (${err.message}); retrying…`;
        updated.classList.add("error");
      }
    }
    setTimeout(poll, refreshMs);
  }

  const initial = document.getElementById("ops-initial");
  if (initial) {
    render(JSON.parse(initial.textContent));
    setTimeout(poll, refreshMs);
  } else {
    poll();
  }
})();
