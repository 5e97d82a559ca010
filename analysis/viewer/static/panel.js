// flocksweep viewer, part 2 of 3: the side panel (the frame's metrics, the metrics chart, the colour
// legend, the run and its parameters) and the colours shared with the 3-D view. Functions take the
// viewer's state v = {data, n, frames, times, dtf, leader, colorBy, speedTop}.
const $ = (id) => document.getElementById(id);

export const COLOUR_MODES = ["boid", "pattern", "leader", "group", "speed"];
export const LEADER_HEX = "#e0301e", FOLLOWER_HEX = "#7f93a8", STRAY_HEX = "#c4cad1", OTHER_GROUP_HEX = "#8a8f96";

export function paletteAt(data, name, x) {
  const p = data.palettes[name];
  return p[Math.max(0, Math.min(p.length - 1, Math.round(x * (p.length - 1))))];
}

const METRIC_ROWS = [["polarization", "polarization", 3], ["n_groups", "groups", 0],
                     ["nn_distance", "nearest-neighbour distance", 2], ["cohesion", "cohesion (largest group)", 3]];

function fmt(v, digits) {
  return v === null || v === undefined ? "n/a" : Number(v).toFixed(digits);
}

export function updatePanel(v, f) {
  const { data: DATA, leader, n: N, frames: F, times: TIMES } = v;
  const T1 = TIMES[F - 1];
  const rows = [["time", TIMES[f].toFixed(2) + " s"]];
  for (const [key, label, digits] of METRIC_ROWS) if (DATA.metrics[key]) rows.push([label, fmt(DATA.metrics[key][f], digits)]);
  if (leader) {
    let count = 0;
    for (let i = 0; i < N; i++) count += leader[f * N + i];
    rows.push(["leaders", String(count)]);
  }
  $("metrics").innerHTML = "";
  for (const [k, v] of rows) addRow($("metrics"), k, v);
  $("slider").value = String(f);
  $("time").textContent = `t = ${TIMES[f].toFixed(2)} s of ${T1.toFixed(1)} s  (frame ${f + 1}/${F})`;
  drawChart(v, f);
}

function addRow(table, key, value) {
  const tr = document.createElement("tr");
  const a = document.createElement("td"), b = document.createElement("td");
  a.textContent = key;
  b.textContent = typeof value === "object" && value !== null ? JSON.stringify(value) : String(value);
  tr.append(a, b);
  table.appendChild(tr);
}

const CHART_LINES = [["polarization", "#1f77b4", 1], ["cohesion", "#ff7f0e", 1], ["nn_distance", "#6b7785", null]];

function drawChart(v, f) {
  const { data: DATA, frames: F } = v;
  const cv = $("chart"), g = cv.getContext("2d");
  const W = cv.width, H = cv.height, pad = 8, head = 34;  // the legend has its own strip: never on a line
  g.clearRect(0, 0, W, H);
  g.fillStyle = "#fbfcfd";
  g.fillRect(0, 0, W, H);
  const xOf = (k) => pad + (W - 2 * pad) * (F > 1 ? k / (F - 1) : 0);
  for (const [key, colour, top] of CHART_LINES) {
    const ys = DATA.metrics[key];
    if (!ys) continue;
    const finite = ys.filter((v) => v !== null);
    const hi = top || Math.max(1e-9, ...finite);
    g.strokeStyle = colour;
    g.lineWidth = 2;
    g.setLineDash(top ? [] : [6, 4]);
    g.beginPath();
    let pen = false;
    ys.forEach((v, k) => {
      if (v === null) { pen = false; return; }
      const y = H - pad - (H - head - pad) * Math.min(1, v / hi);
      if (pen) g.lineTo(xOf(k), y); else g.moveTo(xOf(k), y);
      pen = true;
    });
    g.stroke();
  }
  g.setLineDash([]);
  g.strokeStyle = "#d62728";
  g.lineWidth = 2;
  g.beginPath();
  g.moveTo(xOf(f), head);
  g.lineTo(xOf(f), H);
  g.stroke();
  g.font = "22px system-ui, sans-serif";
  let x = pad + 4;
  for (const [key, colour, top] of CHART_LINES) {
    if (!DATA.metrics[key]) continue;
    g.fillStyle = colour;
    const text = key === "nn_distance" ? "NND (scaled)" : key;
    g.fillText(text, x, 24);
    x += g.measureText(text).width + 16;
  }
}

export function legend(v) {
  const { data: DATA, leader, n: N, colorBy, speedTop } = v;
  const box = $("legend");
  box.innerHTML = "";
  const swatch = (hex, text) => {
    const span = document.createElement("span");
    const sw = document.createElement("span");
    sw.className = "sw";
    sw.style.background = hex;
    span.append(sw, document.createTextNode(text));
    box.appendChild(span);
  };
  const bar = (name, left, right) => {
    const b = document.createElement("div");
    b.className = "bar";
    b.style.background = `linear-gradient(to right, ${DATA.palettes[name].join(",")})`;
    const ends = document.createElement("div");
    ends.className = "ends";
    ends.innerHTML = `<span>${left}</span><span>${right}</span>`;
    box.append(b, ends);
  };
  if (colorBy === "boid") bar("turbo", "boid 0", `boid ${N - 1}`);
  else if (colorBy === "pattern") {
    if (!DATA.pattern) swatch(paletteAt(DATA, "turbo", 0.2), "no patterns in this run");
    else for (const [v, hex] of Object.entries(DATA.pattern_colours)) swatch(hex, "pattern " + Number(v).toString(2).padStart(8, "0"));
  } else if (colorBy === "leader") {
    swatch(LEADER_HEX, "leader");
    swatch(FOLLOWER_HEX, leader ? "not leading" : "no leaders in this run");
  } else if (colorBy === "group") {
    for (let g = 0; g < 5; g++) swatch(DATA.palettes.tab10[g], g === 0 ? "largest group" : `group ${g + 1}`);
    swatch(DATA.palettes.tab10[5], "6th to 10th: more colours");
    swatch(OTHER_GROUP_HEX, "11th and smaller");
    swatch(STRAY_HEX, "stray (alone)");
  } else if (colorBy === "speed") bar("viridis", "0", `${speedTop.toFixed(1)} units/s`);
  for (const a of DATA.agents) swatch(a.color, `${a.label} (${a.m})`);
}

export function fillTables(v) {
  const { data: DATA, frames: F, dtf: DTF } = v;
  const info = $("info"), params = $("params");
  addRow(info, "frames", `${F} (every ${DTF.toFixed(3)} s; stride ${DATA.encoding.stride})`);
  for (const [k, v] of Object.entries(DATA.info)) addRow(info, k, v);
  if (DATA.scene.length) addRow(info, "scene objects", DATA.scene.map((o) => o.label || o.type).join(", "));
  const entries = Object.entries(DATA.params);
  if (!entries.length) addRow(params, "parameters", "not recorded with this trajectory");
  for (const [k, v] of entries) addRow(params, k, v);
}
