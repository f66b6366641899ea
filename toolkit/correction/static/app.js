// The correction page: camera views with draggable joints, frame slider, cost, 3D skeleton, rule highlights.
// Talks to the JSON API of toolkit/correction/app.py only; no external scripts.
"use strict";

const SVG_NS = "http://www.w3.org/2000/svg";
const VIEW_W = 320, VIEW_H = 400;          // on-screen size of a camera view, CSS pixels
const CROP_MARGIN = 0.35;                  // crop around the subject: its box plus this fraction each side
const MIN_CROP_PX = 60;                    // smallest crop height, image pixels
const ELEVATION = 0.25;                    // 3D view: radians above the horizon

const state = { info: null, frames: [], t: null, data: null, crops: {}, azimuth: 30, busy: false, drag: null };

function el(tag, attrs = {}, parent = null) {
  const e = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

function setStatus(text, error = false) {
  const s = document.getElementById("status");
  s.textContent = text;
  s.classList.toggle("error", error);
}

async function api(method, url, body) {
  const opts = { method, headers: {} };
  if (body !== undefined) {
    opts.headers["Content-Type"] = "application/json";
    opts.body = JSON.stringify(body);
  }
  const r = await fetch(url, opts);
  const j = await r.json().catch(() => ({}));
  if (!r.ok) throw new Error(`${r.status}: ${typeof j.detail === "string" ? j.detail : JSON.stringify(j.detail)}`);
  return j;
}

const isLeft = (name) => name.startsWith("l_");

// ------------------------------------------------------------------ camera views
function buildViews() {
  const box = document.getElementById("views");
  box.textContent = "";
  for (const cam of Object.keys(state.info.cameras)) {
    const div = document.createElement("div");
    div.className = "view";
    const h = document.createElement("h3");
    h.textContent = cam;
    div.appendChild(h);
    const svg = el("svg", { "data-camera": cam, width: VIEW_W, height: VIEW_H,
                            preserveAspectRatio: "xMidYMid meet" }, div);
    const [w, hgt] = state.info.cameras[cam].size;
    // pixel centres at integer coordinates: the image's top-left corner is at (-0.5, -0.5)
    el("image", { x: -0.5, y: -0.5, width: w, height: hgt, class: "camera-image", "data-camera": cam }, svg);
    el("g", { class: "reprojections" }, svg);
    el("g", { class: "bones" }, svg);
    el("g", { class: "joints" }, svg);
    box.appendChild(div);
  }
}

function cropFor(cam) {
  const pts = [];
  for (const src of [state.data.cameras[cam], state.data.reprojections[cam]])
    for (const p of Object.values(src)) if (p) pts.push(p);
  const [w, h] = state.info.cameras[cam].size;
  if (!pts.length) return [-0.5, -0.5, w, h];
  const xs = pts.map((p) => p[0]), ys = pts.map((p) => p[1]);
  const x0 = Math.min(...xs), x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
  let ch = Math.max((y1 - y0) * (1 + 2 * CROP_MARGIN), MIN_CROP_PX);
  let cw = Math.max((x1 - x0) * (1 + 2 * CROP_MARGIN), ch * VIEW_W / VIEW_H);
  ch = Math.max(ch, cw * VIEW_H / VIEW_W);
  return [(x0 + x1) / 2 - cw / 2, (y0 + y1) / 2 - ch / 2, cw, ch];
}

function jointPosition(cam, name) {
  return state.data.cameras[cam][name] || state.data.reprojections[cam][name];
}

function renderView(cam) {
  const svg = document.querySelector(`svg[data-camera="${cam}"]`);
  const crop = state.crops[cam];
  svg.setAttribute("viewBox", crop.join(" "));
  const r = crop[3] / 70;
  const bad = new Set(state.data.violations.flatMap((v) => v.joints));
  const edited = new Set(state.data.edited[cam]);
  const rep = svg.querySelector("g.reprojections");
  rep.textContent = "";
  if (document.getElementById("show-reprojection").checked) {
    for (const [a, b] of state.info.bones) {
      const p = state.data.reprojections[cam][a], q = state.data.reprojections[cam][b];
      if (p && q) el("line", { x1: p[0], y1: p[1], x2: q[0], y2: q[1], class: "reproj",
                               "stroke-width": r / 3, "stroke-dasharray": `${r} ${r * 0.7}` }, rep);
    }
  }
  const bones = svg.querySelector("g.bones");
  bones.textContent = "";
  for (const [a, b] of state.info.bones) {
    const p = state.data.cameras[cam][a], q = state.data.cameras[cam][b];
    if (p && q) el("line", { x1: p[0], y1: p[1], x2: q[0], y2: q[1], "data-a": a, "data-b": b,
                             class: "bone" + (isLeft(b) ? " l" : ""), "stroke-width": r / 2 }, bones);
  }
  const joints = svg.querySelector("g.joints");
  joints.textContent = "";
  for (const name of state.info.joints) {
    const p = jointPosition(cam, name) || [crop[0] + crop[2] / 2, crop[1] + crop[3] / 2];
    const cls = ["joint"];
    if (isLeft(name)) cls.push("l");
    if (edited.has(name)) cls.push("edited");
    if (!state.data.cameras[cam][name]) cls.push("missing");
    if (bad.has(name)) cls.push("violation");
    const c = el("circle", { cx: p[0], cy: p[1], r, class: cls.join(" "), "stroke-width": r / 3,
                             "data-joint": name, "data-camera": cam }, joints);
    const title = el("title", {}, c);
    title.textContent = `${name} (${cam})`;
    c.addEventListener("pointerdown", startDrag);
  }
}

function toImage(svg, clientX, clientY) {
  const pt = svg.createSVGPoint();
  pt.x = clientX;
  pt.y = clientY;
  const p = pt.matrixTransform(svg.getScreenCTM().inverse());
  return [p.x, p.y];
}

function startDrag(ev) {
  if (state.busy) return;
  ev.preventDefault();
  const c = ev.currentTarget;
  c.setPointerCapture(ev.pointerId);
  c.classList.add("dragging");
  state.drag = { circle: c, cam: c.dataset.camera, joint: c.dataset.joint, moved: false };
  c.addEventListener("pointermove", moveDrag);
  c.addEventListener("pointerup", endDrag);
  c.addEventListener("pointercancel", endDrag);
}

function moveDrag(ev) {
  const d = state.drag;
  if (!d) return;
  const svg = d.circle.ownerSVGElement;
  const [x, y] = toImage(svg, ev.clientX, ev.clientY);
  d.circle.setAttribute("cx", x);
  d.circle.setAttribute("cy", y);
  d.moved = true;
  d.xy = [x, y];
  for (const line of svg.querySelectorAll("g.bones line")) {
    if (line.dataset.a === d.joint) { line.setAttribute("x1", x); line.setAttribute("y1", y); }
    if (line.dataset.b === d.joint) { line.setAttribute("x2", x); line.setAttribute("y2", y); }
  }
}

async function endDrag(ev) {
  const d = state.drag;
  if (!d) return;
  state.drag = null;
  const c = d.circle;
  c.classList.remove("dragging");
  c.removeEventListener("pointermove", moveDrag);
  c.removeEventListener("pointerup", endDrag);
  c.removeEventListener("pointercancel", endDrag);
  if (!d.moved || ev.type === "pointercancel") { renderFrame(); return; }
  const t = state.t;
  await send("PUT", `/api/frames/${t}/cameras/${encodeURIComponent(d.cam)}/joints/${encodeURIComponent(d.joint)}`,
             { xy: d.xy }, `moved ${d.joint} in ${d.cam}: saved to edits.toml`);
}

async function send(method, url, body, message) {
  state.busy = true;
  try {
    state.data = await api(method, url, body);
    renderFrame();
    setStatus(message);
  } catch (e) {
    setStatus(e.message, true);
    renderFrame();
  } finally {
    state.busy = false;
  }
}

// ------------------------------------------------------------------ 3D view
function render3d() {
  const svg = document.getElementById("view3d");
  svg.textContent = "";
  const j = state.data.joints3d;
  const pts = Object.values(j).filter(Boolean);
  if (!pts.length) return;
  const cx = pts.reduce((s, p) => s + p[0], 0) / pts.length;
  const cy = pts.reduce((s, p) => s + p[1], 0) / pts.length;
  const zc = pts.reduce((s, p) => s + p[2], 0) / pts.length;
  const a = state.azimuth * Math.PI / 180, ce = Math.cos(ELEVATION), se = Math.sin(ELEVATION);
  const proj = (p) => {
    const dx = p[0] - cx, dy = p[1] - cy, dz = p[2] - zc;
    const u = -Math.sin(a) * dx + Math.cos(a) * dy;
    const depth = Math.cos(a) * dx + Math.sin(a) * dy;
    return [u, -(ce * dz + se * depth)];
  };
  const g0 = proj([cx - 0.6, cy, 0]), g1 = proj([cx + 0.6, cy, 0]), g2 = proj([cx, cy - 0.6, 0]), g3 = proj([cx, cy + 0.6, 0]);
  el("line", { x1: g0[0], y1: g0[1], x2: g1[0], y2: g1[1], class: "ground", "stroke-width": 0.01 }, svg);
  el("line", { x1: g2[0], y1: g2[1], x2: g3[0], y2: g3[1], class: "ground", "stroke-width": 0.01 }, svg);
  const bad = new Set(state.data.violations.flatMap((v) => v.joints));
  for (const [na, nb] of state.info.bones) {
    if (!j[na] || !j[nb]) continue;
    const p = proj(j[na]), q = proj(j[nb]);
    el("line", { x1: p[0], y1: p[1], x2: q[0], y2: q[1], class: "bone" + (isLeft(nb) ? " l" : ""),
                 "stroke-width": 0.025 }, svg);
  }
  for (const name of state.info.joints) {
    if (!j[name]) continue;
    const p = proj(j[name]);
    const cls = "joint3d" + (isLeft(name) ? " l" : "") + (bad.has(name) ? " violation" : "");
    const c = el("circle", { cx: p[0], cy: p[1], r: 0.03, class: cls, "data-joint3d": name }, svg);
    el("title", {}, c).textContent = `${name}: ${j[name].map((v) => v.toFixed(3)).join(", ")} m`;
  }
}

// ------------------------------------------------------------------ the frame
function renderFrame() {
  for (const cam of Object.keys(state.info.cameras)) renderView(cam);
  render3d();
  const cost = state.data.cost;
  document.getElementById("cost").textContent = cost === null ? "unknown" : `${(cost * 1000).toFixed(1)} mm`;
  document.getElementById("frame-label").textContent = `${state.t} (${state.frames.indexOf(state.t) + 1} of ${state.frames.length})`;
  document.getElementById("undo").disabled = state.data.undo === 0;
  const ul = document.getElementById("violations");
  ul.textContent = "";
  if (!state.data.violations.length) {
    const li = document.createElement("li");
    li.className = "ok";
    li.textContent = "every rule holds";
    ul.appendChild(li);
  }
  for (const v of state.data.violations) {
    const li = document.createElement("li");
    li.textContent = v.text;
    ul.appendChild(li);
  }
}

async function loadFrame(t) {
  state.t = t;
  try {
    state.data = await api("GET", `/api/frames/${t}`);
  } catch (e) {
    setStatus(e.message, true);
    return;
  }
  for (const cam of Object.keys(state.info.cameras)) {
    state.crops[cam] = cropFor(cam);
    const img = document.querySelector(`image[data-camera="${cam}"]`);
    img.setAttribute("href", `/api/frames/${t}/cameras/${encodeURIComponent(cam)}/image`);
  }
  renderFrame();
  setStatus(`frame ${t}: drag a joint to correct it`);
}

async function main() {
  try {
    state.info = await api("GET", "/api/info");
    state.frames = (await api("GET", "/api/frames")).frames;
  } catch (e) {
    setStatus(e.message, true);
    return;
  }
  document.getElementById("run-name").textContent = state.info.run;
  if (!state.frames.length) { setStatus("the run has no frame with an estimate", true); return; }
  buildViews();
  const slider = document.getElementById("frame-slider");
  slider.max = state.frames.length - 1;
  slider.addEventListener("input", () => loadFrame(state.frames[Number(slider.value)]));
  document.getElementById("undo").addEventListener("click", () =>
    send("POST", `/api/frames/${state.t}/undo`, undefined, "undone"));
  document.getElementById("commit").addEventListener("click", async () => {
    try {
      const r = await api("POST", `/api/frames/${state.t}/commit`);
      const skipped = Object.entries(r.skipped).map(([c, why]) => `${c}: ${why}`).join("; ");
      setStatus(`added ${r.added} pose(s) to ${r.database} (${r.size} entries)` + (skipped ? `; skipped ${skipped}` : ""));
    } catch (e) {
      setStatus(e.message, true);
    }
  });
  document.getElementById("show-reprojection").addEventListener("change", renderFrame);
  const az = document.getElementById("azimuth");
  az.addEventListener("input", () => { state.azimuth = Number(az.value); render3d(); });
  const spin = () => {
    if (!document.getElementById("rotate").checked) return;
    state.azimuth = ((state.azimuth + 181) % 360) - 180;
    az.value = state.azimuth;
    render3d();
    requestAnimationFrame(spin);
  };
  document.getElementById("rotate").addEventListener("change", spin);
  document.addEventListener("keydown", (e) => {
    if ((e.ctrlKey || e.metaKey) && e.key === "z" && !state.busy) {
      e.preventDefault();
      send("POST", `/api/frames/${state.t}/undo`, undefined, "undone");
    }
  });
  await loadFrame(state.frames[0]);
}

main();
