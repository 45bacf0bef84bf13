// A drone's telemetry dashboard: live uPlot charts over a websocket, history from the
// range API (server-side min/max/avg buckets), drag-to-zoom re-queries the server.
(function () {
  "use strict";
  const root = document.getElementById("telemetry-dashboard");
  if (!root || typeof uPlot === "undefined") return;

  // The panels of the Telemetry Dashboard of [Paula 2018], figure 4.23, plus battery and altitude.
  // Each series: [object, field, label, unit]; the unit defaults to the panel's. A panel
  // of two units (battery: V and A) draws one y axis for each.
  const PANELS = [
    { id: "barometer", title: "Barometer", unit: "kPa", series: [["BaroAltitude", "Pressure", "Pressure"]] },
    { id: "temperature", title: "Temperature", unit: "°C", series: [
      ["BaroAltitude", "Temperature", "Barometer"], ["Accels", "temperature", "Accelerometer"],
      ["Gyros", "temperature", "Gyroscope"], ["SystemStats", "CPUTemp", "CPU"]] },
    { id: "accels", title: "Accelerometers", unit: "m/s²", series: [
      ["Accels", "x", "x"], ["Accels", "y", "y"], ["Accels", "z", "z"]] },
    { id: "gyros", title: "Gyroscopes", unit: "°/s", series: [
      ["Gyros", "x", "x"], ["Gyros", "y", "y"], ["Gyros", "z", "z"]] },
    { id: "cpu", title: "CPU load", unit: "%", series: [["SystemStats", "CPULoad", "CPU"]] },
    { id: "memory", title: "Free memory", unit: "bytes", series: [
      ["SystemStats", "HeapRemaining", "Heap"]] },
    { id: "battery", title: "Battery", unit: "V · A", series: [
      ["FlightBatteryState", "Voltage", "Voltage", "V"], ["FlightBatteryState", "Current", "Current", "A"]] },
    { id: "altitude", title: "Altitude", unit: "m", series: [
      ["BaroAltitude", "Altitude", "Barometric"], ["GPSPosition", "Altitude", "GPS (MSL)"]] },
  ];
  const COLORS = ["#2358d6", "#d92d20", "#17803d", "#b54708", "#7a5af8"];
  const LIVE_WINDOW_S = 300; // the live charts keep (and open with) the last five minutes

  const state = { mode: "live", start: null, end: null, request: 0 };
  const stateLabel = document.getElementById("tm-state");
  const exportLink = document.getElementById("tm-export");
  const exportLong = document.getElementById("tm-export-long");
  const container = document.getElementById("tm-panels");
  const charts = [];
  window.telemetryCharts = charts; // for tests and the curious

  function alpha(hex, a) {
    const n = parseInt(hex.slice(1), 16);
    return `rgba(${n >> 16},${(n >> 8) & 255},${n & 255},${a})`;
  }

  // Draw each series' min–max band behind its average line (history buckets only).
  function bandsPlugin(chart) {
    return {
      hooks: {
        drawSeries: [(u, si) => {
          const band = chart.bands[si - 1];
          if (!band || !band.lo) return;
          const xs = u.data[0];
          const scale = u.series[si].scale;
          const ctx = u.ctx;
          const top = [];
          const bottom = [];
          for (let i = 0; i < xs.length; i++) {
            if (band.hi[i] == null || band.lo[i] == null) continue;
            const x = u.valToPos(xs[i], "x", true);
            top.push([x, u.valToPos(band.hi[i], scale, true)]);
            bottom.push([x, u.valToPos(band.lo[i], scale, true)]);
          }
          if (top.length < 2) return;
          ctx.save();
          ctx.beginPath();
          ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
          ctx.clip();
          ctx.beginPath();
          top.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
          for (let i = bottom.length - 1; i >= 0; i--) ctx.lineTo(bottom[i][0], bottom[i][1]);
          ctx.closePath();
          ctx.fillStyle = alpha(COLORS[(si - 1) % COLORS.length], 0.15);
          ctx.fill();
          ctx.restore();
        }],
      },
    };
  }

  const pad = (n) => String(n).padStart(2, "0");
  const MONTHS = ["Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec"];

  /* Time ticks a person reads at a glance, in local time: HH:MM:SS within a day (with
     tenths when ticks are closer than a second), the date added beyond a day. */
  function timeTicks(u, splits, axisIdx, space, incr) {
    return splits.map((ts) => {
      const d = new Date(ts * 1000);
      const clock = `${pad(d.getHours())}:${pad(d.getMinutes())}:${pad(d.getSeconds())}`;
      if (incr < 1) return `${clock}.${Math.floor(d.getMilliseconds() / 100)}`;
      if (incr >= 86400) return `${d.getDate()} ${MONTHS[d.getMonth()]}`;
      const span = u.scales.x.max - u.scales.x.min;
      return span > 86400 ? `${d.getDate()} ${MONTHS[d.getMonth()]} ${clock.slice(0, 5)}` : clock;
    });
  }

  function chartSize(el) {
    const width = Math.max(240, el.clientWidth);
    return { width, height: window.innerWidth < 720 ? 160 : 200 };
  }

  function buildPanel(panel) {
    const section = document.createElement("section");
    section.className = "card tm-panel";
    section.dataset.panel = panel.id;
    section.dataset.points = "0";
    const h2 = document.createElement("h2");
    h2.innerHTML = `${panel.title} <span class="unit"></span>`;
    h2.querySelector(".unit").textContent = panel.unit;
    const body = document.createElement("div");
    body.className = "tm-chart";
    const note = document.createElement("p");
    note.className = "tm-note empty";
    note.textContent = "No data yet.";
    section.append(h2, body, note);
    container.append(section);

    const chart = { panel, section, body, note, live: panel.series.map(() => [[], []]),
      bands: [], plot: null, dirty: false };
    const unitOf = (s) => s[3] || panel.unit;
    const units = [...new Set(panel.series.map(unitOf))];
    const opts = {
      ...chartSize(body),
      plugins: [bandsPlugin(chart)],
      cursor: { sync: { key: "telemetry" }, drag: { x: true, y: false, setScale: false } },
      scales: { x: { time: true }, ...Object.fromEntries(units.map((u) => [u, { auto: true }])) },
      legend: { live: true },
      series: [{}].concat(panel.series.map((s, i) => ({
        label: units.length > 1 ? `${s[2]} [${unitOf(s)}]` : s[2], scale: unitOf(s),
        stroke: COLORS[i % COLORS.length], width: 1.5, spanGaps: false,
        value: (u, v) => (v == null ? "–" : +v.toPrecision(5)),
      }))),
      axes: [{ values: timeTicks, space: 70 }, ...units.map((unit, i) => ({
        scale: unit, size: 60, side: i % 2 ? 1 : 3, grid: { show: i === 0 },
        label: units.length > 1 ? unit : undefined, labelSize: units.length > 1 ? 14 : 0,
      }))],
      hooks: { setSelect: [(u) => onZoom(u)] },
    };
    chart.plot = new uPlot(opts, [[], ...panel.series.map(() => [])], body);
    charts.push(chart);
  }

  function setChartData(chart, tables, withBands) {
    const joined = tables.some((t) => t[0].length) ? uPlot.join(tables) : [[], ...tables.map(() => [])];
    const n = chart.panel.series.length;
    if (withBands) {
      const data = [joined[0]];
      chart.bands = [];
      for (let i = 0; i < n; i++) {
        data.push(joined[1 + i * 3]);
        chart.bands.push({ lo: joined[2 + i * 3], hi: joined[3 + i * 3] });
      }
      chart.plot.setData(data);
    } else {
      chart.bands = [];
      chart.plot.setData(joined);
    }
    const points = joined[0].length;
    chart.section.dataset.points = String(points);
    chart.note.hidden = points > 0;
  }

  // -- live ---------------------------------------------------------------------------

  function applyObjects(objects) {
    let newest = 0;
    for (const chart of charts) {
      chart.panel.series.forEach(([object, field], i) => {
        const sample = objects[object];
        if (!sample) return;
        const value = sample.fields[field];
        if (typeof value !== "number") return;
        const [xs, ys] = chart.live[i];
        if (xs.length && sample.ts <= xs[xs.length - 1]) return;
        xs.push(sample.ts);
        ys.push(value);
        newest = Math.max(newest, sample.ts);
        chart.dirty = true;
      });
    }
    for (const el of document.querySelectorAll("[data-stat]")) {
      const [object, field] = el.dataset.stat.split(".");
      const sample = objects[object];
      if (!sample || sample.fields[field] === undefined) continue;
      const value = sample.fields[field];
      el.textContent = typeof value === "number" && el.dataset.digits
        ? value.toFixed(+el.dataset.digits) + (el.dataset.unit || "")
        : String(value) + (el.dataset.unit || "");
    }
    if (newest) {
      root.dataset.updates = String(+(root.dataset.updates || 0) + 1);
      if (state.mode === "live") {
        stateLabel.textContent = "Live · " + new Date(newest * 1000).toLocaleTimeString();
      }
    }
  }

  function drawLive() {
    if (state.mode === "live") {
      for (const chart of charts) {
        if (!chart.dirty) continue;
        chart.dirty = false;
        for (const [xs, ys] of chart.live) {
          const cutoff = (xs.length ? xs[xs.length - 1] : 0) - LIVE_WINDOW_S;
          let drop = 0;
          while (drop < xs.length && xs[drop] < cutoff) drop++;
          if (drop) { xs.splice(0, drop); ys.splice(0, drop); }
        }
        setChartData(chart, chart.live.map(([xs, ys]) => [xs.slice(), ys.slice()]), false);
      }
    }
    requestAnimationFrame(drawLive);
  }

  let socket = null;
  let retry = 500;
  function connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    socket = new WebSocket(`${scheme}://${location.host}${root.dataset.wsPath}`);
    socket.onopen = () => {
      retry = 500;
      if (state.mode === "live") stateLabel.textContent = "Live · waiting for data";
    };
    socket.onmessage = (event) => {
      const message = JSON.parse(event.data);
      if (message.type === "snapshot" || message.type === "update") applyObjects(message.objects);
    };
    socket.onclose = (event) => {
      if (event.code === 4403 || event.code === 4401) {
        stateLabel.textContent = "Not allowed to watch this drone.";
        return;
      }
      if (state.mode === "live") stateLabel.textContent = "Reconnecting…";
      setTimeout(connect, retry);
      retry = Math.min(retry * 2, 10000);
    };
  }
  // Keeps the drone marked as watched, so the ingest keeps pushing for it.
  setInterval(() => socket && socket.readyState === 1 && socket.send('{"type":"ping"}'), 20000);

  /* A panel's fields grouped by object: one range request per object. */
  function fieldsByObject(panel) {
    const byObject = new Map();
    panel.series.forEach(([object, field]) => {
      if (!byObject.has(object)) byObject.set(object, []);
      byObject.get(object).push(field);
    });
    return byObject;
  }

  /* The live charts start with the last LIVE_WINDOW_S of stored history (bucket averages),
     so a page opened mid-flight shows the recent minutes at once; live samples follow. */
  async function prefillLive() {
    const end = Date.now() / 1000;
    const start = end - LIVE_WINDOW_S;
    await Promise.all(charts.map(async (chart) => {
      const byObject = fieldsByObject(chart.panel);
      const points = Math.max(100, Math.min(1000, Math.round(chart.body.clientWidth)));
      const results = new Map();
      try {
        await Promise.all([...byObject].map(async ([object, fields]) => {
          results.set(object, await fetchRange(object, fields, start, end, points));
        }));
      } catch (err) {
        return; // the live samples still come; history is a bonus here
      }
      chart.panel.series.forEach(([object, field], i) => {
        const r = results.get(object);
        const avg = r && r.series[field] ? r.series[field].avg : [];
        const [xs, ys] = chart.live[i];
        const first = xs.length ? xs[0] : Infinity;
        const older = r ? r.t.map((t, k) => [t, avg[k]]).filter(([t, v]) => t < first && typeof v === "number") : [];
        xs.unshift(...older.map(([t]) => t));
        ys.unshift(...older.map(([, v]) => v));
      });
      chart.dirty = true;
    }));
    root.dataset.prefilled = "true";
  }

  // -- history ------------------------------------------------------------------------

  async function fetchRange(object, fields, start, end, points) {
    const params = new URLSearchParams({ object, fields: fields.join(","), start, end, points });
    const response = await fetch(`${root.dataset.rangeUrl}?${params}`, { credentials: "same-origin" });
    const body = await response.json();
    if (!response.ok) throw new Error(body.error || response.statusText);
    return body;
  }

  async function showHistory(start, end) {
    state.mode = "history";
    state.start = start;
    state.end = end;
    const request = ++state.request;
    markPreset(null);
    updateExport();
    stateLabel.textContent = `Loading ${fmt(start)} – ${fmt(end)}…`;
    const began = performance.now();
    await Promise.all(charts.map(async (chart) => {
      const byObject = fieldsByObject(chart.panel);
      const points = Math.max(100, Math.min(2000, Math.round(chart.body.clientWidth)));
      try {
        const results = new Map();
        await Promise.all([...byObject].map(async ([object, fields]) => {
          results.set(object, await fetchRange(object, fields, start, end, points));
        }));
        if (request !== state.request) return;
        const tables = chart.panel.series.map(([object, field]) => {
          const r = results.get(object);
          const s = r.series[field];
          return [r.t, s.avg, s.min, s.max];
        });
        setChartData(chart, tables, true);
        chart.plot.setScale("x", { min: start, max: end });
        chart.note.textContent = "No data in this range.";
      } catch (err) {
        chart.note.hidden = false;
        chart.note.textContent = "Could not load: " + err.message;
      }
    }));
    if (request === state.request) {
      const ms = Math.round(performance.now() - began);
      stateLabel.textContent = `${fmt(start)} – ${fmt(end)} · loaded in ${ms} ms`;
    }
  }

  function onZoom(u) {
    const sel = u.select;
    if (sel.width < 5) return;
    const start = u.posToVal(sel.left, "x");
    const end = u.posToVal(sel.left + sel.width, "x");
    u.setSelect({ left: 0, top: 0, width: 0, height: 0 }, false);
    showHistory(start, end);
  }

  function goLive() {
    state.mode = "live";
    state.request++;
    markPreset("live");
    updateExport();
    stateLabel.textContent = "Live";
    for (const chart of charts) chart.dirty = true;
  }

  function markPreset(value) {
    for (const button of document.querySelectorAll("[data-range]")) {
      button.setAttribute("aria-pressed", String(button.dataset.range === value));
    }
  }

  function fmt(ts) {
    return new Date(ts * 1000).toLocaleString();
  }

  function updateExport() {
    const now = Date.now() / 1000;
    const [start, end] = state.mode === "live" ? [now - 900, now] : [state.start, state.end];
    exportLink.href = `${root.dataset.exportUrl}?${new URLSearchParams({ start, end })}`;
    if (exportLong) exportLong.href = `${root.dataset.exportUrl}?${new URLSearchParams({ start, end, layout: "long" })}`;
  }

  function toLocalInput(ts) {
    const d = new Date(ts * 1000 - new Date().getTimezoneOffset() * 60000);
    return d.toISOString().slice(0, 19);
  }

  document.querySelectorAll("[data-range]").forEach((button) => {
    button.addEventListener("click", () => {
      if (button.dataset.range === "live") return goLive();
      const end = Date.now() / 1000;
      showHistory(end - +button.dataset.range, end).then(() => markPreset(button.dataset.range));
    });
  });
  const custom = document.getElementById("tm-custom");
  custom.addEventListener("submit", (event) => {
    event.preventDefault();
    const start = new Date(custom.elements.from.value).getTime() / 1000;
    const end = new Date(custom.elements.to.value).getTime() / 1000;
    if (!(end > start)) {
      stateLabel.textContent = "Choose a “to” after “from”.";
      return;
    }
    showHistory(start, end);
  });
  custom.elements.from.value = toLocalInput(Date.now() / 1000 - 3600);
  custom.elements.to.value = toLocalInput(Date.now() / 1000);

  PANELS.forEach(buildPanel);
  new ResizeObserver(() => charts.forEach((c) => c.plot.setSize(chartSize(c.body)))).observe(container);
  updateExport();
  connect();
  prefillLive();
  requestAnimationFrame(drawLive);
})();
