// flocksweep viewer: plays one run in 3-D from the page's "flock-data" JSON (format flocksweep-viewer/1,
// documented in analysis/viewer/encode.py). Boids are instanced cones pointing along their heading;
// positions and headings are interpolated between stored frames; trails, colourings, obstacles and
// extra agents (prey, predators) are drawn; the panel shows the current frame's metrics.
// window.flockViewer exposes the state for tests and scripting. Part 3 of 3 (streams.js, panel.js).
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { decode } from "flock/streams.js";
import { COLOUR_MODES, FOLLOWER_HEX, LEADER_HEX, OTHER_GROUP_HEX, STRAY_HEX, fillTables, legend as drawLegend,
         updatePanel as drawPanel } from "flock/panel.js";

const $ = (id) => document.getElementById(id);
// A page of several runs holds each run's data in its own block, marked with its run id (data-run); the
// run= of the URL fragment (the id or a unique prefix of it) picks the one shown, else the first.
const BLOCKS = [...document.querySelectorAll('script[type="application/json"][data-run]')];
const SEVERAL = BLOCKS.length > 1;
function blockFor(prefix) {
  const found = prefix ? BLOCKS.filter((b) => b.dataset.run.startsWith(prefix)) : [];
  return found.length === 1 ? found[0] : null;
}
const runInUrl = () => new URLSearchParams(window.location.hash.replace(/^#/, "")).get("run");
const BLOCK = SEVERAL ? (blockFor(runInUrl()) || BLOCKS[0]) : $("flock-data");
const DATA = JSON.parse(BLOCK.textContent);
const N = DATA.n, F = DATA.frames, TIMES = DATA.times;
const T0 = TIMES[0], T1 = TIMES[F - 1];
const DTF = F > 1 ? (T1 - T0) / (F - 1) : 1;
const BG = new THREE.Color("#eef2f6");

function say(text) {
  const box = $("message");
  box.textContent = text;
  box.style.display = "block";
}

function fail(text) {
  say(text);
  console.error(text);
}

// --------------------------------------------------------------------------------------------- state

const S = {
  frame: 0, t: T0, playing: false, speed: 1, loop: true,
  colorBy: COLOUR_MODES.includes(DATA.defaults.color_by) ? DATA.defaults.color_by : "boid",
  trailS: DATA.defaults.trail_s, boidScale: DATA.defaults.boid_scale, follow: DATA.defaults.follow,
  renders: 0, drawnFrame: -1, drawnT: NaN, dirty: true,
};

let pos, heading, speed, group, leader, agentData = [];
let renderer, scene, camera, controls, boids, trails, grid, agentMeshes = [];
const tmp = { m: new THREE.Matrix4(), q: new THREE.Quaternion(), v: new THREE.Vector3(), d: new THREE.Vector3(),
              s: new THREE.Vector3(), z: new THREE.Vector3(0, 0, 1), c: new THREE.Color() };
let groupSizes = null;
let lastHead = null;

function frameAt(t) {
  const x = (t - T0) / DTF;
  const f = Math.max(0, Math.min(F - 1, Math.floor(x + 1e-4)));  // stored times are rounded
  return [f, Math.max(0, Math.min(1, x - f))];
}

// interpolated position and heading of item i (of m per frame) at frame f + a, written to tmp.v, tmp.d
function sample(p, h, m, i, f, a) {
  const j = (f * m + i) * 3;
  let x = p[j], y = p[j + 1], z = p[j + 2];
  let hx = h[j], hy = h[j + 1], hz = h[j + 2];
  if (a > 0 && f + 1 < F) {
    const k = j + m * 3;
    const dx = p[k] - x, dy = p[k + 1] - y, dz = p[k + 2] - z;
    const jump = DATA.wrap_jump;
    if (jump === null || dx * dx + dy * dy + dz * dz <= jump * jump) {
      x += a * dx; y += a * dy; z += a * dz;
      hx += a * (h[k] - hx); hy += a * (h[k + 1] - hy); hz += a * (h[k + 2] - hz);
    } else if (a >= 0.5) {
      x = p[k]; y = p[k + 1]; z = p[k + 2]; hx = h[k]; hy = h[k + 1]; hz = h[k + 2];
    }
  }
  tmp.v.set(x, y, z);
  tmp.d.set(hx, hy, hz);
}

// colours parsed once: boidColour returns a shared THREE.Color, never parses a string per boid
const C = {};
function prepareColours() {
  const list = (hexes) => hexes.map((h) => new THREE.Color(h));
  C.turbo = list(DATA.palettes.turbo);
  C.viridis = list(DATA.palettes.viridis);
  C.tab10 = list(DATA.palettes.tab10);
  C.leader = new THREE.Color(LEADER_HEX);
  C.follower = new THREE.Color(FOLLOWER_HEX);
  C.stray = new THREE.Color(STRAY_HEX);
  C.otherGroup = new THREE.Color(OTHER_GROUP_HEX);
  C.byBoid = Array.from({ length: N }, (_, i) => C.turbo[Math.round((N > 1 ? i / (N - 1) : 0) * (C.turbo.length - 1))]);
  C.byPattern = Array.from({ length: N }, (_, i) => DATA.pattern
    ? new THREE.Color(DATA.pattern_colours[String(DATA.pattern[i])] || "#888888") : C.turbo[13]);
}

function boidColour(i, f) {
  switch (S.colorBy) {
    case "pattern": return C.byPattern[i];
    case "leader": return leader && leader[f * N + i] ? C.leader : C.follower;
    case "group": {
      const g = group[f * N + i];
      if (groupSizes[g] === 1) return C.stray;
      return g < 10 ? C.tab10[g] : C.otherGroup;
    }
    case "speed": {
      const x = Math.min(1, speed[f * N + i] / SPEED_TOP);
      return C.viridis[Math.round(x * (C.viridis.length - 1))];
    }
    default: return C.byBoid[i];
  }
}
let SPEED_TOP = 1;

function panelState() {
  return { data: DATA, n: N, frames: F, times: TIMES, dtf: DTF, leader, colorBy: S.colorBy, speedTop: SPEED_TOP };
}

function countGroups(f) {
  const sizes = new Int32Array(N + 1);
  for (let i = 0; i < N; i++) sizes[group[f * N + i]]++;
  return sizes;
}

// ---------------------------------------------------------------------------------------------- scene

function coneGeometry(length) {
  const g = new THREE.ConeGeometry(0.32 * length, length, 10);
  g.rotateX(Math.PI / 2);  // tip along +z
  return g;
}

function addWorld() {
  const w = DATA.world || {};
  const mat = new THREE.LineBasicMaterial({ color: 0x9aa6b2, transparent: true, opacity: 0.5 });
  if (w.boundary === "sphere_wrap") {
    const geo = new THREE.WireframeGeometry(new THREE.SphereGeometry(w.sphere_radius, 24, 12));
    scene.add(new THREE.LineSegments(geo, mat));
  } else if (w.boundary === "periodic_box") {
    const L = w.box_size;
    scene.add(new THREE.LineSegments(new THREE.EdgesGeometry(new THREE.BoxGeometry(L, L, L)), mat));
  }
}

function addSceneObjects() {
  for (const o of DATA.scene) {
    const mat = new THREE.MeshLambertMaterial({ color: o.color, transparent: o.opacity < 1, opacity: o.opacity,
                                                wireframe: o.wireframe, side: THREE.DoubleSide, depthWrite: o.opacity >= 1 });
    let mesh;
    if (o.type === "sphere") {
      mesh = new THREE.Mesh(new THREE.SphereGeometry(o.radius, 32, 16), mat);
      mesh.position.fromArray(o.center);
    } else if (o.type === "plane") {
      mesh = new THREE.Mesh(new THREE.PlaneGeometry(o.size, o.size), mat);
      mesh.position.fromArray(o.point);
      mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), new THREE.Vector3().fromArray(o.normal).normalize());
    } else if (o.type === "box") {
      mesh = new THREE.Mesh(new THREE.BoxGeometry(o.size[0], o.size[1], o.size[2]), mat);
      mesh.position.fromArray(o.center);
      mesh.quaternion.fromArray(o.rotation);
    } else if (o.type === "cylinder") {
      const a = new THREE.Vector3().fromArray(o.a), b = new THREE.Vector3().fromArray(o.b);
      const axis = b.clone().sub(a), length = axis.length();
      const geo = o.caps === "round" ? new THREE.CapsuleGeometry(o.radius, length, 8, 24)
                                     : new THREE.CylinderGeometry(o.radius, o.radius, length, 32);
      mesh = new THREE.Mesh(geo, mat);
      mesh.position.copy(a).add(b).multiplyScalar(0.5);
      mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), axis.normalize());
    }
    mesh.name = "scene:" + o.type;
    scene.add(mesh);
  }
}

// a run in the plane z = 0 (world.dimensions = 2, or a track whose every z is 0): seen from above (+z)
function isFlat() {
  return (DATA.world || {}).dimensions === 2 || (DATA.bounds.min[2] === 0 && DATA.bounds.max[2] === 0);
}

function addGrid() {
  const lo = DATA.bounds.min, hi = DATA.bounds.max;
  const flat = isFlat();
  const across = flat ? 1 : 2;  // the grid lies in the x-z plane below a 3-D flock, in the x-y plane under a flat one
  const span = Math.max(hi[0] - lo[0], hi[across] - lo[across], 20);
  const step = Math.pow(10, Math.floor(Math.log10(span / 4)));
  const size = Math.ceil(span * 1.2 / step) * step;
  grid = new THREE.GridHelper(size, Math.round(size / step), 0xb4bfcb, 0xd3dae2);
  if (flat) {
    grid.rotation.x = Math.PI / 2;
    grid.position.set((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, -0.02 * span);
  } else {
    grid.position.set((lo[0] + hi[0]) / 2, lo[1] - 0.02 * span, (lo[2] + hi[2]) / 2);
  }
  scene.add(grid);
}

const TRAIL_POINTS = 24;  // at most this many stored frames per trail (longer trails skip frames)

function makeTrails() {
  const count = (N + agentData.reduce((sum, ag) => sum + ag.m, 0)) * TRAIL_POINTS * 2;  // boids and agents
  const geo = new THREE.BufferGeometry();
  geo.setAttribute("position", new THREE.BufferAttribute(new Float32Array(count * 3), 3).setUsage(THREE.DynamicDrawUsage));
  geo.setAttribute("color", new THREE.BufferAttribute(new Float32Array(count * 3), 3).setUsage(THREE.DynamicDrawUsage));
  geo.setDrawRange(0, 0);
  trails = new THREE.LineSegments(geo, new THREE.LineBasicMaterial({ vertexColors: true }));
  trails.frustumCulled = false;
  scene.add(trails);
}

// The GPU's name, or "" when the browser hides it; software renderers (no GPU) draw without
// antialiasing, which halves their frame rate.
function rendererName() {
  const gl = document.createElement("canvas").getContext("webgl2") || document.createElement("canvas").getContext("webgl");
  if (!gl) return "";
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER) || "");
  const lose = gl.getExtension("WEBGL_lose_context");
  if (lose) lose.loseContext();
  return name;
}

function setupScene() {
  const software = /swiftshader|llvmpipe|software|softpipe/i.test(rendererName());
  try {
    renderer = new THREE.WebGLRenderer({ antialias: !software });
  } catch (err) {
    fail("WebGL is not available in this browser, so the flock cannot be drawn: " + err.message);
    return false;
  }
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  $("stage").appendChild(renderer.domElement);
  scene = new THREE.Scene();
  scene.background = BG;
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8899aa, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(0.4, 1, 0.6);
  scene.add(sun);
  camera = new THREE.PerspectiveCamera(45, 1, 0.05, 1e6);
  controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = false;
  controls.addEventListener("change", () => { S.dirty = true; });
  boids = new THREE.InstancedMesh(coneGeometry(1.6), new THREE.MeshLambertMaterial({ color: 0xffffff }), N);
  boids.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
  boids.frustumCulled = false;
  for (let i = 0; i < N; i++) boids.setColorAt(i, tmp.c.set(0xffffff));
  scene.add(boids);
  for (const a of agentData) {  // an agent that appears later is drawn ghosted (see ghostAgents) until it does
    const material = new THREE.MeshLambertMaterial({ color: a.color, transparent: a.appears !== null && a.appears !== undefined });
    const mesh = new THREE.InstancedMesh(coneGeometry(1.6 * a.size), material, a.m);
    mesh.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    mesh.frustumCulled = false;
    mesh.name = "agent:" + a.kind;
    agentMeshes.push(mesh);
    scene.add(mesh);
  }
  makeTrails();
  addGrid();
  addWorld();
  addSceneObjects();
  resize();
  fitView(0);
  return true;
}

function resize() {
  const stage = $("stage");
  const w = Math.max(1, stage.clientWidth), h = Math.max(1, stage.clientHeight);
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
  S.dirty = true;
}

function centroid(f, largestOnly) {
  const c = new THREE.Vector3();
  let count = 0;
  for (let i = 0; i < N; i++) {
    if (largestOnly && group[f * N + i] !== 0) continue;
    const j = (f * N + i) * 3;
    c.x += pos[j]; c.y += pos[j + 1]; c.z += pos[j + 2];
    count++;
  }
  return count ? c.multiplyScalar(1 / count) : c;
}

function fitView(f) {
  const c = centroid(f, false);
  let r = 1;
  for (let i = 0; i < N; i++) {
    const j = (f * N + i) * 3;
    r = Math.max(r, Math.hypot(pos[j] - c.x, pos[j + 1] - c.y, pos[j + 2] - c.z));
  }
  const w = DATA.world || {};
  if (w.boundary === "sphere_wrap") r = Math.max(r, w.sphere_radius);
  if (w.boundary === "periodic_box") r = Math.max(r, 0.87 * w.box_size);
  const dist = 1.15 * r / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
  controls.target.copy(c);
  const from = isFlat() ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(0.75, 0.45, 0.95).normalize();
  camera.position.copy(c).add(from.multiplyScalar(dist));
  camera.near = Math.max(0.01, dist / 2000);
  camera.far = dist * 200;
  camera.updateProjectionMatrix();
  controls.update();
  lastHead = null;
  S.dirty = true;
}

// --------------------------------------------------------------------------------------------- draw

function placeInstances(mesh, p, h, m, f, a, scale) {
  for (let i = 0; i < m; i++) {
    sample(p, h, m, i, f, a);
    if (tmp.d.lengthSq() > 1e-12) {
      tmp.q.setFromUnitVectors(tmp.z, tmp.d.normalize());
    }  // a stopped boid keeps the orientation of the previous one drawn: harmless, it has none
    tmp.s.setScalar(scale);
    tmp.m.compose(tmp.v, tmp.q, tmp.s);
    mesh.setMatrixAt(i, tmp.m);
  }
  mesh.instanceMatrix.needsUpdate = true;
}

function colourBoids(f) {
  if (S.colorBy === "group") groupSizes = countGroups(f);
  for (let i = 0; i < N; i++) boids.setColorAt(i, boidColour(i, f));
  boids.instanceColor.needsUpdate = true;
}

// One trail: instance i of the stored stream p (count per frame), back from the interpolated frame
// (f, a) over `points` stored frames `step` apart, fading from colour col to the background; writes
// segments into P, C from vertex offset v and returns the next offset.
function addTrail(P, C, v, p, h, count, i, col, f, a, step, points, jump2) {
  sample(p, h, count, i, f, a);
  let px = tmp.v.x, py = tmp.v.y, pz = tmp.v.z;
  for (let s = 0; s < points; s++) {
    const g = f - s * step;  // the segment runs from the newer point back to stored frame g
    if (g < 0) break;
    const j = (g * count + i) * 3;
    const qx = p[j], qy = p[j + 1], qz = p[j + 2];
    const dx = qx - px, dy = qy - py, dz = qz - pz;
    if (dx * dx + dy * dy + dz * dz > jump2) break;  // a boundary wrap: the trail stops there
    const fade = 0.3 + 0.7 * (1 - s / points), fade2 = 0.3 + 0.7 * (1 - (s + 1) / points);
    P[v] = px; P[v + 1] = py; P[v + 2] = pz;
    C[v] = BG.r + (col.r - BG.r) * fade; C[v + 1] = BG.g + (col.g - BG.g) * fade; C[v + 2] = BG.b + (col.b - BG.b) * fade;
    P[v + 3] = qx; P[v + 4] = qy; P[v + 5] = qz;
    C[v + 3] = BG.r + (col.r - BG.r) * fade2; C[v + 4] = BG.g + (col.g - BG.g) * fade2; C[v + 5] = BG.b + (col.b - BG.b) * fade2;
    v += 6;
    px = qx; py = qy; pz = qz;
  }
  return v;
}

function drawTrails(f, a) {
  const k = Math.min(F - 1, Math.round(S.trailS / DTF));
  const geo = trails.geometry;
  if (k < 1 || S.trailS <= 0) { geo.setDrawRange(0, 0); trails.visible = false; return; }
  trails.visible = true;
  const P = geo.attributes.position.array, C = geo.attributes.color.array;
  const step = Math.ceil(k / TRAIL_POINTS), points = Math.ceil(k / step);
  const jump2 = DATA.wrap_jump === null ? Infinity : DATA.wrap_jump * DATA.wrap_jump;
  let v = 0;
  for (let i = 0; i < N; i++) v = addTrail(P, C, v, pos, heading, N, i, boidColour(i, f), f, a, step, points, jump2);
  for (const ag of agentData) {  // prey and predators: trails in their own colour
    const col = new THREE.Color(ag.color);
    for (let i = 0; i < ag.m; i++) v = addTrail(P, C, v, ag.pos, ag.heading, ag.m, i, col, f, a, step, points, jump2);
  }
  geo.setDrawRange(0, v / 3);
  geo.attributes.position.needsUpdate = true;
  geo.attributes.color.needsUpdate = true;
}

function follow(f, a) {
  if (!S.follow) { lastHead = null; return; }
  const c = centroid(f, true);
  if (a > 0 && f + 1 < F) c.lerp(centroid(f + 1, true), a);
  if (lastHead) {
    const shift = c.clone().sub(lastHead);
    camera.position.add(shift);
    controls.target.add(shift);
  }
  lastHead = c;
}

// A predator or prey that appears during the run is visible from the start, where it first appears,
// semi-transparent (GHOST_OPACITY) until its time `appears`, then opaque.
const GHOST_OPACITY = 0.3;
function ghostAgents() {
  agentData.forEach((ag, k) => {
    const ghost = ag.appears !== null && ag.appears !== undefined && S.t < ag.appears - 1e-9;
    const material = agentMeshes[k].material;
    material.opacity = ghost ? GHOST_OPACITY : 1;
    material.depthWrite = !ghost;
  });
}

function draw() {
  const [f, a] = frameAt(S.t);
  const frameChanged = f !== S.drawnFrame;
  if (S.t !== S.drawnT || S.dirty) {
    follow(f, a);
    placeInstances(boids, pos, heading, N, f, a, S.boidScale);
    agentData.forEach((ag, k) => placeInstances(agentMeshes[k], ag.pos, ag.heading, ag.m, f, a, S.boidScale));
    ghostAgents();
    if (frameChanged || S.dirty) colourBoids(f);
    drawTrails(f, a);
    if (frameChanged) drawPanel(panelState(), f);
    S.frame = f;
    S.drawnFrame = f;
    S.drawnT = S.t;
  }
  controls.update();
  renderer.render(scene, camera);
  S.renders++;
  S.dirty = false;
}

let lastNow = null;
function tick(now) {
  if (S.playing && lastNow !== null) {
    S.t += ((now - lastNow) / 1000) * S.speed;
    if (S.t > T1) {
      if (S.loop && F > 1) S.t = T0; else { S.t = T1; setPlaying(false); }
    }
  }
  lastNow = now;
  draw();
  requestAnimationFrame(tick);
}

function setPlaying(on) {
  S.playing = on;
  $("play").innerHTML = on ? "&#10074;&#10074; pause" : "&#9654; play";
  lastNow = null;
  rememberInUrl();
}

function seekFrame(f) {
  f = Math.max(0, Math.min(F - 1, f));
  S.t = TIMES[f];  // a following camera jumps with the flock
  S.dirty = true;
  rememberInUrl();
}

// The URL fragment #run=RUN_ID&t=SECONDS&color=MODE opens the page at that time and colouring (else the
// page's defaults.start_time); pausing, stepping and recolouring write it back, so the address can be
// shared. `run` names the sweep run the address is for (a page of a sweep run writes its run id): a page
// of several runs shows that run (switching runs in its menu writes the fragment and reloads the page on
// it); a page that does not hold the run says so, names the page to open, and keeps its own time and
// colouring.
const RUN_ID = SEVERAL ? BLOCK.dataset.run : DATA.info && DATA.info["run id"] ? String(DATA.info["run id"]) : null;
function fromUrl() {
  const said = new URLSearchParams(window.location.hash.replace(/^#/, ""));
  const run = said.get("run");
  if (run && !(RUN_ID && RUN_ID.startsWith(run))) {
    const held = SEVERAL ? `this page holds runs ${BLOCKS.map((b) => b.dataset.run).join(", ")}, not that one`
                         : `this page shows ${RUN_ID ? "run " + RUN_ID : "another run"}`;
    say(`This address is for run ${run}, but ${held}: ` +
        `open that run's page (flocksweep view RESULTS --run ${run} writes RESULTS/viewer/${run}.html).`);
    S.t = Math.max(T0, Math.min(T1, Number.isFinite(DATA.defaults.start_time) ? DATA.defaults.start_time : T0));
    S.dirty = true;
    return;
  }
  const t = parseFloat(said.has("t") ? said.get("t") : DATA.defaults.start_time);
  if (Number.isFinite(t)) S.t = Math.max(T0, Math.min(T1, t));
  const colour = said.get("color");
  if (colour && COLOUR_MODES.includes(colour)) S.colorBy = colour;
  S.dirty = true;
}

function rememberInUrl() {
  if (S.playing || !window.history || !window.history.replaceState) return;
  try {
    window.history.replaceState(null, "", `#${RUN_ID ? "run=" + RUN_ID + "&" : ""}t=${S.t.toFixed(2)}&color=${S.colorBy}`);
  } catch (err) { /* a page opened where the address cannot change: nothing to remember */ }
}

// the run menu of a page of several runs: choosing a run writes its address (a new history entry, so
// Back returns to the run before), and the hashchange handler reloads the page on it
function switchRun(run) {
  window.location.hash = `run=${run}&t=${S.t.toFixed(2)}&color=${S.colorBy}`;
}

function bindRunMenu() {
  if (!SEVERAL) return;
  const menu = $("run");
  for (const b of BLOCKS) {
    const option = document.createElement("option");
    option.value = b.dataset.run;
    option.textContent = b.dataset.label || b.dataset.run;
    menu.appendChild(option);
  }
  menu.value = RUN_ID;
  menu.addEventListener("change", (e) => switchRun(e.target.value));
  $("run-row").hidden = false;
  document.title = DATA.title;
  $("title").textContent = DATA.title;
}

function bindControls() {
  bindRunMenu();
  $("slider").max = String(F - 1);
  $("play").addEventListener("click", () => setPlaying(!S.playing));
  $("step").addEventListener("click", () => { setPlaying(false); seekFrame(S.frame + 1); });
  $("back").addEventListener("click", () => { setPlaying(false); seekFrame(S.frame - (frameAt(S.t)[1] > 0 ? 0 : 1)); });
  $("speed").addEventListener("change", (e) => { S.speed = Number(e.target.value); });
  $("slider").addEventListener("input", (e) => { seekFrame(Number(e.target.value)); });
  const colorby = $("colorby");
  colorby.value = S.colorBy;
  colorby.addEventListener("change", (e) => { S.colorBy = e.target.value; drawLegend(panelState()); S.dirty = true;
                                               rememberInUrl(); });
  const trail = $("trail");
  trail.value = String(S.trailS);
  $("trail-v").textContent = S.trailS + " s";
  trail.addEventListener("input", (e) => { S.trailS = Number(e.target.value); $("trail-v").textContent = S.trailS + " s"; S.dirty = true; });
  const size = $("size");
  size.value = String(S.boidScale);
  $("size-v").textContent = "\u00d7" + S.boidScale;
  size.addEventListener("input", (e) => { S.boidScale = Number(e.target.value); $("size-v").textContent = "\u00d7" + S.boidScale; S.dirty = true; });
  $("follow").checked = S.follow;
  $("follow").addEventListener("change", (e) => { S.follow = e.target.checked; lastHead = null; });
  $("loop").addEventListener("change", (e) => { S.loop = e.target.checked; });
  $("grid").addEventListener("change", (e) => { grid.visible = e.target.checked; S.dirty = true; });
  $("fit").addEventListener("click", () => fitView(S.frame));
  const chart = $("chart");
  const seekChart = (e) => {
    const r = chart.getBoundingClientRect();
    seekFrame(Math.round(((e.clientX - r.left) / r.width) * (F - 1)));
  };
  chart.addEventListener("mousedown", seekChart);
  chart.addEventListener("mousemove", (e) => { if (e.buttons & 1) seekChart(e); });
  window.addEventListener("keydown", (e) => {
    if (e.target.tagName === "INPUT" && e.target.type !== "range" || e.target.tagName === "SELECT") return;
    if (e.code === "Space") { e.preventDefault(); setPlaying(!S.playing); }
    else if (e.code === "ArrowRight") { e.preventDefault(); setPlaying(false); seekFrame(S.frame + 1); }
    else if (e.code === "ArrowLeft") { e.preventDefault(); setPlaying(false); seekFrame(S.frame - 1); }
    else if (e.code === "Home") seekFrame(0);
    else if (e.code === "End") seekFrame(F - 1);
  });
  window.addEventListener("resize", resize);
}

// ---------------------------------------------------------------------------------------------- start

async function start() {
  if (DATA.format !== "flocksweep-viewer/1") throw new Error("unknown data format " + DATA.format);
  [pos, heading, speed, group] = await Promise.all([decode(DATA.pos), decode(DATA.heading), decode(DATA.speed), decode(DATA.group)]);
  leader = DATA.leader ? await decode(DATA.leader) : null;
  SPEED_TOP = DATA.speed.scale * 255;
  for (const a of DATA.agents) {
    const [p, h] = await Promise.all([decode(a.pos), decode(a.heading)]);
    agentData.push({ ...a, pos: p, heading: h });
  }
  prepareColours();
  fromUrl();
  if (!setupScene()) return;
  bindControls();
  window.addEventListener("hashchange", () => {
    const next = SEVERAL ? blockFor(runInUrl()) : null;
    if (next && next !== BLOCK) { window.location.reload(); return; }   // another run of this page
    fromUrl(); $("colorby").value = S.colorBy; drawLegend(panelState());
  });
  drawLegend(panelState());
  fillTables(panelState());
  drawPanel(panelState(), 0);
  window.flockViewer = {
    get ready() { return true; }, frames: F, n: N, data: DATA, run: RUN_ID, runs: BLOCKS.map((b) => b.dataset.run),
    switchRun,
    get frame() { return S.frame; }, get time() { return S.t; }, get playing() { return S.playing; },
    get colorBy() { return S.colorBy; }, get renders() { return S.renders; },
    play: () => setPlaying(true), pause: () => setPlaying(false), seek: seekFrame,
    setColorBy: (mode) => { $("colorby").value = mode; $("colorby").dispatchEvent(new Event("change")); },
    setSpeed: (x) => { S.speed = x; },
    boidMatrix: (i) => { const m = new THREE.Matrix4(); boids.getMatrixAt(i, m); return m.elements.slice(); },
    sceneNames: () => scene.children.map((c) => c.name).filter(Boolean),
    agentOpacity: (k) => agentMeshes[k].material.opacity,
    agentMatrix: (k) => { const m = new THREE.Matrix4(); agentMeshes[k].getMatrixAt(0, m); return m.elements.slice(); },
    trailVertices: () => (trails.visible ? trails.geometry.drawRange.count : 0),
    cameraDirection: () => camera.getWorldDirection(new THREE.Vector3()).toArray(),
    gridNormal: () => new THREE.Vector3(0, 1, 0).applyQuaternion(grid.quaternion).toArray(),
  };
  document.body.dataset.ready = "1";
  requestAnimationFrame(tick);
}

start().catch((err) => fail("The viewer could not start: " + (err && err.message ? err.message : err)));
