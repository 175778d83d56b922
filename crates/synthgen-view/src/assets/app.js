// synthgen view front end: plain JavaScript, no dependencies. Three pages share this file,
// told apart by <body data-page>.
"use strict";

const $ = (id) => document.getElementById(id);
const params = () => new URLSearchParams(location.search);
const getJSON = async (url) => {
  const r = await fetch(url);
  if (!r.ok) throw new Error(url + ": " + r.status + " " + (await r.text()));
  return r.json();
};
const COLOURS = ["#aaa", "#0ef", "#f0f", "#f80", "#a0ff50", "#fff", "#ff0", "#08f", "#f44", "#4f4", "#c8f", "#fc8"];
const colour = (obj) => COLOURS[obj % COLOURS.length];

async function gridPage() {
  const q = params();
  const info = await getJSON("/api/datasets");
  // Several datasets: side by side (one column each) unless one is picked.
  const pick = q.get("ds") ?? (info.datasets.length > 1 ? "all" : "0");
  const shown = pick === "all" ? info.datasets.map((d) => d.id) : [Number(pick)];
  const page = Number(q.get("page") || 0);
  const sel = $("ds");
  const opt = (value, text) => {
    const o = document.createElement("option");
    o.value = value;
    o.textContent = text;
    sel.appendChild(o);
  };
  if (info.datasets.length > 1) opt("all", "all, side by side");
  for (const d of info.datasets) opt(d.id, `${d.name} (${d.frames} frames)`);
  sel.value = pick;
  sel.onchange = () => { location.search = "?ds=" + sel.value; };
  const form = $("filters");
  for (const el of form.elements) if (el.name && q.get(el.name)) el.value = q.get(el.name);
  form.onsubmit = (e) => {
    e.preventDefault();
    const p = new URLSearchParams({ ds: pick });
    for (const el of form.elements) if (el.name && el.value !== "") p.set(el.name, el.value);
    location.search = "?" + p.toString();
  };
  const grid = $("grid");
  grid.classList.toggle("columns", shown.length > 1);
  let pages = 0, totals = [];
  for (const ds of shown) {
    const api = new URLSearchParams(q);
    api.set("ds", ds);
    api.set("page", page);
    if (shown.length > 1) api.set("per_page", 30);
    const res = await getJSON("/api/frames?" + api.toString());
    pages = Math.max(pages, res.pages);
    totals.push(`${info.datasets[ds].name}: ${res.total}`);
    const col = document.createElement("div");
    col.className = "column";
    if (shown.length > 1) col.innerHTML = `<h2>${info.datasets[ds].name}</h2>`;
    const cells = document.createElement("div");
    cells.className = "cells";
    for (const f of res.frames) {
      const a = document.createElement("a");
      a.className = "thumb";
      a.href = `/frame?ds=${ds}&idx=${f.idx}`;
      a.dataset.idx = f.idx;
      const objs = [...new Set(f.instances.map((i) => i.obj_id))].join(" ");
      a.innerHTML = `<img loading="lazy" src="/img/${ds}/${f.idx}/thumb" alt="">` +
        `<span>${f.split} ${f.scene_id}/${f.im_id} · obj ${objs}</span>`;
      cells.appendChild(a);
    }
    col.appendChild(cells);
    grid.appendChild(col);
  }
  $("pageinfo").textContent = `page ${page + 1} of ${Math.max(pages, 1)} (frames: ${totals.join(", ")})`;
  const go = (p) => { const n = new URLSearchParams(q); n.set("page", p); location.search = "?" + n; };
  $("prev").disabled = page <= 0;
  $("next").disabled = page + 1 >= pages;
  $("prev").onclick = () => go(page - 1);
  $("next").onclick = () => go(page + 1);
  document.body.dataset.ready = "1";
}

function drawOverlay(canvas, frame) {
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const boxes = $("layer-boxes").checked, axes = $("layer-axes").checked;
  const ests = $("layer-estimates").checked;
  const draw = (d, col, dashed) => {
    if (!d) return;
    ctx.setLineDash(dashed ? [6, 4] : []);
    if (boxes && d.box) {
      ctx.strokeStyle = col;
      ctx.lineWidth = 2;
      for (const [a, b] of frame.edges) {
        const p = d.box[a], q = d.box[b];
        if (!p || !q) continue;
        ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
      }
    }
    if (axes && d.axes && d.axes[0]) {
      ["#f00", "#0f0", "#05f"].forEach((c, i) => {
        const e = d.axes[i + 1];
        if (!e) return;
        ctx.strokeStyle = c;
        ctx.lineWidth = 3;
        ctx.beginPath(); ctx.moveTo(d.axes[0][0], d.axes[0][1]); ctx.lineTo(e[0], e[1]); ctx.stroke();
      });
    }
  };
  for (const inst of frame.instances) {
    draw(inst.gt, colour(inst.obj_id), false);
    if (ests && inst.estimate) draw(inst.estimate, "#fff", true);
  }
  ctx.setLineDash([]);
}

async function framePage() {
  const q = params();
  const ds = Number(q.get("ds") || 0);
  const idx = Number(q.get("idx") || 0);
  const f = await getJSON(`/api/frame/${ds}/${idx}`);
  $("title").textContent = `${f.split} scene ${f.scene_id} image ${f.im_id} (frame ${idx + 1} of ${f.frames})`;
  $("back").href = `/?ds=${ds}`;
  const nav = (i) => { if (i >= 0 && i < f.frames) location.search = `?ds=${ds}&idx=${i}`; };
  $("fprev").onclick = () => nav(idx - 1);
  $("fnext").onclick = () => nav(idx + 1);
  const rgb = $("img-rgb");
  rgb.src = `/img/${ds}/${idx}/rgb`;
  const canvas = $("overlay");
  canvas.width = f.width;
  canvas.height = f.height;
  if (f.has_masks) {
    $("img-masks").src = `/img/${ds}/${idx}/masks`;
    $("img-contours").src = `/img/${ds}/${idx}/contours`;
  } else {
    $("img-contours").classList.add("hidden");
  }
  const layer = (box, el) => {
    const apply = () => $(el).classList.toggle("hidden", !$(box).checked);
    $(box).onchange = apply;
    apply();
  };
  layer("layer-rgb", "img-rgb");
  if (f.has_masks) {
    layer("layer-masks", "img-masks");
    layer("layer-contours", "img-contours");
  }
  for (const id of ["layer-boxes", "layer-axes", "layer-estimates"]) $(id).onchange = () => drawOverlay(canvas, f);
  drawOverlay(canvas, f);
  const tbody = document.querySelector("#objects tbody");
  const fmt = (v, d) => (v === null || v === undefined ? "–" : Number(v).toFixed(d));
  for (const i of f.instances) {
    const e = i.estimate || {};
    const tr = document.createElement("tr");
    tr.innerHTML = `<td>${i.gt_id}</td><td style="color:${colour(i.obj_id)}">${i.obj_id}</td>` +
      `<td>${fmt(i.visib_fract, 3)}</td><td>${i.px_count_visib ?? "–"}</td><td>${fmt(i.distance_m, 3)}</td>` +
      `<td>${fmt(e.add_s_mm, 1)}</td><td>${fmt(e.te_cm, 2)}</td><td>${fmt(e.re_deg, 2)}</td>`;
    tbody.appendChild(tr);
  }
  if (f.has_depth) {
    const dimg = $("img-depth");
    dimg.src = `/img/${ds}/${idx}/depth`;
    const buf = await (await fetch(`/img/${ds}/${idx}/depth.raw`)).arrayBuffer();
    const head = new Uint32Array(buf, 0, 2);
    const w = head[0], h = head[1];
    const vals = new Uint16Array(buf.slice(8));
    const show = (ev) => {
      const r = ev.target.getBoundingClientRect();
      const x = Math.floor((ev.clientX - r.left) * w / r.width), y = Math.floor((ev.clientY - r.top) * h / r.height);
      if (x < 0 || y < 0 || x >= w || y >= h) return;
      const v = vals[y * w + x];
      $("cursor").textContent = v ? `depth at (${x}, ${y}): ${(v * f.depth_scale).toFixed(1)} mm` : `(${x}, ${y}): no depth`;
    };
    dimg.onmousemove = show;
    $("stack").onmousemove = show;
  } else {
    $("cursor").textContent = "this frame has no depth image";
  }
  document.body.dataset.ready = "1";
}

function barChart(title, series, lo, hi, unit) {
  const W = 520, H = 180, pad = 30;
  const n = series[0].frac.length;
  const max = Math.max(1, ...series.flatMap((s) => s.frac));
  let svg = `<svg class="chart" width="${W}" height="${H + 40}" xmlns="http://www.w3.org/2000/svg">` +
    `<text x="4" y="14" fill="#ddd">${title}</text>`;
  const bw = (W - pad) / n / series.length;
  series.forEach((s, k) => {
    s.frac.forEach((v, i) => {
      const bh = (v / max) * H;
      svg += `<rect x="${pad + i * bw * series.length + k * bw}" y="${20 + H - bh}" width="${bw - 1}" height="${bh}" fill="${s.colour}" opacity="0.85"/>`;
    });
  });
  svg += `<text x="${pad}" y="${H + 36}" fill="#aaa">${lo} ${unit}</text><text x="${W - 60}" y="${H + 36}" fill="#aaa">${hi} ${unit}</text></svg>`;
  return svg;
}

async function statsPage() {
  const all = (await getJSON("/api/stats")).datasets;
  const cols = ["#4af", "#f84", "#8f4", "#f4f"];
  $("legend").innerHTML = all.map((d, i) => `<span style="color:${cols[i % 4]}">■ ${d.name} (${d.stats.frames} frames, ${d.stats.instances} instances)</span>`).join(" ");
  const norm = (c) => { const t = c.reduce((a, b) => a + b, 0) || 1; return c.map((v) => v / t); };
  const charts = [
    ["visible fraction", (s) => s.visib_fract, ""],
    ["distance", (s) => s.distance_m && s.distance_m.histogram, "m"],
    ["camera elevation", (s) => s.elevation_deg && s.elevation_deg.histogram, "°"],
    ["in-plane rotation", (s) => s.inplane_deg && s.inplane_deg.histogram, "°"],
  ];
  let html = "";
  for (const [title, pick, unit] of charts) {
    const hs = all.map((d) => pick(d.stats));
    const first = hs.find((h) => h);
    if (!first) continue;
    const series = hs.map((h, i) => ({ frac: h ? norm(h.counts) : first.counts.map(() => 0), colour: cols[i % 4] }));
    html += barChart(title + " (share of instances)", series, Number(first.lo.toFixed(2)), Number(first.hi.toFixed(2)), unit);
  }
  const objs = [...new Set(all.flatMap((d) => d.stats.objects.map((o) => o.obj_id)))].sort((a, b) => a - b);
  const count = (d, o) => (d.stats.objects.find((x) => x.obj_id === o) || { instances: 0 }).instances;
  html += `<table><tr><th>object</th>${all.map((d) => `<th>${d.name}</th>`).join("")}</tr>` +
    objs.map((o) => `<tr><td>${o}</td>${all.map((d) => `<td>${count(d, o)}</td>`).join("")}</tr>`).join("") + "</table>";
  $("charts").innerHTML = html;
  document.body.dataset.ready = "1";
}

const page = document.body.dataset.page;
const run = page === "grid" ? gridPage : page === "frame" ? framePage : statsPage;
run().catch((e) => {
  document.body.dataset.error = String(e);
  const p = document.createElement("pre");
  p.textContent = String(e);
  document.body.appendChild(p);
});
