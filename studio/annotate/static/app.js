// studio annotate: the page. Plain JS, no build step, nothing loaded from outside 127.0.0.1.
"use strict";

const $ = (id) => document.getElementById(id);
const CLIENT = "tab-" + Math.random().toString(36).slice(2, 10);
const S = {
  meta: null, frames: [], idx: 0, data: null, rev: 0, sel: null, addMode: false,
  flagged: new Set(), reviewed: new Set(), scale: 40, busy: 0, loadSeq: 0, abort: null,
  drag: null, hover: null, follow: true, lastRerunFrame: null, view: [0, 0], fitted: false,
};

// ------------------------------------------------------------------ helpers
function idColor(id, alpha = 1) {
  const h = (id * 137.508) % 360;
  return `hsla(${h}, 75%, 60%, ${alpha})`;
}
async function api(path, opts = {}) {
  const res = await fetch(path, opts);
  let body = null;
  try { body = await res.json(); } catch (e) { body = { error: `HTTP ${res.status}` }; }
  if (!res.ok) { const err = new Error(body.error || `HTTP ${res.status}`); err.status = res.status; err.body = body; throw err; }
  return body;
}
function status(text, cls = "") { const el = $("status"); el.textContent = text; el.className = "status " + cls; }
function banner(text) { const b = $("banner"); b.textContent = text || ""; b.hidden = !text; }
const frameNo = () => S.frames[S.idx];
const fmt = (v, d = 3) => (v === null || v === undefined ? "–" : typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toFixed(d)) : String(v));

// ------------------------------------------------------------------ loading
async function loadMeta() {
  S.meta = await api("/api/meta");
  S.frames = S.meta.frames;
  S.rev = S.meta.rev;
  S.reviewed = new Set(S.meta.reviewed);
  S.doubts = new Set(S.meta.doubts || []);
  $("run").textContent = S.meta.run;
  $("nframes").textContent = `/ ${S.frames[S.frames.length - 1]}`;
  $("frameno").max = S.frames[S.frames.length - 1];
  if (!S.meta.has_camera) { $("pano-wrap").hidden = true; }
  const note = $("media-note");
  note.hidden = !S.meta.media_problem;
  note.textContent = S.meta.media_problem ? `No sensor data (${S.meta.media_problem}): scans and panoramas are not ` +
    "shown (but for panoramas cached earlier); the labels can still be corrected in the bird's-eye view." : "";
  const rr = S.meta.rerun;
  $("follow-wrap").hidden = !(rr && rr.can_follow);
  $("rerun-state").hidden = !(rr && rr.connected);
  if (rr && rr.connected) $("rerun-state").title = `${rr.url} · recording ${rr.recording_id}\n${rr.note || ""}`;
}

async function loadFrame(idx, { keepSel = true } = {}) {
  idx = Math.max(0, Math.min(S.frames.length - 1, idx));
  const changed = idx !== S.idx;
  S.idx = idx;
  const n = frameNo();
  $("frameno").value = n;
  location.hash = "#" + n;
  if (S.abort) S.abort.abort();
  S.abort = new AbortController();
  const seq = ++S.loadSeq;
  if (S.meta.has_camera) {
    const img = $("pano");
    const src = `/api/frame/${n}/panorama.jpg`;
    if (!img.src.endsWith(src)) img.src = src;
    for (const k of [1, 2]) if (S.idx + k < S.frames.length) new Image().src = `/api/frame/${S.frames[S.idx + k]}/panorama.jpg`;
  }
  let data;
  try { data = await api(`/api/frame/${n}`, { signal: S.abort.signal }); }
  catch (e) { if (e.name === "AbortError") return; status(e.message, "bad"); return; }
  if (seq !== S.loadSeq) return;
  S.data = data;
  S.rev = Math.max(S.rev, data.rev);
  if (!keepSel || changed) { if (S.sel !== null && !data.gt.some((p) => p.id === S.sel)) S.sel = keepSel ? S.sel : null; }
  if (data.reviewed) S.reviewed.add(n); else S.reviewed.delete(n);
  const doubts = data.doubts || [], dn = $("doubt-note");
  const how = (q) => (q.doubt === undefined ? "" : ` (doubt ${q.doubt.toFixed(2)})`);
  dn.textContent = doubts.length ? "to check: " + doubts.map((q) => q.note + how(q)).join(" · ") : "";
  dn.hidden = !doubts.length;
  render();
  loadHistory();
  if (S.meta.rerun && S.meta.rerun.can_follow && $("follow").checked && changed) {
    api("/api/rerun/time", { method: "POST", body: JSON.stringify({ frame: n }) }).catch(() => {});
    S.lastRerunFrame = n;
  }
}

async function loadHistory() {
  const n = frameNo();
  try {
    const h = await api(`/api/history?frame=${n}&limit=30`);
    const ol = $("history");
    ol.innerHTML = "";
    for (const e of h.history) {
      const li = document.createElement("li");
      const t = e.time ? new Date(e.time / 1e6).toLocaleTimeString() : "";
      li.textContent = `#${e.seq} ${e.author || "?"}${e.client && e.client === CLIENT ? " (this tab)" : ""}: ${describeOp(e.op)} ${t}`;
      if (e.undone) li.className = "undone";
      ol.appendChild(li);
    }
    if (!h.history.length) ol.innerHTML = '<li class="dim">no corrections yet</li>';
  } catch (e) { /* history is informative only */ }
}

function describeOp(op) {
  if (!op) return "?";
  const o = op.op;
  if (o === "move") return `moved ${op.id} to (${fmt(op.x, 2)}, ${fmt(op.y, 2)})${op.propagate ? " + forward" : ""}`;
  if (o === "add") return `added ${op.id}`;
  if (o === "delete") return `deleted ${op.id}`;
  if (o === "set_id") return `ID ${op.id} → ${op.new_id} (${op.start}–${op.end})`;
  if (o === "merge") return `merged ${op.ids.join("+")} → ${op.into} (${op.start}–${op.end})`;
  if (o === "swap") return `swapped ${op.ids.join(" ⇄ ")} (${op.start}–${op.end})`;
  if (o === "split") return `split ${op.id} at ${op.frame} → ${op.new_id}`;
  if (o === "flag") return `flagged ${op.id}${op.occluded ? " occluded" : ""}${op.uncertain ? " uncertain" : ""}`;
  if (o === "review") return `${op.reviewed === false ? "unreviewed" : "reviewed"} ${op.start}–${op.end}`;
  if (o === "undo" || o === "redo") return `${o}`;
  return JSON.stringify(op);
}

async function loadMetrics(wait = false) {
  try {
    const m = await api(`/api/metrics?wait=${wait ? 15 : 0}`);
    S.metricsRev = m.metrics_rev;
    if (S.data && !m.stale && S.data.flags_rev !== m.metrics_rev && !S.drag) loadFrame(S.idx);
    S.flagged = new Set(m.flagged || []);
    if (m.reviewed) S.reviewed = new Set(m.reviewed);
    $("metrics-scope").textContent = `(${m.reviewed_frames} reviewed · ${m.flagged_frames} flagged)`;
    const tb = $("metrics").querySelector("tbody");
    tb.innerHTML = "";
    const x = m.metrics;
    const r3 = (v) => (typeof v === "number" ? v.toFixed(3) : "–");
    const rows = x ? [["precision", r3(x.precision)], ["recall", r3(x.recall)], ["F1", r3(x.f1)], ["MOTA", r3(x.mota)],
      ["IDF1", r3(x.idf1)], ["HOTA", r3(x.hota)], ["ID switches", x.id_switches], ["TP / FP / FN", `${x.tp} / ${x.fp} / ${x.fn}`],
      ["frames", x.num_frames]] : [["", m.metrics_error ? `evaluation failed: ${m.metrics_error}` : "mark frames reviewed (R) to measure the auto labels on them"]];
    for (const [k, v] of rows) {
      const tr = document.createElement("tr");
      tr.innerHTML = `<td>${k}</td><td data-key="${k}">${fmt(v)}</td>`;
      tb.appendChild(tr);
    }
    drawTimeline();
  } catch (e) { /* shown on next action */ }
}

// ------------------------------------------------------------------ edits
async function send(op) {
  S.busy++;
  status("saving…", "busy");
  try {
    const r = await api("/api/op", { method: "POST", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ op, base_rev: S.rev, client: CLIENT }) });
    S.rev = r.rev;
    banner("");
    status(`saved · rev ${r.rev}`, "ok");
    await loadFrame(S.idx);
    loadMetrics(true);
    return r;
  } catch (e) {
    if (e.status === 409) {
      banner(`Conflict: ${e.message} — another tab or user changed this since you loaded it. ` +
        "The frame was reloaded; nothing was overwritten. Check it and redo your edit if still needed.");
      status("conflict", "bad");
      await refreshAll();
    } else {
      status(e.message, "bad");
      banner(`Not applied: ${e.message}`);
      await loadFrame(S.idx);
    }
    return null;
  } finally { S.busy--; }
}

async function undoRedo(kind) {
  try {
    const r = await api(`/api/${kind}`, { method: "POST", body: JSON.stringify({ base_rev: S.rev, client: CLIENT }) });
    const fr = r.frames.length ? ` frame${r.frames.length > 1 ? "s" : ""} ${r.frames[0]}${r.frames.length > 1 ? "–" + r.frames[r.frames.length - 1] : ""}` : "";
    S.rev = r.rev; banner(""); status(`${kind} of #${r.op.target}${fr} · rev ${r.rev}`, "ok");
  } catch (e) {
    if (e.status === 409) banner(`Conflict: ${e.message}`); else status(e.message, "bad");
  }
  await refreshAll();
}

async function refreshAll() { await loadMeta(); await loadFrame(S.idx); loadMetrics(true); }

function scopeRange() {
  const n = frameNo(), first = S.frames[0], last = S.frames[S.frames.length - 1];
  const s = $("scope").value;
  return s === "all" ? [first, last] : s === "one" ? [n, n] : [n, last];
}
function newId() {
  let m = -1;
  for (const p of (S.data ? S.data.gt : [])) m = Math.max(m, p.id);
  for (const p of (S.data ? S.data.auto : [])) m = Math.max(m, p.id);
  return m + 1;
}
function readId() {
  const v = $("new-id").value.trim();
  if (v === "" || !/^\d+$/.test(v)) { status("type an ID (a non-negative integer) first", "bad"); $("new-id").focus(); return null; }
  return parseInt(v, 10);
}
const ops = {
  setId() { if (S.sel === null) return; const id = readId(); if (id === null) return; const [start, end] = scopeRange();
    send({ op: "set_id", id: S.sel, new_id: id, start, end }).then((r) => { if (r) { S.sel = id; render(); } }); },
  merge() { if (S.sel === null) return; const other = readId(); if (other === null) return; const [start, end] = scopeRange();
    send({ op: "merge", ids: [S.sel, other], into: S.sel, start, end }); },
  swap() {
    if (S.sel === null) return;
    let other = null;
    if ($("new-id").value.trim() === "") {  // at an encounter doubt: its other track
      const d = ((S.data && S.data.doubts) || []).find((q) => q.ids.length === 2 && q.ids.includes(S.sel));
      if (d) other = d.ids.find((i) => i !== S.sel);
    }
    if (other === null && (other = readId()) === null) return;
    const [start, end] = scopeRange();
    send({ op: "swap", ids: [S.sel, other], start, end });
  },
  split() { if (S.sel === null) return; const v = $("new-id").value.trim(); const op = { op: "split", id: S.sel, frame: frameNo() };
    if (/^\d+$/.test(v)) op.new_id = parseInt(v, 10); send(op); },
  del() { if (S.sel === null) return; const id = S.sel; S.sel = null; send({ op: "delete", frame: frameNo(), id }); },
  flag() { if (S.sel === null) return; send({ op: "flag", frame: frameNo(), id: S.sel, occluded: $("occluded").checked, uncertain: $("uncertain").checked }); },
  review(val) { const n = frameNo(); return send({ op: "review", start: n, end: n, reviewed: val }); },
};

async function jump(kind, dir = 1) {
  try {
    const r = await api(`/api/next?kind=${kind}&start=${frameNo()}&dir=${dir}`);
    const what = { flag: "flagged", unreviewed: "unreviewed", doubt: "unreviewed doubt", worst: "unreviewed doubt" }[kind];
    if (r.frame === null) { status(kind === "worst" ? "no unreviewed doubt frame" : `no ${dir > 0 ? "further" : "earlier"} ${what} frame`, ""); return; }
    await loadFrame(S.frames.indexOf(r.frame));
    if ((kind === "doubt" || kind === "worst") && S.data && S.data.frame === r.frame) {  // select the first track in doubt
      const first = S.data.doubts.reduce((a, q) => (q.doubt > a.doubt ? q : a), S.data.doubts[0] || { ids: [] });
      const ids = first.ids.filter((i) => S.data.gt.some((p) => p.id === i));
      if (ids.length) { S.sel = ids[0]; render(); }
    }
    status(`${kind === "worst" ? "most doubtful" : what} frame ${r.frame} · ${r.remaining} ${what} frames in all`, "");
  } catch (e) { status(e.message, "bad"); }
}

// ------------------------------------------------------------------ drawing
function render() {
  renderPano(); renderBev(); renderSide(); drawTimeline();
  const rv = $("reviewed");
  rv.classList.toggle("on", !!(S.data && S.data.reviewed));
  $("add-mode").classList.toggle("on", S.addMode);
}

function panoCtx() {
  const c = $("pano-overlay"), img = $("pano");
  const w = img.clientWidth, h = img.clientHeight || w / 2;
  const dpr = window.devicePixelRatio || 1;
  if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) { c.width = Math.round(w * dpr); c.height = Math.round(h * dpr); }
  const ctx = c.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.clearRect(0, 0, w, h);
  const size = S.meta.image_size || [w, h];
  return { ctx, k: w / size[0], w, h, W: size[0] };
}

function renderPano() {
  if (!S.meta || !S.meta.has_camera || !S.data) return;
  const { ctx, k, w, W } = panoCtx();
  const d = S.data;
  if (d.scan && d.scan.uv) {
    ctx.fillStyle = "rgba(0, 255, 200, 0.8)";
    for (const uv of d.scan.uv) if (uv) ctx.fillRect(uv[0] * k - 1, uv[1] * k - 1, 2, 2);
  }
  const boxes = (people, dashed) => {
    for (const p of people) {
      if (!p.box) continue;
      const [u1, v1, u2, v2] = p.box;
      ctx.setLineDash(dashed ? [5, 4] : []);
      ctx.strokeStyle = idColor(p.id, dashed ? 0.7 : 1);
      ctx.lineWidth = p.id === S.sel ? 3 : 1.5;
      const pieces = u2 > W ? [[u1, W], [0, u2 - W]] : [[u1, u2]];
      for (const [a, b] of pieces) ctx.strokeRect(a * k, v1 * k, (b - a) * k, (v2 - v1) * k);
    }
    ctx.setLineDash([]);
  };
  boxes(d.auto, true);
  ctx.font = "bold 12px system-ui";
  for (const p of d.gt) {
    if (!p.pano) continue;
    const [u, vTop, vFoot] = p.pano;
    ctx.strokeStyle = idColor(p.id); ctx.lineWidth = p.id === S.sel ? 5 : 3;
    ctx.beginPath(); ctx.moveTo(u * k, vTop * k); ctx.lineTo(u * k, vFoot * k); ctx.stroke();
    ctx.fillStyle = "rgba(0,0,0,.6)"; ctx.fillRect(u * k + 4, vTop * k - 14, 28, 14);
    ctx.fillStyle = idColor(p.id); ctx.fillText(String(p.id), u * k + 6, vTop * k - 3);
  }
  if (d.media_error) { ctx.fillStyle = "#ff8080"; ctx.fillText(d.media_error, 8, 16); }
  void w;
}

function bevGeom() {
  const c = $("bev");
  const w = c.clientWidth, h = c.clientHeight, dpr = window.devicePixelRatio || 1;
  if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) { c.width = Math.round(w * dpr); c.height = Math.round(h * dpr); }
  const ctx = c.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  const s = S.scale, [vx, vy] = S.view;
  const cx = w / 2 + vy * s, cy = h / 2 + vx * s; // screen position of the robot (base frame origin)
  // base frame: x forward (up on screen), y left (left on screen)
  return { ctx, w, h, toScreen: (x, y) => [cx - y * s, cy - x * s], toWorld: (sx, sy) => [(cy - sy) / s, (cx - sx) / s], s };
}

// fit the bird's-eye view to the robot and the people (on the first frame, on "0", or when someone is off view)
function fitBev(force) {
  if (!S.data) return;
  const c = $("bev"), w = c.clientWidth, h = c.clientHeight;
  const pts = [[0, 0], ...S.data.gt.map((p) => [p.x, p.y]), ...S.data.auto.map((p) => [p.x, p.y])];
  if (!force && S.fitted) {
    const g = bevGeom();
    const off = pts.some(([x, y]) => { const [sx, sy] = g.toScreen(x, y); return sx < 10 || sy < 10 || sx > w - 10 || sy > h - 10; });
    if (!off) return;
  }
  const xs = pts.map((p) => p[0]), ys = pts.map((p) => p[1]);
  const x0 = Math.min(...xs) - 1.5, x1 = Math.max(...xs) + 1.5, y0 = Math.min(...ys) - 1.5, y1 = Math.max(...ys) + 1.5;
  S.scale = Math.max(8, Math.min(120, Math.min(w / (y1 - y0), h / (x1 - x0))));
  S.view = [(x0 + x1) / 2, (y0 + y1) / 2];
  S.fitted = true;
}

function renderBev() {
  if (!S.data) return;
  if (!S.drag) fitBev(false);
  const { ctx, w, h, toScreen } = bevGeom();
  const d = S.data;
  ctx.fillStyle = "#0f1115"; ctx.fillRect(0, 0, w, h);
  // grid every metre, stronger every 5 m
  const g = bevGeom(), [xTop, yLeft] = g.toWorld(0, 0), [xBot, yRight] = g.toWorld(w, h);
  ctx.lineWidth = 1;
  for (let m = Math.floor(yRight); m <= Math.ceil(yLeft); m++) {
    const [sx] = toScreen(0, m); ctx.strokeStyle = m % 5 === 0 ? "#283040" : "#1a1e27";
    ctx.beginPath(); ctx.moveTo(sx, 0); ctx.lineTo(sx, h); ctx.stroke();
  }
  for (let m = Math.floor(xBot); m <= Math.ceil(xTop); m++) {
    const [, sy] = toScreen(m, 0); ctx.strokeStyle = m % 5 === 0 ? "#283040" : "#1a1e27";
    ctx.beginPath(); ctx.moveTo(0, sy); ctx.lineTo(w, sy); ctx.stroke();
  }
  // robot
  const [rx, ry] = toScreen(0, 0);
  ctx.fillStyle = "#8b91a0"; ctx.beginPath(); ctx.moveTo(rx, ry - 12); ctx.lineTo(rx - 7, ry + 8); ctx.lineTo(rx + 7, ry + 8); ctx.closePath(); ctx.fill();
  // scan
  if (d.scan) {
    ctx.fillStyle = "rgba(0, 255, 200, 0.65)";
    for (const [x, y] of d.scan.xy) { const [sx, sy] = toScreen(x, y); ctx.fillRect(sx - 1, sy - 1, 2, 2); }
  }
  // trails
  for (const [id, pts] of Object.entries(d.trails || {})) {
    if (pts.length < 2) continue;
    ctx.strokeStyle = idColor(+id, 0.45); ctx.lineWidth = 2; ctx.beginPath();
    pts.forEach(([x, y], i) => { const [sx, sy] = toScreen(x, y); if (i) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy); });
    ctx.stroke();
  }
  const fp = new Set(d.flags.fp), fn = new Set(d.flags.fn);
  // auto labels: rings
  for (const p of d.auto) {
    const [sx, sy] = toScreen(p.x, p.y);
    ctx.strokeStyle = fp.has(p.id) ? "#ff5d5d" : idColor(p.id, 0.8); ctx.lineWidth = fp.has(p.id) ? 2.5 : 1.5;
    ctx.setLineDash([3, 3]); ctx.beginPath(); ctx.arc(sx, sy, 11, 0, 2 * Math.PI); ctx.stroke(); ctx.setLineDash([]);
  }
  // ground truth: filled discs with ids
  ctx.font = "bold 12px system-ui";
  for (const p of d.gt) {
    const drag = S.drag && S.drag.id === p.id && S.drag.moved ? S.drag : null;
    const [sx, sy] = drag ? [drag.sx, drag.sy] : toScreen(p.x, p.y);
    ctx.fillStyle = idColor(p.id, 0.9);
    ctx.beginPath(); ctx.arc(sx, sy, 7, 0, 2 * Math.PI); ctx.fill();
    if (p.id === S.sel) { ctx.strokeStyle = "#fff"; ctx.lineWidth = 2; ctx.beginPath(); ctx.arc(sx, sy, 10, 0, 2 * Math.PI); ctx.stroke(); }
    if (fn.has(p.id)) { ctx.strokeStyle = "#ff5d5d"; ctx.lineWidth = 2; ctx.beginPath(); ctx.moveTo(sx - 12, sy - 12); ctx.lineTo(sx - 6, sy - 6); ctx.moveTo(sx - 6, sy - 12); ctx.lineTo(sx - 12, sy - 6); ctx.stroke(); }
    const flags = (p.occluded ? "ᵒ" : "") + (p.uncertain ? "?" : "");
    ctx.fillStyle = "#fff"; ctx.fillText(String(p.id) + flags, sx + 9, sy - 7);
  }
  $("bev-scale").textContent = `grid 1 m · ${d.scan ? d.scan.xy.length + " scan points" : "no scan"}`;
}

function renderSide() {
  const d = S.data;
  if (!d) return;
  const p = d.gt.find((q) => q.id === S.sel);
  $("sel").hidden = !p; $("sel-none").hidden = !!p;
  if (p) {
    $("sel-id").innerHTML = `<span class="swatch" style="background:${idColor(p.id)}"></span>ID ${p.id}`;
    $("sel-src").textContent = `${p.source || ""} (${fmt(p.x, 2)}, ${fmt(p.y, 2)}) m`;
    $("sel-who").textContent = p.changed ? `changed: ${describeChange(p.changed)}` : "unchanged (auto label)";
    $("occluded").checked = !!p.occluded; $("uncertain").checked = !!p.uncertain;
  }
  const tb = $("people").querySelector("tbody");
  tb.innerHTML = "";
  for (const q of d.gt) {
    const tr = document.createElement("tr");
    if (q.id === S.sel) tr.className = "sel";
    tr.innerHTML = `<td><span class="swatch" style="background:${idColor(q.id)}"></span>${q.id}</td><td>${fmt(q.x, 2)}</td><td>${fmt(q.y, 2)}</td><td>${q.source || ""}</td><td class="dim">${q.changed ? describeChange(q.changed) : ""}</td>`;
    tr.onclick = () => { S.sel = q.id; render(); };
    tb.appendChild(tr);
  }
  $("people-count").textContent = `(${d.gt.length} ground truth · ${d.auto.length} auto)`;
}

function describeChange(c) {
  if (typeof c !== "object") return String(c);
  const parts = [];
  if (c.author) parts.push(c.author);
  if (c.how) parts.push(c.how);
  else if (c.op) parts.push(typeof c.op === "string" ? c.op : c.op.op);
  if (c.seq !== undefined) parts.push(`#${c.seq}`);
  return parts.join(" ");
}

function drawTimeline() {
  const c = $("timeline");
  const w = c.clientWidth, dpr = window.devicePixelRatio || 1;
  c.width = Math.round(w * dpr); c.height = Math.round(14 * dpr);
  const ctx = c.getContext("2d"); ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.fillStyle = "#101216"; ctx.fillRect(0, 0, w, 14);
  const n = S.frames.length;
  if (!n) return;
  const x = (i) => (i / n) * w, bw = Math.max(1, w / n);
  S.frames.forEach((f, i) => {
    if (S.reviewed.has(f)) { ctx.fillStyle = "#2f7d57"; ctx.fillRect(x(i), 0, bw, 7); }
    if (S.flagged.has(f)) { ctx.fillStyle = "#d04545"; ctx.fillRect(x(i), 7, bw, 7); }
    else if (S.doubts && S.doubts.has(f)) { ctx.fillStyle = "#d9a13b"; ctx.fillRect(x(i), 7, bw, 7); }
  });
  ctx.fillStyle = "#fff"; ctx.fillRect(x(S.idx), 0, Math.max(2, bw), 14);
}

// ------------------------------------------------------------------ input
function hitGt(sx, sy, toScreen) {
  let best = null, bd = 14;
  for (const p of S.data.gt) {
    const [px, py] = toScreen(p.x, p.y);
    const dd = Math.hypot(px - sx, py - sy);
    if (dd < bd) { bd = dd; best = p; }
  }
  return best;
}

function setupBev() {
  const c = $("bev");
  const pos = (e) => { const r = c.getBoundingClientRect(); return [e.clientX - r.left, e.clientY - r.top]; };
  c.addEventListener("mousedown", (e) => {
    if (!S.data || S.data.frame !== frameNo()) return; // the frame's people are still being fetched
    const [sx, sy] = pos(e);
    const { toScreen, toWorld } = bevGeom();
    const p = hitGt(sx, sy, toScreen);
    if (p) { S.sel = p.id; S.drag = { id: p.id, sx, sy, x0: sx, y0: sy, moved: false }; render(); return; }
    if (S.addMode) {
      const [x, y] = toWorld(sx, sy);
      const v = $("new-id").value.trim();
      const id = /^\d+$/.test(v) && !S.data.gt.some((q) => q.id === parseInt(v, 10)) ? parseInt(v, 10) : newId();
      S.sel = id;
      send({ op: "add", frame: frameNo(), id, x: +x.toFixed(3), y: +y.toFixed(3) });
      return;
    }
    S.sel = null; render();
  });
  window.addEventListener("mousemove", (e) => {
    if (!S.drag) return;
    const [sx, sy] = pos(e);
    if (Math.hypot(sx - S.drag.x0, sy - S.drag.y0) > 3) S.drag.moved = true;
    S.drag.sx = sx; S.drag.sy = sy;
    renderBev();
  });
  window.addEventListener("mouseup", () => {
    const d = S.drag; S.drag = null;
    if (!d || !d.moved) return;
    const [x, y] = bevGeom().toWorld(d.sx, d.sy);
    send({ op: "move", frame: frameNo(), id: d.id, x: +x.toFixed(3), y: +y.toFixed(3), propagate: $("propagate").checked });
  });
  c.addEventListener("wheel", (e) => { e.preventDefault(); S.fitted = true; S.scale = Math.max(8, Math.min(200, S.scale * (e.deltaY < 0 ? 1.15 : 1 / 1.15))); renderBev(); }, { passive: false });
}

function setupPano() {
  const c = $("pano-overlay");
  c.addEventListener("mousedown", (e) => {
    if (!S.data || S.data.frame !== frameNo()) return; // the frame's people are still being fetched
    const r = c.getBoundingClientRect();
    const k = r.width / (S.meta.image_size ? S.meta.image_size[0] : r.width);
    let best = null, bd = 20;
    for (const p of S.data.gt) {
      if (!p.pano) continue;
      const dx = Math.abs(p.pano[0] * k - (e.clientX - r.left));
      const y = e.clientY - r.top;
      if (dx < bd && y > p.pano[1] * k - 20 && y < p.pano[2] * k + 20) { bd = dx; best = p; }
    }
    S.sel = best ? best.id : null; render();
  });
  $("pano").addEventListener("load", () => { $("pano-msg").hidden = true; $("pano-wrap").classList.remove("missing"); renderPano(); });
  $("pano").addEventListener("error", () => {
    // keep the panel's size (people are still drawn where they are in the panorama)
    const m = $("pano-msg"); m.hidden = false; $("pano-wrap").classList.add("missing");
    m.textContent = S.meta && S.meta.media_problem ? "panorama unavailable: no recording" : "panorama unavailable";
    renderPano();
  });
}

function setupControls() {
  $("prev").onclick = () => loadFrame(S.idx - 1);
  $("next").onclick = () => loadFrame(S.idx + 1);
  $("frameno").addEventListener("change", () => { const i = S.frames.indexOf(parseInt($("frameno").value, 10)); if (i >= 0) loadFrame(i); else status("no such frame", "bad"); });
  $("next-flag").onclick = () => jump("flag");
  $("next-unrev").onclick = () => jump("unreviewed");
  $("next-doubt").onclick = () => jump("doubt");
  $("worst-doubt").onclick = () => jump("worst");
  $("reviewed").onclick = () => ops.review(!(S.data && S.data.reviewed));
  $("undo").onclick = () => undoRedo("undo");
  $("redo").onclick = () => undoRedo("redo");
  $("add-mode").onclick = () => { S.addMode = !S.addMode; render(); };
  $("set-id").onclick = ops.setId; $("merge").onclick = ops.merge; $("swap").onclick = ops.swap; $("split").onclick = ops.split; $("delete").onclick = ops.del;
  $("occluded").onchange = ops.flag; $("uncertain").onchange = ops.flag;
  $("timeline").addEventListener("click", (e) => { const r = e.target.getBoundingClientRect(); loadFrame(Math.floor(((e.clientX - r.left) / r.width) * S.frames.length)); });
  window.addEventListener("resize", render);
  // a typed #N (or the back button) goes to frame N
  window.addEventListener("hashchange", () => {
    const i = S.frames.indexOf(parseInt(location.hash.slice(1), 10));
    if (i >= 0 && i !== S.idx) loadFrame(i);
  });
  // the panorama's height changes the bird's-eye view's size: keep every person on screen
  if (window.ResizeObserver) new ResizeObserver(() => { if (S.data && !S.drag) renderBev(); }).observe($("bev").parentElement);
  window.addEventListener("keydown", (e) => {
    if (e.target.tagName === "INPUT" && e.target.type !== "checkbox" || e.target.tagName === "SELECT") { if (e.key === "Escape") e.target.blur(); return; }
    const step = e.shiftKey ? 10 : 1, k = e.key;
    if ((e.ctrlKey || e.metaKey) && (k === "z" || k === "Z")) { e.preventDefault(); undoRedo(e.shiftKey ? "redo" : "undo"); return; }
    if ((e.ctrlKey || e.metaKey) && (k === "y" || k === "Y")) { e.preventDefault(); undoRedo("redo"); return; }
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    const map = {
      ArrowRight: () => loadFrame(S.idx + step), ArrowLeft: () => loadFrame(S.idx - step), d: () => loadFrame(S.idx + 1), a: () => loadFrame(S.idx - 1),
      Home: () => loadFrame(0), End: () => loadFrame(S.frames.length - 1),
      f: () => jump("flag", 1), F: () => jump("flag", -1), u: () => jump("unreviewed", 1), U: () => jump("unreviewed", -1),
      c: () => jump("doubt", 1), C: () => jump("doubt", -1), x: () => jump("worst"),
      r: () => ops.review(!(S.data && S.data.reviewed)),
      Enter: async () => { if (await ops.review(true)) loadFrame(S.idx + 1); }, // stay on a refused frame
      n: () => { S.addMode = !S.addMode; render(); }, Delete: ops.del, Backspace: ops.del,
      i: () => $("new-id").focus(), m: ops.merge, w: ops.swap, s: ops.split, p: () => { $("propagate").checked = !$("propagate").checked; },
      Escape: () => { S.sel = null; S.addMode = false; render(); }, "+": () => { S.scale *= 1.2; renderBev(); }, "-": () => { S.scale /= 1.2; renderBev(); },
      0: () => { fitBev(true); renderBev(); },
    };
    if (map[k]) { e.preventDefault(); map[k](); }
  });
}

// other tabs / users: poll the revision and the Rerun time cursor
async function poll() {
  if (window.studioNoPoll) return; // tests: keep a tab stale on purpose
  try {
    const m = await api("/api/state"); // a few bytes, whatever the run's length
    if (m.rev !== S.rev && !S.busy && !S.drag) { S.rev = m.rev; await loadFrame(S.idx); loadMetrics(true); status(`updated · rev ${m.rev}`, "ok"); }
    else if (S.metricsRev !== m.metrics_rev && !S.busy) loadMetrics(false);
    S.meta.rerun = m.rerun;
    if (m.rerun && m.rerun.can_follow && $("follow").checked && m.rerun.frame !== null && m.rerun.frame !== undefined &&
        m.rerun.frame !== S.lastRerunFrame && m.rerun.frame !== frameNo()) {
      S.lastRerunFrame = m.rerun.frame;
      const i = S.frames.indexOf(m.rerun.frame);
      if (i >= 0) await loadFrame(i);
    }
  } catch (e) { status("server unreachable", "bad"); }
}

async function main() {
  setupControls(); setupBev(); setupPano();
  try { await loadMeta(); } catch (e) { status(e.message, "bad"); return; }
  const want = parseInt(location.hash.slice(1), 10);
  const i = Number.isFinite(want) ? S.frames.indexOf(want) : -1;
  S.idx = -1;
  await loadFrame(i >= 0 ? i : 0);
  loadMetrics(true);
  status(`rev ${S.rev} · autosave on`, "ok");
  setInterval(poll, 2000);
}
main();
