// The explorer's page: inputs, requests to the local server, and the plots, drawn here on canvases.
// The server answers with the library's numbers (JSON); nothing is computed here but pixels.
"use strict";

const DIMS = ["eps", "L", "K", "A", "N"];
const $ = (id) => document.getElementById(id);

// What tests and the benchmark read: each change's time from the input to the drawn answer.
const probe = window.explore = { ready: false, changes: [], pendingAnswers: 0, last: {} };

let meta = null;
let form = {};
const kinds = ["point", "map", "line", "export"];
const net = {};  // per kind: seq sent, inflight, wanted change, last change drawn
for (const k of kinds) net[k] = { seq: 0, inflight: false, want: 0, sent: 0, drawnSeq: 0 };
let changeId = 0;
// This page's name: the server orders each page's requests by their own count.
const client = Date.now().toString(36) + Math.random().toString(36).slice(2);
// Nothing asked and unanswered, nothing in the background.
probe.idle = () => kinds.every((k) => !net[k].inflight && net[k].want <= net[k].sent) &&
  Object.keys(busy).length === 0;
const changes = {};  // id -> {t0, kinds: Set}
const errors = {};
const busy = {};
let lastMapKey = null;
let lastPoint = null;
let mapImage = null;  // the map's pixels, built once per map answer

// ---------------------------------------------------------------------------------------------
// numbers as people type them: 0.5, 1e-3, 1/30
function parseNumber(text) {
  text = String(text).trim();
  if (text === "") return NaN;
  const n = Number(text);
  if (!Number.isNaN(n)) return n;
  const parts = text.split("/");
  if (parts.length === 2) {
    const a = Number(parts[0]), b = Number(parts[1]);
    if (!Number.isNaN(a) && !Number.isNaN(b) && b !== 0) return a / b;
  }
  return NaN;
}
const fmt = (x, p = 6) => (x === null || x === undefined) ? "—" :
  (x === 0 ? "0" : (Math.abs(x) >= 1e-3 && Math.abs(x) < 1e6 ? String(Number(x.toPrecision(p))) : x.toExponential(p - 1)));

// ---------------------------------------------------------------------------------------------
// inputs
function sliderRow(name, label, parent) {
  const s = meta.sliders[name];
  const row = document.createElement("div");
  row.className = "row";
  row.id = "row-" + name;
  row.innerHTML = `<label for="in-${name}" title="">${label}</label>` +
    `<input id="in-${name}" class="num" type="text" spellcheck="false">` +
    `<input id="sl-${name}" type="range">`;
  parent.appendChild(row);
  const sl = $("sl-" + name);
  const lo = s.log ? Math.log10(s.lo) : s.lo, hi = s.log ? Math.log10(s.hi) : s.hi;
  sl.min = lo; sl.max = hi; sl.step = (hi - lo) / 600;
  $("in-" + name).value = form[name];
  placeSlider(name);
  sl.addEventListener("input", () => {
    const v = Number(sl.value);
    const x = s.log ? Math.pow(10, v) : v;
    form[name] = String(Number(x.toPrecision(5)));
    $("in-" + name).value = form[name];
    changed(name);
  });
  $("in-" + name).addEventListener("change", () => {
    form[name] = $("in-" + name).value;
    placeSlider(name);
    changed(name);
  });
}

function placeSlider(name) {
  const s = meta.sliders[name];
  const x = parseNumber(form[name]);
  if (!Number.isFinite(x) || (s.log && x <= 0)) return;
  $("sl-" + name).value = s.log ? Math.log10(x) : x;
}

function textRow(name, parent) {
  const row = document.createElement("div");
  row.className = "row";
  row.innerHTML = `<label for="in-${name}">${name}</label><input id="in-${name}" class="num" type="text" spellcheck="false">`;
  parent.appendChild(row);
  $("in-" + name).value = form[name];
  $("in-" + name).addEventListener("change", () => { form[name] = $("in-" + name).value; changed(name); });
}

function buildInputs() {
  const params = $("params");
  const describe = {};
  for (const p of meta.parameters) describe[p.name] = p;
  for (const d of DIMS) {
    const alt = meta.alternatives[d];
    if (alt) {
      const row = document.createElement("div");
      row.className = "row";
      row.innerHTML = `<select id="from-${d}" class="from"><option value="${d}">${d}</option>` +
        `<option value="${alt.name}">${alt.name} with ${alt.needs} (${d} from them)</option></select>`;
      params.appendChild(row);
      $("from-" + d).value = form[d + "_from"];
      $("from-" + d).addEventListener("change", () => {
        form[d + "_from"] = $("from-" + d).value;
        showAlternatives();
        changed(d);
      });
      sliderRow(alt.name, alt.name, params);
      $("row-" + alt.name).title = `${alt.sentence}, in ${alt.interval}`;
    }
    sliderRow(d, d, params);
    $("row-" + d).title = `${describe[d].sentence}, in ${describe[d].interval}`;
  }
  for (const m of meta.material) textRow(m.name, $("material"));
  $("in-material").checked = !!form.material;
  $("in-material").addEventListener("change", () => { form.material = $("in-material").checked; changed("material"); });
  $("in-rtol").value = form.rtol;
  $("in-rtol").addEventListener("change", () => { form.rtol = $("in-rtol").value; changed("rtol"); });
  showAlternatives();
  // the line's choices
  for (const d of DIMS) $("line-x").add(new Option(d, d));
  for (const o of meta.outputs) $("line-y").add(new Option(o.name, o.name));
  $("line-x").value = form.line_x; $("line-y").value = form.line_y;
  $("line-x").addEventListener("change", () => { form.line_x = $("line-x").value; changed("line"); });
  $("line-y").addEventListener("change", () => { form.line_y = $("line-y").value; changed("line"); });
  $("export").addEventListener("click", () => { $("export-result").textContent = "writing…"; ask(["export"]); });
  $("map").addEventListener("click", mapClick);
}

function showAlternatives() {
  for (const d of ["eps", "N"]) {
    const alt = meta.alternatives[d].name;
    const useAlt = form[d + "_from"] === alt;
    $("row-" + d).classList.toggle("hidden", useAlt);
    $("row-" + alt).classList.toggle("hidden", !useAlt);
  }
}

function mapKey() {
  return JSON.stringify([form.eps_from, form.eps, form.W, form.d_p, form.L]);
}

// One change of the inputs: ask for what it changes.
function changed(what) {
  // A move of the line's own parameter leaves the line as it is: only its marker moves, drawn
  // with the point's answer.
  const want = what === "line" ? ["line"] : (what === form.line_x ? ["point"] : ["point", "line"]);
  if (what !== "line" && mapKey() !== lastMapKey) want.push("map");
  ask(want);
}

// ---------------------------------------------------------------------------------------------
// requests: one in flight per kind; a change made meanwhile is sent when it returns
function ask(wantKinds) {
  const id = ++changeId;
  changes[id] = { t0: performance.now(), kinds: new Set(wantKinds), pending: false };
  for (const k of wantKinds) { net[k].want = id; pump(k); }
}

function pump(kind) {
  const n = net[kind];
  if (n.inflight || n.want <= n.sent) return;
  n.inflight = true;
  n.sent = n.want;
  const seq = ++n.seq, change = n.want;
  if (kind === "map") lastMapKey = mapKey();
  fetch("/api/" + kind, { method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ client, seq, form }) })
    .then((r) => r.json())
    .then((a) => answered(kind, seq, change, a))
    .catch((e) => answered(kind, seq, change, { error: "the server does not answer (" + e + ")" }));
}

function settle(kind, change, pending) {
  for (const [id, c] of Object.entries(changes)) {
    if (Number(id) <= change && c.kinds.has(kind)) {
      c.kinds.delete(kind);
      c.pending = c.pending || pending;
      if (c.kinds.size === 0) {
        probe.changes.push({ ms: performance.now() - c.t0, pending: c.pending });
        delete changes[id];
      }
    }
  }
}

function answered(kind, seq, change, a) {
  const n = net[kind];
  n.inflight = false;
  if (a.pending) {
    busy[kind] = a.note || "working in the background";
    showBusy();
    settle(kind, change, true);
    poll(kind, seq, change, a.pending);
  } else {
    apply(kind, seq, a);
    settle(kind, change, false);
  }
  pump(kind);
}

function poll(kind, seq, change, job) {
  fetch("/api/job/" + job).then((r) => r.json()).then((a) => {
    if (a.pending) { setTimeout(() => poll(kind, seq, change, job), 60); return; }
    probe.pendingAnswers += 1;
    apply(kind, seq, a);
  }).catch(() => setTimeout(() => poll(kind, seq, change, job), 500));
}

function apply(kind, seq, a) {
  const n = net[kind];
  if (a.stale || seq < n.drawnSeq) return;  // overtaken by a newer answer
  n.drawnSeq = seq;
  if (seq === n.seq) { delete busy[kind]; showBusy(); }
  if (a.error) { errors[kind] = a.error; showError(); if (kind === "export") $("export-result").textContent = ""; return; }
  delete errors[kind];
  showError();
  probe.last[kind] = a;
  if (kind === "point") drawPoint(a);
  else if (kind === "map") { probe.map = a; mapImage = null; drawMap(); }
  else if (kind === "line") drawLine(a);
  else if (kind === "export") $("export-result").textContent = "written: " + a.written.join(", ");
}

function showError() {
  const first = ["point", "map", "line", "export"].map((k) => errors[k]).find((e) => e);
  $("error").textContent = first || "";
}
function showBusy() {
  $("busy").textContent = [...new Set(Object.values(busy))].join("; ");
}

// ---------------------------------------------------------------------------------------------
// plots
function niceTicks(lo, hi, n = 5) {
  const span = hi - lo;
  if (!(span > 0)) return [lo];
  const raw = span / n, mag = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((s) => span / s <= n) || 10 * mag;
  const out = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9; t += step) out.push(Math.abs(t) < step * 1e-9 ? 0 : t);
  return out;
}

function plotLines(canvas, o) {
  const ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 54, R = 10, T = 20, B = 34;
  ctx.clearRect(0, 0, W, H);
  const tx = o.xlog ? Math.log10 : (v) => v;
  let xs = o.x.filter((v) => v !== null && (!o.xlog || v > 0)).map(tx);
  let ys = [];
  for (const s of o.series) for (const v of s.y) if (v !== null && Number.isFinite(v)) ys.push(v);
  for (const m of (o.marks || [])) if (m.y !== null && Number.isFinite(m.y)) ys.push(m.y);
  let x0 = Math.min(...xs), x1 = Math.max(...xs);
  if (o.xlim) { x0 = tx(o.xlim[0]); x1 = tx(o.xlim[1]); }
  let y0 = ys.length ? Math.min(...ys) : 0, y1 = ys.length ? Math.max(...ys) : 1;
  if (y1 - y0 < 1e-12 * Math.max(1, Math.abs(y1))) { y0 -= 0.5 * Math.max(1e-12, Math.abs(y0)) || 0.5; y1 += 0.5 * Math.max(1e-12, Math.abs(y1)) || 0.5; }
  const pad = 0.05 * (y1 - y0); y0 -= pad; y1 += pad;
  const px = (v) => L + (tx(v) - x0) / (x1 - x0) * (W - L - R);
  const py = (v) => T + (y1 - v) / (y1 - y0) * (H - T - B);
  ctx.font = "11px system-ui, sans-serif";
  ctx.strokeStyle = "#ccc"; ctx.fillStyle = "#333"; ctx.lineWidth = 1;
  ctx.strokeRect(L, T, W - L - R, H - T - B);
  // ticks
  ctx.textAlign = "center"; ctx.textBaseline = "top";
  const xt = o.xlog ? decadeTicks(x0, x1) : niceTicks(x0, x1);
  for (const t of xt) {
    const X = L + (t - x0) / (x1 - x0) * (W - L - R);
    ctx.beginPath(); ctx.moveTo(X, H - B); ctx.lineTo(X, H - B + 4); ctx.stroke();
    ctx.fillText(o.xlog ? "1e" + t : fmt(t, 3), X, H - B + 5);
  }
  ctx.textAlign = "right"; ctx.textBaseline = "middle";
  for (const t of niceTicks(y0, y1)) {
    const Y = py(t);
    ctx.beginPath(); ctx.moveTo(L - 4, Y); ctx.lineTo(L, Y); ctx.stroke();
    ctx.fillText(fmt(t, 3), L - 6, Y);
  }
  ctx.textAlign = "center"; ctx.textBaseline = "bottom";
  ctx.fillText(o.xlabel || "", L + (W - L - R) / 2, H - 1);
  ctx.textAlign = "left"; ctx.textBaseline = "top";
  ctx.fillText(o.title || "", L + 2, 3);
  ctx.save();
  ctx.beginPath(); ctx.rect(L, T, W - L - R, H - T - B); ctx.clip();
  for (const v of (o.vlines || [])) {
    if (v.x === null || !Number.isFinite(v.x)) continue;
    ctx.strokeStyle = v.color || "#666"; ctx.setLineDash([5, 4]); ctx.lineWidth = 1.2;
    ctx.beginPath(); ctx.moveTo(px(v.x), T); ctx.lineTo(px(v.x), H - B); ctx.stroke();
  }
  for (const s of o.series) {
    ctx.strokeStyle = s.color; ctx.setLineDash(s.dash || []); ctx.lineWidth = 1.8;
    ctx.beginPath();
    let pen = false;
    for (let i = 0; i < o.x.length; i++) {
      const y = s.y[i];
      if (y === null || !Number.isFinite(y)) { pen = false; continue; }
      if (pen) ctx.lineTo(px(o.x[i]), py(y)); else ctx.moveTo(px(o.x[i]), py(y));
      pen = true;
    }
    ctx.stroke();
  }
  ctx.setLineDash([]);
  for (const m of (o.marks || [])) {
    if (m.y === null || !Number.isFinite(m.y)) continue;
    ctx.fillStyle = m.color || "#000";
    ctx.beginPath(); ctx.arc(px(m.x), py(m.y), 4, 0, 2 * Math.PI); ctx.fill();
  }
  ctx.restore();
  // legend
  let lx = W - R - 4;
  ctx.textAlign = "right"; ctx.textBaseline = "top";
  for (const s of o.series.slice().reverse()) {
    if (!s.label) continue;
    ctx.fillStyle = s.color; ctx.fillText(s.label, lx, 3);
    lx -= ctx.measureText(s.label).width + 10;
  }
}

function decadeTicks(lo, hi) {
  const out = [];
  const step = Math.max(1, Math.ceil((hi - lo) / 6));
  for (let t = Math.ceil(lo); t <= Math.floor(hi); t += step) out.push(t);
  return out;
}

function statusOf(code) {
  return meta.statuses.find((s) => s.code === code) || meta.undecided;
}

function drawPoint(a) {
  lastPoint = a;
  probe.point = a;
  const s = statusOf(a.code);
  $("status").textContent = a.status;
  $("status").style.background = s.color;
  $("status-message").textContent = a.message + "  (eps L = " + fmt(a.eta) + ")";
  const p = a.profile;
  const xiP = a.outputs.xi_p;
  const blank = { x: [0, 1], series: [], xlim: [0, 1] };
  const common = (title, series) => p ? { x: p.xi, series, xlim: [0, 1], xlabel: "ξ = x/W", title,
    vlines: [{ x: xiP, color: "#555" }] } : { ...blank, title: title + " (no solution)" };
  plotLines($("prof-u"), common("u/u(0)", p ? [{ y: p.u_over_u0, color: "#1f77b4" }] : []));
  plotLines($("prof-omega"), common("ω̂ = ω/ω_w", p ? [{ y: p.omega_hat, color: "#ff7f0e" }] : []));
  plotLines($("prof-sigma"), common("shear stresses / ν", p ? [
    { y: p.sigma_xy, color: "#2ca02c", label: "σ_xy" },
    { y: p.sigma_yx, color: "#d62728", dash: [6, 3], label: "σ_yx" }] : []));
  plotLines($("prof-m"), common("m / ν", p ? [{ y: p.m, color: "#9467bd" }] : []));
  // outputs with their sensitivities
  $("outputs").tHead.innerHTML = "<tr><th>output</th><th>value</th><th>units</th>" +
    DIMS.map((d) => `<th>∂/∂${d}</th>`).join("") + "</tr>";
  const rows = [];
  for (const o of meta.outputs) {
    if (!(o.name in a.outputs)) continue;
    const v = a.outputs[o.name];
    const sens = a.sensitivities[o.name] || {};
    rows.push(`<tr title="${o.description}"><td>${o.name}</td>` +
      `<td id="out-${o.name}" data-value="${v === null ? "" : String(v)}">${fmt(v)}</td>` +
      `<td>${o.units === "1" ? "" : o.units}</td>` +
      DIMS.map((d) => `<td>${fmt(sens[d] === undefined ? null : sens[d], 3)}</td>`).join("") + "</tr>");
  }
  $("outputs").tBodies[0].innerHTML = rows.join("");
  drawMap();
  if (probe.last.line) drawLine(probe.last.line);
}

function drawMap() {
  const a = probe.map;
  const canvas = $("map"), ctx = canvas.getContext("2d");
  const W = canvas.width, H = canvas.height, L = 44, R = 8, T = 8, B = 34;
  ctx.clearRect(0, 0, W, H);
  if (!a) return;
  const nA = a.A.length, nN = a.N.length;
  if (!mapImage) {
    const img = new ImageData(nA, nN);
    const colors = {};
    for (const s of meta.statuses.concat([meta.undecided])) {
      const h = s.color.replace("#", "");
      colors[s.code] = [parseInt(h.slice(0, 2), 16), parseInt(h.slice(2, 4), 16), parseInt(h.slice(4, 6), 16)];
    }
    for (let j = 0; j < nN; j++) {
      const row = a.codes[nN - 1 - j];  // the image's first row is the largest N
      for (let i = 0; i < nA; i++) {
        const c = colors[row[i]] || [255, 255, 255], k = 4 * (j * nA + i);
        img.data[k] = c[0]; img.data[k + 1] = c[1]; img.data[k + 2] = c[2]; img.data[k + 3] = 255;
      }
    }
    mapImage = document.createElement("canvas");
    mapImage.width = nA; mapImage.height = nN;
    mapImage.getContext("2d").putImageData(img, 0, 0);
  }
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(mapImage, L, T, W - L - R, H - T - B);
  const [a0, a1, n0, n1] = [a.A[0], a.A[nA - 1], a.N[0], a.N[nN - 1]];
  const px = (v) => L + (v - a0) / (a1 - a0) * (W - L - R);
  const py = (v) => T + (n1 - v) / (n1 - n0) * (H - T - B);
  ctx.font = "11px system-ui, sans-serif"; ctx.fillStyle = "#333"; ctx.strokeStyle = "#333";
  ctx.textAlign = "center"; ctx.textBaseline = "top";
  for (const t of niceTicks(a0, a1)) { ctx.fillText(fmt(t, 3), px(t), H - B + 4); }
  ctx.fillText("A", L + (W - L - R) / 2, H - 14);
  ctx.textAlign = "right"; ctx.textBaseline = "middle";
  for (const t of niceTicks(n0, n1)) { ctx.fillText(fmt(t, 3), L - 4, py(t)); }
  ctx.save(); ctx.translate(10, T + (H - T - B) / 2); ctx.rotate(-Math.PI / 2);
  ctx.textAlign = "center"; ctx.fillText("N", 0, 0); ctx.restore();
  if (lastPoint) {
    const X = px(lastPoint.point.A), Y = py(lastPoint.point.N);
    ctx.lineWidth = 2; ctx.strokeStyle = "#000";
    ctx.beginPath(); ctx.arc(X, Y, 6, 0, 2 * Math.PI); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(X - 9, Y); ctx.lineTo(X + 9, Y); ctx.moveTo(X, Y - 9); ctx.lineTo(X, Y + 9); ctx.stroke();
  }
  const present = new Set(a.codes.flat());
  $("map-legend").innerHTML = meta.statuses.concat([meta.undecided]).filter((s) => present.has(s.code))
    .map((s) => `<span title="${s.message}"><i style="background:${s.color}"></i>${s.name || "undecided"}</span>`).join("") +
    `<span class="small">${a.atlas} atlas, eps L = ${fmt(a.eta)}</span>`;
}

function mapClick(ev) {
  const a = probe.map;
  if (!a) return;
  const canvas = $("map"), r = canvas.getBoundingClientRect();
  const x = (ev.clientX - r.left) * canvas.width / r.width, y = (ev.clientY - r.top) * canvas.height / r.height;
  const W = canvas.width, H = canvas.height, L = 44, R = 8, T = 8, B = 34;
  const nA = a.A.length, nN = a.N.length;
  const fa = (x - L) / (W - L - R), fn = (H - B - y) / (H - T - B);
  if (fa < 0 || fa > 1 || fn < 0 || fn > 1) return;
  const A = a.A[0] + fa * (a.A[nA - 1] - a.A[0]), N = a.N[0] + fn * (a.N[nN - 1] - a.N[0]);
  form.A = String(Number(A.toPrecision(4)));
  form.N = String(Number(N.toPrecision(4)));
  form.N_from = "N";
  $("from-N").value = "N";
  showAlternatives();
  for (const d of ["A", "N"]) { $("in-" + d).value = form[d]; placeSlider(d); }
  changed("A");
}

function drawLine(a) {
  const out = meta.outputs.find((o) => o.name === a.y_name);
  // the marker sits at the point shown (its own answer), on this line if the other
  // parameters are the line's
  const others = lastPoint && DIMS.every((d) => d === a.x_name || lastPoint.point[d] === a.point[d]);
  const at = others ? lastPoint.point[a.x_name] : a.at;
  const here = others ? lastPoint.outputs[a.y_name] : null;
  const i = a.x.indexOf(at);
  plotLines($("line"), {
    x: a.x, xlog: a.log, xlabel: a.x_name, title: `${a.y_name}${out && out.units !== "1" ? " (" + out.units + ")" : ""} against ${a.x_name}`,
    series: [{ y: a.y, color: "#1f77b4" }],
    vlines: [{ x: at, color: "#999" }],
    marks: [{ x: at, y: here !== null && here !== undefined ? here : (i >= 0 ? a.y[i] : null), color: "#d62728" }],
  });
}

// ---------------------------------------------------------------------------------------------
fetch("/api/meta").then((r) => r.json()).then((m) => {
  meta = m;
  form = Object.assign({}, m.defaults);
  buildInputs();
  probe.ready = true;
  ask(["point", "map", "line"]);
}).catch((e) => { $("error").textContent = "cannot reach the explorer's server: " + e; });
