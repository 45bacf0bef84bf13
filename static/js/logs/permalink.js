// The view in the page's address: time cursor, selected interval, zoom and plotted
// quantities, so a shared link opens on the same moment of the flight.
//   #t=12.345&sel=10~20&view=0~60&plot=path1,path2&spec=1   (seconds since the log's start;
//   spec=1 opens the spectrum of the plotted quantities)

import { debounce } from "./state.js";

function range(text) {
  const [a, b] = (text || "").split("~").map(Number);
  return Number.isFinite(a) && Number.isFinite(b) && b > a ? [a, b] : null;
}

export function applyHash(viewer, hash = location.hash) {
  const params = new URLSearchParams(hash.replace(/^#/, ""));
  const state = viewer.state;
  const view = range(params.get("view"));
  if (view) state.setView(state.start + view[0], state.start + view[1]);
  const selection = range(params.get("sel"));
  if (selection) state.setSelection(state.start + selection[0], state.start + selection[1]);
  const t = Number(params.get("t"));
  if (params.has("t") && Number.isFinite(t)) state.setCursor(state.start + t, "link");
  if (params.get("plot")) viewer.setPlotPaths(params.get("plot").split(",").map(decodeURIComponent));
  if (params.get("spec") === "1") viewer.showSpectrum();
}

export function hashOf(viewer) {
  const state = viewer.state;
  const rel = (t) => Number((t - state.start).toFixed(6));
  const parts = [`t=${rel(state.cursor)}`];
  if (state.selection) parts.push(`sel=${rel(state.selection[0])}~${rel(state.selection[1])}`);
  if (state.view[0] !== state.start || state.view[1] !== state.end) {
    parts.push(`view=${rel(state.view[0])}~${rel(state.view[1])}`);
  }
  const plot = viewer.plotPaths();
  if (plot.length) parts.push(`plot=${plot.map(encodeURIComponent).join(",")}`);
  if (viewer.spectrum && !viewer.spectrum.card.hidden) parts.push("spec=1");
  return `#${parts.join("&")}`;
}

/** Keep the address bar and the share box on the current view (no history entries). */
export function followView(viewer, shareInput) {
  const base = shareInput ? shareInput.value.split("#")[0] : "";
  const update = debounce(() => {
    const hash = hashOf(viewer);
    history.replaceState(null, "", hash);
    if (shareInput) shareInput.value = base + hash;
  }, 300);
  for (const type of ["cursor", "selection", "view"]) viewer.state.on(type, update);
  viewer.addEventListener("plotchange", update);
}
