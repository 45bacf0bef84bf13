// The past-view page: the chosen past frame as background, the drone drawn over it, the
// live camera beside it, warnings and a beep when tracking is lost or there is no frame,
// the evaluation function's settings, and teleoperation for operators.
import { DroneScene } from "./pastview_scene.js";
import { Teleop } from "./pastview_teleop.js";

const config = JSON.parse(document.getElementById("pv-config").textContent);
const $ = (id) => document.getElementById(id);

const state = {
  frame: null, // the chosen frame's id
  tracking: "none", // "none" (no pose yet), "tracked", "lost"
  updates: 0,
  beeps: 0,
  socket: null,
  linkOpen: false,
  liveAt: null, // when (performance.now()) the drone's last camera frame arrived
  trackedAt: null, // when the last pose update with tracking came
  liveFrames: 0,
};
window.pastview = state; // for tests and the curious

const scene = new DroneScene($("pv-canvas"), {
  box: config.box,
  camera: config.settings.camera,
});
// The canvas must cover exactly the picture: follow the frames' own proportions.
$("pv-frame").addEventListener("load", (event) => {
  const { naturalWidth: width, naturalHeight: height } = event.target;
  if (width && height) $("pv-stage").style.aspectRatio = `${width} / ${height}`;
});

// -- warnings and sound -----------------------------------------------------------------

let audio = null;
function beep() {
  if (!$("pv-sound").checked) return;
  state.beeps += 1;
  try {
    audio = audio || new AudioContext();
    const oscillator = audio.createOscillator();
    const gain = audio.createGain();
    oscillator.frequency.value = 880;
    gain.gain.setValueAtTime(0.2, audio.currentTime);
    gain.gain.exponentialRampToValueAtTime(0.001, audio.currentTime + 0.4);
    oscillator.connect(gain).connect(audio.destination);
    oscillator.start();
    oscillator.stop(audio.currentTime + 0.4);
  } catch (error) {
    console.warn("no sound:", error);
  }
}
// Browsers start audio only after a user gesture: unlock it on the first one.
window.addEventListener("pointerdown", () => audio?.resume?.(), { once: true });

function showWarning() {
  let text = "";
  if (state.tracking === "lost") text = "Tracking lost — the drone's pose is stale";
  else if (state.frame === null) text = "No frame yet";
  else if (state.tracking === "none") text = "No pose yet";
  const warning = $("pv-warning");
  // Beep when a warning appears or changes (lost, or no frame to draw on), not on every pose.
  if (text !== "" && text !== warning.textContent) beep();
  warning.textContent = text;
  warning.hidden = text === "";
  const badge = $("pv-tracking");
  badge.dataset.state = state.tracking;
  badge.textContent = { none: "no pose yet", tracked: "tracked", lost: "tracking lost" }[state.tracking];
}

// -- messages from the server -------------------------------------------------------------

function applyUpdate(update, fresh = true) {
  if (!update) return;
  state.updates += 1;
  state.tracking = update.tracking;
  // A stored snapshot shows the last view but says nothing about the drone now.
  if (fresh && update.tracking === "tracked" && update.frame) state.trackedAt = performance.now();
  if (update.frame) {
    if (update.jpeg) $("pv-frame").src = `data:image/jpeg;base64,${update.jpeg}`;
    state.frame = update.frame.id;
  }
  scene.setPose(update.frame ? update.relative : null);
  showWarning();
}

// This drone's counters (the service keeps them per drone), and the age of what came last.
const STATUS = [
  ["frames_received", "frames received"], ["frames_stored", "frames kept"],
  ["frames_malformed", "frames malformed"], ["frames_out_of_order", "frames out of order"],
  ["poses_received", "poses received"], ["poses_bad", "poses refused"],
  ["poses_out_of_order", "poses out of order"], ["quaternions_repaired", "orientations repaired"],
];
let lastStatus = {};

function age(at) {
  return at === null ? "never" : `${((performance.now() - at) / 1000).toFixed(1)} s ago`;
}

function applyStatus(status) {
  lastStatus = status || {};
  const rows = [
    ...STATUS.map(([key, label]) => [label, lastStatus[key] ?? "–", key]),
    ["last camera frame", age(state.liveAt), "live_age"],
    ["last tracked pose", age(state.trackedAt), "pose_age"],
  ];
  $("pv-status").replaceChildren(...rows.flatMap(([label, value, key]) => {
    const dt = document.createElement("dt");
    dt.textContent = label;
    const dd = document.createElement("dd");
    dd.dataset.key = key;
    dd.textContent = value;
    return [dt, dd];
  }));
}

function applyLive(live, fresh = true) {
  if (!live || !live.jpeg) return;
  $("pv-live").src = `data:image/jpeg;base64,${live.jpeg}`;
  if (fresh) {
    state.liveAt = performance.now();
    state.liveFrames += 1;
  }
  // The live picture is offered once there is one: never an empty or broken image.
  $("pv-show-live").disabled = false;
  $("pv-live-box").hidden = !$("pv-show-live").checked;
}

const handlers = {
  hello(message) {
    fillSettings(message.settings);
  },
  snapshot(message) {
    applyLive(message.live, false);
    if (message.status) applyStatus(message.status);
    applyUpdate(message.update, false);
  },
  update: applyUpdate,
  live: applyLive,
  status: applyStatus,
  settings(message) {
    fillSettings({ ...message.settings, camera: currentCamera });
  },
  teleop(message) {
    const box = $("pv-teleop-message");
    if (!box) return;
    box.textContent = message.ok ? `moved: ${message.sent.map((s) => `${s.command} ${s.value}`).join(", ")}` : message.error;
    box.classList.toggle("error", !message.ok);
  },
};

let retry = 500;
function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const socket = new WebSocket(`${scheme}://${location.host}${config.socketPath}`);
  state.socket = socket;
  const badge = $("pv-connection");
  socket.onopen = () => {
    retry = 500;
    state.linkOpen = true;
    badge.dataset.state = "open";
    badge.textContent = "live";
  };
  socket.onmessage = (event) => {
    const message = JSON.parse(event.data);
    handlers[message.type]?.(message);
  };
  socket.onclose = (event) => {
    state.linkOpen = false;
    badge.dataset.state = "closed";
    badge.textContent = "disconnected";
    if (event.code === 4401 || event.code === 4404) return; // not allowed: do not hammer
    setTimeout(connect, retry);
    retry = Math.min(retry * 2, 10000);
  };
}

function send(message) {
  if (state.socket && state.socket.readyState === WebSocket.OPEN) {
    state.socket.send(JSON.stringify(message));
  }
}

// -- settings -----------------------------------------------------------------------------

let currentCamera = config.settings.camera;
const select = $("pv-function");
for (const name of Object.keys(config.functions)) {
  const option = document.createElement("option");
  option.value = name;
  option.textContent = name.replaceAll("_", " ");
  select.append(option);
}

function paramInputs(values) {
  const box = $("pv-params");
  const hidden = new Set(["function", "camera_pitch_down_deg"]); // set with the camera
  box.replaceChildren(...Object.entries(values).filter(([k]) => !hidden.has(k)).map(([key, value]) => {
    const label = document.createElement("label");
    label.textContent = key.replaceAll("_", " ");
    const input = document.createElement("input");
    input.type = "number";
    input.step = "any";
    input.name = key;
    input.value = value;
    input.disabled = !config.canOperate;
    label.append(input);
    return label;
  }));
}

function fillSettings(settings) {
  currentCamera = settings.camera || currentCamera;
  scene.setCamera(currentCamera);
  select.value = settings.evaluation.function;
  paramInputs(settings.evaluation);
}

select.addEventListener("change", () => paramInputs(config.functions[select.value]));
select.disabled = !config.canOperate;

$("pv-settings").addEventListener("submit", async (event) => {
  event.preventDefault();
  const evaluation = { function: select.value };
  for (const input of $("pv-params").querySelectorAll("input")) {
    evaluation[input.name] = Number(input.value);
  }
  const message = $("pv-settings-message");
  const token = document.querySelector("[name=csrfmiddlewaretoken]").value;
  const response = await fetch(config.settingsUrl, {
    method: "PUT",
    headers: { "Content-Type": "application/json", "X-CSRFToken": token },
    body: JSON.stringify({ evaluation }),
  });
  const body = await response.json();
  message.classList.toggle("error", !response.ok);
  message.textContent = response.ok ? "Applied; the next pose uses it." : body.error;
  if (response.ok) fillSettings(body);
});

$("pv-show-live").addEventListener("change", (event) => {
  $("pv-live-box").hidden = !event.target.checked || state.liveAt === null;
});

// Teleoperation is offered only while the view is current: the page's link is open, and
// a camera frame and a tracked pose arrived within teleopFreshS (the server checks too).
function teleopBlocker() {
  const fresh = (at) => at !== null && performance.now() - at <= config.teleopFreshS * 1000;
  if (!state.linkOpen) return "No link to the server.";
  if (!fresh(state.liveAt)) return "No camera frame from the drone in the last few seconds.";
  if (!fresh(state.trackedAt)) return "No tracked pose of the drone in the last few seconds.";
  return "";
}
state.teleopBlocker = teleopBlocker;

// -- teleoperation ------------------------------------------------------------------------

if (config.canOperate) {
  const button = $("pv-control");
  const teleop = new Teleop({
    send,
    rateHz: config.teleopHz,
    onChange(enabled) {
      button.setAttribute("aria-pressed", String(enabled));
      button.textContent = enabled ? "Release control" : "Take control";
    },
  });
  button.addEventListener("click", () => teleop.setEnabled(!teleop.enabled && !teleopBlocker()));
  const reason = $("pv-teleop-reason");
  const check = () => {
    const blocker = teleopBlocker();
    if (blocker && teleop.enabled) {
      teleop.setEnabled(false);
      $("pv-teleop-message").textContent = `Control released: ${blocker}`;
    }
    button.disabled = Boolean(blocker) && !teleop.enabled;
    reason.textContent = blocker;
  };
  setInterval(check, 250);
  check();
  window.addEventListener("gamepadconnected", () => {
    $("pv-teleop-message").textContent = "Gamepad connected.";
  });
}

fillSettings(config.settings);
showWarning();
applyStatus({});
setInterval(() => applyStatus(lastStatus), 1000); // the ages move on between status messages
connect();
