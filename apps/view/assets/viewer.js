// specula view: the page. Plain JavaScript, no build step; every number comes from the /api endpoints of
// apps/view/service.cpp. The plotted points carry their values (data-nm, data-value) so tests can read them.
"use strict";

const $ = (sel) => document.querySelector(sel);
const SVG = "http://www.w3.org/2000/svg";
const COLOURS = ["#1f5fbf", "#d0402a", "#2a9d4a", "#8e44ad", "#c98a00", "#00838f", "#6d4c41"];
let listing = null;

function el(tag, attrs = {}, parent = null, ns = null) {
  const e = ns ? document.createElementNS(ns, tag) : document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "text") e.textContent = v; else e.setAttribute(k, v);
  }
  if (parent) parent.appendChild(e);
  return e;
}

function showError(message) {
  const s = $("#status");
  s.textContent = message;
  s.style.display = message ? "block" : "none";
}

async function getJSON(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${r.status}: ${await r.text()}`);
  return r.json();
}

const query = (params) => new URLSearchParams(params).toString();

// A line/scatter plot. series: [{xs, ys, colour, dash, points, cls, label}]; nulls break lines.
function plot(svg, series, opts) {
  svg.replaceChildren();
  const W = +svg.getAttribute("width"), H = +svg.getAttribute("height");
  const L = 58, R = 12, T = 22, B = 38;
  const all = series.flatMap((s) => s.ys.filter((y) => y !== null && Number.isFinite(y)));
  let ymin = opts.ymin ?? Math.min(0, ...all), ymax = opts.ymax ?? Math.max(...all, ymin + 1e-12);
  if (ymax <= ymin) ymax = ymin + 1;
  const xmin = opts.xmin, xmax = opts.xmax;
  const X = (x) => L + ((x - xmin) / (xmax - xmin)) * (W - L - R);
  const Y = (y) => H - B - ((y - ymin) / (ymax - ymin)) * (H - T - B);
  el("rect", { x: L, y: T, width: W - L - R, height: H - T - B, fill: "none", stroke: "#999" }, svg, SVG);
  for (let i = 0; i <= 4; i++) {
    const xv = xmin + ((xmax - xmin) * i) / 4, yv = ymin + ((ymax - ymin) * i) / 4;
    el("text", { x: X(xv), y: H - B + 14, "text-anchor": "middle", text: +xv.toPrecision(4) }, svg, SVG);
    el("text", { x: L - 4, y: Y(yv) + 4, "text-anchor": "end", text: +yv.toPrecision(3) }, svg, SVG);
  }
  el("text", { x: (L + W - R) / 2, y: H - 6, "text-anchor": "middle", text: opts.xlabel }, svg, SVG);
  el("text", { x: L, y: 14, text: opts.ylabel }, svg, SVG);
  series.forEach((s, si) => {
    const g = el("g", { class: s.cls || "series" }, svg, SVG);
    let d = "", pen = false;
    s.xs.forEach((x, i) => {
      const y = s.ys[i];
      if (y === null || !Number.isFinite(y)) { pen = false; return; }
      d += `${pen ? "L" : "M"}${X(x).toFixed(2)},${Y(y).toFixed(2)}`;
      pen = true;
    });
    if (!s.points || s.line) {
      el("path", { d, fill: "none", stroke: s.colour, "stroke-width": 1.6, "stroke-dasharray": s.dash || "" }, g, SVG);
    }
    if (s.points) {
      s.xs.forEach((x, i) => {
        const y = s.ys[i];
        if (y === null || !Number.isFinite(y)) return;
        el("circle", { cx: X(x), cy: Y(y), r: s.radius ?? 2.2, fill: s.colour, "data-nm": x, "data-value": s.raw ? s.raw[i] : y }, g, SVG);
      });
    }
    if (s.label) el("text", { x: W - R - 4, y: T + 14 + 14 * si, "text-anchor": "end", fill: s.colour, text: s.label }, svg, SVG);
  });
}

function slider(parent, label, min, max, step, value, onInput) {
  const l = el("label", {}, parent);
  const span = el("span", {}, l);
  const input = el("input", { type: "range", min, max, step, value }, l);
  const update = () => { span.textContent = label(+input.value) + " "; };
  update();
  input.addEventListener("input", () => { update(); onInput(+input.value); });
  return input;
}

// ---- images ---------------------------------------------------------------------------------------------
function showImage(info) {
  const content = $("#content");
  content.replaceChildren();
  const left = el("div", { class: "panel" }, content);
  const controls = el("div", { class: "controls" }, left);
  const state = { illuminant: "D65", exposure: "auto", band: Math.floor(info.bands / 2), showBand: false,
                  basis: "", k: 3, pins: [], last: null, pending: null, busy: false };

  const ill = el("select", { id: "illuminant" }, el("label", { text: "Illuminant " }, controls));
  for (const n of ["D65", "D50", "A", "E"]) el("option", { value: n, text: n }, ill);
  for (const c of listing.collections) {
    if (c.bands !== info.bands || c.size > 32) continue;
    for (let i = 0; i < c.size; i++) el("option", { value: `collection:${c.name}:${i}`, text: `${c.name}[${i}]` }, ill);
  }
  ill.addEventListener("change", () => { state.illuminant = ill.value; refresh(); });

  const autoBox = el("input", { type: "checkbox", checked: "" }, el("label", { text: "Auto exposure " }, controls));
  const exposure = slider(controls, (v) => `Exposure ${v} EV`, -8, 8, 0.5, 0, (v) => {
    autoBox.checked = false; state.exposure = String(v); refresh();
  });
  autoBox.addEventListener("change", () => { state.exposure = autoBox.checked ? "auto" : exposure.value; refresh(); });

  const bandBox = el("input", { type: "checkbox", id: "show-band" }, el("label", { text: "Show one band " }, controls));
  slider(controls, (v) => `Band ${v} (${info.wavelengths[v]} nm)`, 0, info.bands - 1, 1, state.band, (v) => {
    state.band = v; bandBox.checked = true; state.showBand = true; refresh();
  }).id = "band";
  bandBox.addEventListener("change", () => { state.showBand = bandBox.checked; refresh(); });

  const basis = el("select", { id: "basis" }, el("label", { text: "Reconstruct with " }, controls));
  el("option", { value: "", text: "no basis" }, basis);
  for (const b of listing.bases) if (b.bands === info.bands) el("option", { value: b.name, text: `${b.name} (${b.method}, k ${b.k})` }, basis);
  const kInput = el("input", { type: "number", min: 0, max: 64, value: state.k, style: "width:4em", id: "k" },
                    el("label", { text: "k (PCA) " }, controls));
  basis.addEventListener("change", () => { state.basis = basis.value; resend(); });
  kInput.addEventListener("change", () => { state.k = +kInput.value; resend(); });
  const clear = el("button", { text: "Clear pinned spectra" }, controls);
  clear.addEventListener("click", () => { state.pins = []; draw(); });

  el("div", { class: "hint", text: `${info.width} x ${info.height}, ${info.bands} bands, ${info.units}. Hover for the spectrum, click to pin it.` }, left);
  const img = el("img", { class: "picture", id: "picture", alt: info.name }, left);

  const right = el("div", { class: "panel" }, content);
  const svg = el("svg", { class: "plot", id: "spectrum", width: 560, height: 330 }, right, SVG);
  const readout = el("div", { id: "readout" }, right);

  function refresh() {
    const p = state.showBand ? `/api/image/band?${query({ name: info.name, band: state.band })}`
                             : `/api/image/rgb?${query({ name: info.name, illuminant: state.illuminant, exposure: state.exposure })}`;
    img.src = p;
  }
  img.addEventListener("error", async () => {
    const r = await fetch(img.src);
    showError(r.ok ? "" : `${r.status}: ${await r.text()}`);
  });
  img.addEventListener("load", () => {
    // Small images are enlarged by a whole factor so that pixels stay square and easy to point at.
    const zoom = Math.max(1, Math.floor(640 / Math.max(img.naturalWidth, img.naturalHeight / 0.75)));
    img.style.width = `${img.naturalWidth * zoom}px`;
    showError("");
    img.dataset.loaded = "1";
  });

  function draw() {
    const series = [];
    state.pins.forEach((p, i) => series.push({ xs: info.wavelengths, ys: p.values, colour: COLOURS[(i + 2) % COLOURS.length],
                                               label: `pinned (${p.x}, ${p.y})`, cls: "pinned" }));
    const s = state.last;
    if (s) {
      series.push({ xs: s.wavelengths, ys: s.values, colour: COLOURS[0], points: true, line: true, cls: "spectrum",
                    label: `(${s.x}, ${s.y})${s.valid ? "" : " masked"}` });
      if (s.reconstruction)
        series.push({ xs: s.wavelengths, ys: s.reconstruction.values, colour: COLOURS[1], dash: "5,3", cls: "reconstruction",
                      label: `${s.reconstruction.basis}, k ${s.reconstruction.k}` });
    }
    plot(svg, series, { xmin: info.wavelengths[0], xmax: info.wavelengths[info.bands - 1], xlabel: "wavelength (nm)",
                        ylabel: info.units });
    if (!s) return;
    let text = `pixel (${s.x}, ${s.y})  ${s.valid ? "valid" : "masked"}`;
    if (s.reconstruction)
      text += `\n${s.reconstruction.basis} (${s.reconstruction.method}, k ${s.reconstruction.k}): L2 error ` +
              `${s.reconstruction.l2_error.toPrecision(4)}, relative ${s.reconstruction.relative_error.toPrecision(4)}`;
    readout.textContent = text;
  }

  // One request at a time; the latest pixel wins.
  async function request(x, y) {
    state.pending = { x, y };
    if (state.busy) return;
    state.busy = true;
    while (state.pending) {
      const p = state.pending;
      state.pending = null;
      const params = { name: info.name, x: p.x, y: p.y };
      if (state.basis) Object.assign(params, { basis: state.basis, k: state.k });
      try {
        state.last = await getJSON(`/api/image/spectrum?${query(params)}`);
        showError("");
        draw();
        svg.dataset.pixel = `${p.x},${p.y}`;
      } catch (e) { showError(e.message); }
    }
    state.busy = false;
  }
  function resend() { if (state.last) request(state.last.x, state.last.y); }
  function pixelOf(ev) {
    const r = img.getBoundingClientRect();
    const x = Math.floor(((ev.clientX - r.left) / r.width) * img.naturalWidth);
    const y = Math.floor(((ev.clientY - r.top) / r.height) * img.naturalHeight);
    return [Math.min(Math.max(x, 0), img.naturalWidth - 1), Math.min(Math.max(y, 0), img.naturalHeight - 1)];
  }
  img.addEventListener("mousemove", (ev) => request(...pixelOf(ev)));
  img.addEventListener("click", () => {
    if (state.last && state.pins.length < 6) state.pins.push(state.last);
    draw();
  });
  refresh();
  draw();
}

// ---- BRDF grids -----------------------------------------------------------------------------------------
function showGrid(info) {
  const content = $("#content");
  content.replaceChildren();
  const left = el("div", { class: "panel" }, content);
  el("div", { class: "hint", text: `${info.name}: ${info.bands} bands, under D65 from one direction` }, left);
  const sphere = el("img", { class: "picture", id: "sphere", alt: info.name }, left);
  const light = { theta: 45, phi: 135 };
  const lightControls = el("div", { class: "controls" }, left);
  const relight = () => { sphere.src = `/api/grid/sphere?${query({ name: info.name, light_theta: light.theta, light_phi: light.phi })}`; };
  slider(lightControls, (v) => `Light θ ${v}° from the viewer`, 0, 85, 5, light.theta, (v) => { light.theta = v; relight(); });
  slider(lightControls, (v) => `Light φ ${v}°`, 0, 360, 15, light.phi, (v) => { light.phi = v; relight(); });
  relight();
  const right = el("div", { class: "panel" }, content);
  const controls = el("div", { class: "controls" }, right);
  const state = { theta: 45, band: Math.floor(info.bands / 2), data: null };
  slider(controls, (v) => `θi ${v}°`, 0, 89, 1, state.theta, (v) => { state.theta = v; load(); });
  slider(controls, (v) => `Band ${v} (${info.wavelengths[v]} nm)`, 0, info.bands - 1, 1, state.band, (v) => { state.band = v; draw(); });
  const svg = el("svg", { class: "plot", id: "incidence", width: 560, height: 330 }, right, SVG);
  // A reconstruction with a prior (docs/prior.md): its confidence along the same slice, 1 at a sample, 0 where the
  // prior alone fills the cell.
  let confidence = null;
  if (info.confidence) {
    const l = el("label", { class: "controls" }, right);
    const box = el("input", { type: "checkbox", id: "show-confidence", checked: "" }, l);
    el("span", { text: ` Show the confidence (${info.confidence})` }, l);
    confidence = el("svg", { class: "plot", id: "confidence", width: 560, height: 170 }, right, SVG);
    box.addEventListener("change", () => { confidence.style.display = box.checked ? "" : "none"; });
  }
  async function load() {
    try { state.data = await getJSON(`/api/grid/incidence?${query({ name: info.name, theta_i: state.theta })}`); showError(""); draw(); }
    catch (e) { showError(e.message); }
  }
  function draw() {
    const d = state.data;
    if (!d) return;
    const raw = d.values.map((row) => row[state.band]);
    plot(svg, [{ xs: d.theta_o, ys: raw.map((v) => (v === null ? null : Math.cbrt(Math.max(0, v)))), raw, colour: COLOURS[0],
                 line: true, points: true, radius: 1.4, label: `${d.wavelengths[state.band]} nm` }],
         { xmin: -90, xmax: 90, xlabel: "θo (degrees; negative: the light's side)", ylabel: "cube root of the BRDF (1/sr)" });
    if (confidence && d.confidence) {
      plot(confidence, [{ xs: d.theta_o, ys: d.confidence.map((v) => (v === null || v < 0 ? null : v)), colour: COLOURS[2],
                          line: true, points: true, radius: 1.4, cls: "confidence" }],
           { xmin: -90, xmax: 90, ymin: 0, ymax: 1, xlabel: "θo (degrees)", ylabel: "confidence (1: measured, 0: the prior alone)" });
      confidence.dataset.theta = d.theta_i;
    }
  }
  load();
}

// ---- scattered samples ----------------------------------------------------------------------------------
function showSamples(info) {
  const content = $("#content");
  content.replaceChildren();
  const panel = el("div", { class: "panel" }, content);
  el("div", { class: "hint", text: `${info.name}: ${info.size.toLocaleString()} samples, ${info.bands} bands` }, panel);
  const controls = el("div", { class: "controls" }, panel);
  const state = { theta: 45, band: Math.floor(info.bands / 2), eps: 2 };
  slider(controls, (v) => `θi ${v}°`, 0, 89, 1, state.theta, (v) => { state.theta = v; load(); });
  slider(controls, (v) => `Band ${v} (${info.wavelengths[v]} nm)`, 0, info.bands - 1, 1, state.band, (v) => { state.band = v; load(); });
  slider(controls, (v) => `Within ${v}° of the plane and of θi`, 0.5, 10, 0.5, state.eps, (v) => { state.eps = v; load(); });
  const svg = el("svg", { class: "plot", id: "scatter", width: 560, height: 330 }, panel, SVG);
  const note = el("div", { class: "hint" }, panel);
  async function load() {
    try {
      const d = await getJSON(`/api/samples/incidence?${query({ name: info.name, theta_i: state.theta, band: state.band, eps: state.eps })}`);
      showError("");
      plot(svg, [{ xs: d.points.map((p) => p[0]), ys: d.points.map((p) => Math.cbrt(Math.max(0, p[1]))), raw: d.points.map((p) => p[1]),
                   colour: COLOURS[0], points: true, radius: 1.6 }],
           { xmin: -90, xmax: 90, xlabel: "θo (degrees; negative: the light's side)", ylabel: `cube root of the BRDF at ${d.wavelength} nm` });
      note.textContent = `${d.points.length} samples shown of ${d.scanned.toLocaleString()} read`;
    } catch (e) { showError(e.message); }
  }
  load();
}

// ---- the store ------------------------------------------------------------------------------------------
async function main() {
  try { listing = await getJSON("/api/store"); } catch (e) { showError(e.message); return; }
  $("#file").textContent = listing.file;
  const nav = $("#objects");
  nav.replaceChildren();
  const kinds = [["images", "Images", showImage], ["grids", "BRDF grids", showGrid], ["samples", "Scattered samples", showSamples]];
  const buttons = [];
  for (const [key, title, show] of kinds) {
    if (!listing[key].length) continue;
    el("h3", { text: title }, nav);
    for (const o of listing[key]) {
      const b = el("button", { text: o.name, "data-kind": key, "data-name": o.name }, nav);
      buttons.push(b);
      b.addEventListener("click", () => {
        buttons.forEach((x) => x.classList.toggle("active", x === b));
        location.hash = `${key}=${encodeURIComponent(o.name)}`;
        show(o);
      });
    }
  }
  if (listing.bases.length) {
    el("h3", { text: "Bases" }, nav);
    for (const b of listing.bases) el("div", { text: `${b.name} (${b.method}, k ${b.k})` }, nav);
  }
  const m = /^#(images|grids|samples)=(.+)$/.exec(location.hash);
  const wanted = m ? buttons.find((b) => b.dataset.kind === m[1] && b.dataset.name === decodeURIComponent(m[2])) : buttons[0];
  if (wanted) wanted.click();
}

main();
