// zwplan viewer: plain JavaScript, no build step, no network beyond this service.
"use strict";

const $ = (id) => document.getElementById(id);
const state = { grid: null, taskId: null, previewUrl: null, chainUrl: null };

function status(text, isError = false) {
  const el = $("status");
  el.textContent = text;
  el.classList.toggle("error", isError);
}

function headers(extra = {}) {
  const key = $("api-key").value.trim();
  return key ? { ...extra, Authorization: `Bearer ${key}` } : extra;
}

// A call to the service; a problem document becomes an Error with its detail.
async function api(path, options = {}) {
  const response = await fetch(path, { ...options, headers: headers(options.headers || {}) });
  if (!response.ok) {
    let detail = `${response.status} ${response.statusText}`;
    try {
      const problem = await response.json();
      detail = `${problem.title}: ${problem.detail}`;
    } catch (_) { /* not a problem document */ }
    throw new Error(detail);
  }
  return response;
}

// ---- z-maps ---------------------------------------------------------------------------

function bytesToBase64(bytes) {
  let binary = "";
  const chunk = 0x8000;
  for (let i = 0; i < bytes.length; i += chunk) {
    binary += String.fromCharCode.apply(null, bytes.subarray(i, i + chunk));
  }
  return btoa(binary);
}

const NPY_READERS = {
  f4: (dv, o, le) => dv.getFloat32(o, le), f8: (dv, o, le) => dv.getFloat64(o, le),
  i1: (dv, o) => dv.getInt8(o), u1: (dv, o) => dv.getUint8(o),
  i2: (dv, o, le) => dv.getInt16(o, le), u2: (dv, o, le) => dv.getUint16(o, le),
  i4: (dv, o, le) => dv.getInt32(o, le), u4: (dv, o, le) => dv.getUint32(o, le),
};

// The .npy format (NumPy's NEP 1): magic, version, header length, a Python dict literal.
function parseNpy(buffer) {
  const u8 = new Uint8Array(buffer);
  const magic = String.fromCharCode(...u8.subarray(1, 6));
  if (u8[0] !== 0x93 || magic !== "NUMPY") throw new Error("not a .npy file");
  const dv = new DataView(buffer);
  const major = u8[6];
  const headerLength = major === 1 ? dv.getUint16(8, true) : dv.getUint32(8, true);
  const start = major === 1 ? 10 : 12;
  const header = new TextDecoder("latin1").decode(u8.subarray(start, start + headerLength));
  const descr = /'descr':\s*'([<>|=])(\w\d)'/.exec(header);
  const fortran = /'fortran_order':\s*True/.test(header);
  const shapeText = /'shape':\s*\(([^)]*)\)/.exec(header);
  if (!descr || !shapeText) throw new Error("unreadable .npy header");
  const read = NPY_READERS[descr[2]];
  if (!read) throw new Error(`.npy dtype ${descr[2]} is not a number type read here`);
  const shape = shapeText[1].split(",").map((s) => s.trim()).filter(Boolean).map(Number);
  if (shape.length !== 2 || shape[0] < 2 || shape[1] < 2) {
    throw new Error(`a z-map is a 2-D grid of at least 2 x 2, this .npy has shape [${shape}]`);
  }
  const [ny, nx] = shape;
  const size = Number(descr[2].slice(1));
  const little = descr[1] !== ">";
  const data = start + headerLength;
  if (buffer.byteLength < data + ny * nx * size) throw new Error(".npy file is truncated");
  const z = new Float64Array(ny * nx);
  for (let i = 0; i < ny; i++) {
    for (let k = 0; k < nx; k++) {
      const index = fortran ? k * ny + i : i * nx + k;
      z[i * nx + k] = read(dv, data + index * size, little);
    }
  }
  // float32 files go up as float32 (half the bytes); everything else as float64
  return { ny, nx, z, dtype: descr[2] === "f4" ? "float32" : "float64" };
}

function setGrid(ny, nx, z, label, dtype = "float64") {
  let lo = Infinity;
  let hi = -Infinity;
  for (const v of z) {
    if (!Number.isFinite(v)) throw new Error("the z-map holds a non-finite height");
    lo = Math.min(lo, v);
    hi = Math.max(hi, v);
  }
  state.grid = { ny, nx, z, dtype };
  $("zmap-info").textContent =
    `${label}: ${ny} x ${nx} nodes, heights ${lo.toFixed(3)} .. ${hi.toFixed(3)} mm`;
  $("run-scanline").disabled = false;
  $("run-contour").disabled = false;
}

function gridBody() {
  const { ny, nx, z, dtype } = state.grid;
  const dx = Number($("dx").value);
  const dy = Number($("dy").value);
  // typed arrays use the platform byte order: little-endian wherever browsers run today
  const values = dtype === "float32" ? Float32Array.from(z) : z;
  return { x0: 0, y0: 0, dx, dy, shape: [ny, nx], dtype,
           z_b64: bytesToBase64(new Uint8Array(values.buffer)) };
}

function syntheticGrid() {
  // a die-like part: a dome on a sloped plate with a pocket, 64 x 64 nodes at 1 mm
  const n = 64;
  const z = new Float64Array(n * n);
  for (let i = 0; i < n; i++) {
    for (let k = 0; k < n; k++) {
      const r2 = (k - 24) ** 2 + (i - 30) ** 2;
      const pocket = (k - 46) ** 2 + (i - 40) ** 2 < 64 ? -4 : 0;
      z[i * n + k] = 12 * Math.exp(-r2 / 180) + 0.05 * k + pocket;
    }
  }
  $("dx").value = 1;
  $("dy").value = 1;
  setGrid(n, n, z, "synthetic part");
}

// ---- tools ------------------------------------------------------------------------------

async function loadDefaultTools() {
  const library = await (await api("/v1/tools")).json();
  $("tools").value = JSON.stringify(library.tools, null, 1);
}

function toolsOfKind(kind) {
  const text = $("tools").value.trim();
  if (!text) return undefined; // the service's shipped library
  let tools;
  try {
    tools = JSON.parse(text);
  } catch (e) {
    throw new Error(`tool library is not JSON: ${e.message}`);
  }
  if (!Array.isArray(tools)) tools = tools.tools;
  if (!Array.isArray(tools)) throw new Error("tool library: a JSON list of tools");
  const picked = tools.filter((t) => !t.kind || t.kind === kind);
  if (!picked.length) throw new Error(`the tool library has no ${kind} end mill`);
  return picked;
}

// ---- plans ------------------------------------------------------------------------------

const COLUMNS = {
  scanline: [["level", "level"], ["pick_feed", "pick-feed"], ["scallop_height", "scallop"],
             ["max_depth_of_cut", "max cut"], ["removed_volume", "removed mm³"],
             ["max_stock_left", "stock left"]],
  contour: [["level", "level"], ["cell_size", "cell"], ["z_levels", "contours"],
            ["removed_volume", "removed mm³"], ["max_stock_left", "stock left"]],
};

function cell(value) {
  if (Array.isArray(value)) {
    return value.length > 2 ? `${value.length}` : value.map((v) => Number(v).toFixed(3)).join(" x ");
  }
  if (typeof value === "number") return Number.isInteger(value) ? `${value}` : value.toFixed(4);
  return value === null || value === undefined ? "" : `${value}`;
}

function showStages(kind, result) {
  const columns = COLUMNS[kind];
  const head = $("stages").querySelector("thead tr");
  head.replaceChildren(...["#", "tool", "Ø mm", "flutes mm", ...columns.map((c) => c[1])]
    .map((text) => Object.assign(document.createElement("th"), { textContent: text })));
  const body = $("stages").querySelector("tbody");
  body.replaceChildren(...result.stages.map((stage) => {
    const row = document.createElement("tr");
    const values = [stage.index, stage.tool.id, stage.tool.diameter, stage.tool.flute_length,
                    ...columns.map((c) => stage[c[0]])];
    row.replaceChildren(...values.map((v) => Object.assign(document.createElement("td"),
                                                           { textContent: cell(v) })));
    row.addEventListener("click", () => {
      body.querySelectorAll("tr").forEach((r) => r.classList.remove("selected"));
      row.classList.add("selected");
      showPreview(`?stage=${stage.index}`).catch((e) => status(e.message, true));
    });
    return row;
  }));
}

async function previewBlob(query, imgId, urlKey, taskId) {
  const blob = await (await api(`/v1/tasks/${taskId}/preview.png${query}`)).blob();
  if (state[urlKey]) URL.revokeObjectURL(state[urlKey]);
  state[urlKey] = URL.createObjectURL(blob);
  const img = $(imgId);
  await new Promise((resolve, reject) => {
    img.onload = resolve;
    img.onerror = () => reject(new Error("the preview did not decode"));
    img.src = state[urlKey];
  });
}

function showPreview(query = "") {
  return previewBlob(query, "preview", "previewUrl", state.taskId);
}

async function runPlan(kind) {
  if (!state.grid) throw new Error("load or make a z-map first");
  const body = { include_models: true };
  if (state.grid.gridTask) body.grid_task = state.grid.gridTask;
  else body.grid = gridBody();
  const tools = toolsOfKind(kind === "scanline" ? "ball" : "flat");
  if (tools) body.tools = tools;
  if (kind === "scanline") body.tolerance = Number($("tolerance").value);
  status(`running the ${kind} plan ...`);
  const result = await (await api(`/v1/plans/${kind}`, {
    method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify(body),
  })).json();
  state.taskId = result.task_id;
  const checks = result.checks || {};
  $("plan-info").textContent = `${kind} plan, task ${result.task_id.slice(0, 12)}: ` +
    `${result.stages.length} stages, stock top ${result.stock_top.toFixed(3)} mm, ` +
    `checks ${checks.ok ? "ok" : "FAILED"}` +
    (result.notes && result.notes.length ? ` (${result.notes.join("; ")})` : "");
  showStages(kind, result);
  status(`drawing the ${result.stages.length} stages ...`);
  await showPreview();
  status(`${kind} plan done`);
}

// ---- curves -----------------------------------------------------------------------------

function exampleCurve() {
  const lines = [];
  for (let i = 0; i <= 120; i++) {
    const t = (Math.PI * i) / 120;
    lines.push(`${(60 * Math.cos(t)).toFixed(4)} ${(25 * Math.sin(t)).toFixed(4)}`);
  }
  for (let i = 1; i <= 30; i++) lines.push(`${(-60 + 2 * i).toFixed(4)} 0`);
  $("curve").value = lines.join("\n");
  $("curve-file").value = "";
}

function parsePoints(text) {
  if (text.startsWith("[")) return JSON.parse(text);
  return text.split(/\n/).map((l) => l.trim()).filter(Boolean)
    .map((l) => l.split(/[\s,;]+/).slice(0, 2).map(Number));
}

function download(name, text, type) {
  const link = document.createElement("a");
  link.href = URL.createObjectURL(new Blob([text], { type }));
  link.download = name;
  link.textContent = `download ${name}`;
  $("downloads").replaceChildren(link);
}

async function curveRequest() {
  const tolerance = Number($("curve-tolerance").value);
  const file = $("curve-file").files[0];
  const text = $("curve").value.trim();
  if (file) {
    const isDxf = file.name.toLowerCase().endsWith(".dxf");
    return { path: `/v1/arcs?tolerance=${tolerance}`, body: await file.arrayBuffer(),
             type: isDxf ? "application/dxf" : "text/plain" };
  }
  if (!text) throw new Error("paste a curve or a program, or load a file");
  if (/[GXYM]\s*-?\d/i.test(text) && !text.startsWith("[")) {
    return { path: `/v1/arcs?tolerance=${tolerance}`, body: text, type: "text/plain" };
  }
  const points = parsePoints(text);
  const body = { points, tolerance, closed: $("curve-closed").checked, gcode: true };
  return { path: "/v1/arcs", body: JSON.stringify(body), type: "application/json" };
}

async function runArcs() {
  const request = await curveRequest();
  status("fitting arcs ...");
  const result = await (await api(request.path, {
    method: "POST", headers: { "Content-Type": request.type }, body: request.body,
  })).json();
  $("arcs-info").textContent = JSON.stringify(result.summary, null, 1);
  $("program").textContent = "";
  $("downloads").replaceChildren();
  if (result.operation === "arcs_gcode") {
    $("program").textContent = result.program.split("\n").slice(0, 400).join("\n");
    download("rewritten.nc", result.program, "text/plain");
  } else if (result.operation === "arcs_dxf") {
    download("arcs.dxf", result.dxf, "application/dxf");
  } else if (result.gcode) {
    $("program").textContent = result.gcode;
    download("chain.nc", result.gcode, "text/plain");
  }
  await previewBlob("", "chain-preview", "chainUrl", result.task_id);
  status("arcs done");
}

// ---- wiring -----------------------------------------------------------------------------

function guarded(fn) {
  return () => fn().catch((e) => status(e.message, true));
}

// An STL becomes a z-map task on the service (POST /v1/zmaps); plans then name it by
// its task id (grid_task), so the grid is uploaded once and planned many times.
async function readStl(file) {
  const dx = Number($("dx").value);
  const dy = Number($("dy").value);
  status(`making the z-map of ${file.name} ...`);
  const result = await (await api(`/v1/zmaps?dx=${dx}&dy=${dy}&grid_encoding=float32`, {
    method: "POST", headers: { "Content-Type": "model/stl" }, body: await file.arrayBuffer(),
  })).json();
  const { nx, ny } = result.grid;
  state.grid = { gridTask: result.task_id, ny, nx };
  const b = result.bounds;
  $("zmap-info").textContent = `${file.name}: z-map task ${result.task_id.slice(0, 12)}, ` +
    `${ny} x ${nx} nodes, part ${b.min[2].toFixed(3)} .. ${b.max[2].toFixed(3)} mm` +
    (result.notes.length ? ` (${result.notes.join("; ")})` : "");
  $("run-scanline").disabled = false;
  $("run-contour").disabled = false;
  status("");
}

async function readGridFile() {
  const file = $("npy-file").files[0];
  if (!file) return;
  if (file.name.toLowerCase().endsWith(".stl")) {
    await readStl(file);
    return;
  }
  const { ny, nx, z, dtype } = parseNpy(await file.arrayBuffer());
  setGrid(ny, nx, z, file.name, dtype);
  status("");
}

async function readTools() {
  const file = $("tools-file").files[0];
  if (file) $("tools").value = await file.text();
}

$("api-key").value = sessionStorage.getItem("zwplan-api-key") || "";
$("api-key").addEventListener("change", () => {
  sessionStorage.setItem("zwplan-api-key", $("api-key").value.trim());
});
$("npy-file").addEventListener("change", guarded(readGridFile));
$("synthetic").addEventListener("click", guarded(async () => syntheticGrid()));
$("tools-file").addEventListener("change", guarded(readTools));
$("tools-default").addEventListener("click", guarded(loadDefaultTools));
$("run-scanline").addEventListener("click", guarded(() => runPlan("scanline")));
$("run-contour").addEventListener("click", guarded(() => runPlan("contour")));
$("preview").addEventListener("click", guarded(() => showPreview()));
$("curve-example").addEventListener("click", guarded(async () => exampleCurve()));
$("run-arcs").addEventListener("click", guarded(runArcs));
guarded(loadDefaultTools)();
