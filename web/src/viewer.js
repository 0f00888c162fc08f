// The page of `progiso view`: keeps the engine's surface in slots that follow the server's
// frames (apps/progiso/view/frame_codec.hpp gives the layout), shades it, and sends the slider's
// isovalue and the buttons back. The page never sees the volume: only triangles.
import * as THREE from 'three';
import { OrbitControls } from '/OrbitControls.js';
import { GLTFExporter } from '/GLTFExporter.js';

const MAGIC = 0x31564750;
const canvas = document.getElementById('view');
const statusLine = document.getElementById('status');
const slider = document.getElementById('iso');
const isoText = document.getElementById('isoText');

// A software rasteriser (SwiftShader, llvmpipe) spends most of a frame on multisampling: without
// a GPU the page draws without it.
function softwareRenderer() {
  const gl = document.createElement('canvas').getContext('webgl2');
  const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
  const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
  gl?.getExtension('WEBGL_lose_context')?.loseContext();
  return /swiftshader|llvmpipe|softpipe|software/i.test(name);
}
const renderer = new THREE.WebGLRenderer({ canvas, antialias: !softwareRenderer(), preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x15181d);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1e7);
const controls = new OrbitControls(camera, canvas);
scene.add(new THREE.HemisphereLight(0xdde6ff, 0x303030, 1.2));
const light = new THREE.DirectionalLight(0xffffff, 1.6);
scene.add(light);

// The slot pool: slot s holds vertices 3s .. 3s + 2; a freed slot is collapsed to a point (it
// draws nothing) and reused. Pieces of one triangle share an id.
class Slots {
  constructor() {
    this.capacity = 0;
    this.count = 0;          // slots below the high-water mark
    this.free = [];
    this.slotsOf = new Map(); // id (BigInt) -> [slots]
    this.geometry = new THREE.BufferGeometry();
    this.grow(1 << 16);
  }
  grow(min) {
    let cap = Math.max(this.capacity * 2, min);
    const pos = new Float32Array(cap * 9);
    const nor = new Float32Array(cap * 9);
    if (this.capacity) {
      pos.set(this.positions.array.subarray(0, this.count * 9));
      nor.set(this.normals.array.subarray(0, this.count * 9));
    }
    this.positions = new THREE.BufferAttribute(pos, 3);
    this.normals = new THREE.BufferAttribute(nor, 3);
    this.positions.setUsage(THREE.DynamicDrawUsage);
    this.normals.setUsage(THREE.DynamicDrawUsage);
    this.geometry.setAttribute('position', this.positions);
    this.geometry.setAttribute('normal', this.normals);
    this.capacity = cap;
  }
  clear() {
    this.count = 0;
    this.free = [];
    this.slotsOf.clear();
  }
  apply(frame) {
    if (frame.rebuilt) { this.clear(); morphs.length = 0; }
    const pos = () => this.positions.array;
    let lo = Infinity, hi = -1;
    // The triangles this frame's splits remove: where the coarser surface was (geomorphs).
    const morph = !frame.rebuilt && frame.added.length <= MORPH_MAX_PIECES;
    const coarse = morph ? new Coarse() : null;
    for (const id of frame.gone) {
      const slots = this.slotsOf.get(id);
      if (!slots) continue;
      this.slotsOf.delete(id);
      for (const s of slots) {
        const p = pos(), b = s * 9;
        if (coarse) coarse.add(p, b);
        for (let k = 3; k < 9; ++k) p[b + k] = p[b + (k % 3)];
        this.free.push(s);
        lo = Math.min(lo, s); hi = Math.max(hi, s);
      }
    }
    const n = frame.added.length;
    if (this.count + n > this.capacity) this.grow(this.count + n);
    const p = this.positions.array, q = this.normals.array;
    if (coarse) coarse.index();
    const now = performance.now();
    let gliding = coarse !== null && !coarse.empty();
    for (let i = 0; i < n; ++i) {
      const s = this.free.length ? this.free.pop() : this.count++;
      const end = frame.positions.subarray(i * 9, i * 9 + 9);
      p.set(end, s * 9);
      if (frame.normals) q.set(frame.normals.subarray(i * 9, i * 9 + 9), s * 9);
      if (gliding && (i & 63) === 0 && performance.now() > now + MORPH_BUDGET_MS) gliding = false;
      if (gliding) {
        // Geomorph: each new vertex starts at its closest point on the removed triangles.
        const start = new Float32Array(9);
        for (let c = 0; c < 3; ++c) coarse.closest(end[3 * c], end[3 * c + 1], end[3 * c + 2], start, 3 * c);
        p.set(start, s * 9);
        morphs.push({ slot: s, id: frame.added[i], start, end: Float32Array.from(end), t0: now });
        state.morphed += 1;
        for (let k = 0; k < 9; k += 3) {
          state.morphReach = Math.max(state.morphReach, Math.hypot(end[k] - start[k], end[k + 1] - start[k + 1], end[k + 2] - start[k + 2]));
        }
      }
      const id = frame.added[i];
      const list = this.slotsOf.get(id);
      if (list) list.push(s); else this.slotsOf.set(id, [s]);
      lo = Math.min(lo, s); hi = Math.max(hi, s);
    }
    this.geometry.setDrawRange(0, this.count * 3);
    if (hi >= lo) this.upload(lo, hi);
  }
  upload(lo, hi) {
    dirty = true;
    for (const attr of [this.positions, this.normals]) {
      attr.clearUpdateRanges();
      attr.addUpdateRange(lo * 9, (hi - lo + 1) * 9);
      attr.needsUpdate = true;
    }
  }
  liveTriangles() { let t = 0; for (const v of this.slotsOf.values()) t += v.length; return t; }
}

// Geomorphs (paper §7: continuous transitions between levels). The rule: a split replaces the
// triangles of its diamond by finer ones; each vertex of a new triangle starts at its closest
// point on the triangles the same frame removed (the coarser surface there) and glides to its
// own position over MORPH_MS, so refinement does not pop. A triangle removed again while gliding
// simply goes; a rebuilt frame (a new isovalue) and frames of more than MORPH_MAX_PIECES pieces
// (a change too large to animate smoothly) appear at once, as do a frame's pieces past
// MORPH_BUDGET_MS of geomorph work (the page keeps its frame rate).
const MORPH_MS = 250;
const MORPH_MAX_PIECES = 4096;
const MORPH_BUDGET_MS = 4;  // per frame: pieces past it appear at once, so a frame applies fast
const morphs = [];

// The removed triangles, hashed by cell, for closest-point queries.
class Coarse {
  constructor() { this.tris = []; this.cells = new Map(); this.size = 0; }
  add(p, b) { this.tris.push(Float32Array.from(p.subarray(b, b + 9))); }
  empty() { return this.tris.length === 0; }
  key(x, y, z) { return ((x & 1023) | ((y & 1023) << 10) | ((z & 1023) << 20)) >>> 0; }
  index() {
    let sum = 0;
    for (const t of this.tris) sum += Math.hypot(t[3] - t[0], t[4] - t[1], t[5] - t[2]);
    this.size = Math.max(1e-6, 2 * sum / Math.max(1, this.tris.length));
    // Each triangle goes into every cell its box, grown by half a cell, meets: a point's own cell
    // then lists every triangle within half a cell of it, each once, so a query reads one cell.
    const m = this.size / 2;
    this.tris.forEach((t, i) => {
      const lo = [0, 1, 2].map((a) => Math.floor((Math.min(t[a], t[a + 3], t[a + 6]) - m) / this.size));
      const hi = [0, 1, 2].map((a) => Math.floor((Math.max(t[a], t[a + 3], t[a + 6]) + m) / this.size));
      for (let x = lo[0]; x <= hi[0]; ++x) for (let y = lo[1]; y <= hi[1]; ++y) for (let z = lo[2]; z <= hi[2]; ++z) {
        const k = this.key(x, y, z);
        const l = this.cells.get(k);
        if (l) l.push(i); else this.cells.set(k, [i]);
      }
    });
  }
  // The closest point to (x, y, z) on the removed triangles near it, into out[at..at+2]; the
  // point itself when none is near.
  closest(x, y, z, out, at) {
    out[at] = x; out[at + 1] = y; out[at + 2] = z;
    const l = this.cells.get(this.key(Math.floor(x / this.size), Math.floor(y / this.size), Math.floor(z / this.size)));
    if (!l) return;
    let best = Infinity;
    for (const i of l) {
      closestOnTriangle(x, y, z, this.tris[i], nearest);
      const d = (nearest[0] - x) ** 2 + (nearest[1] - y) ** 2 + (nearest[2] - z) ** 2;
      if (d < best) { best = d; out[at] = nearest[0]; out[at + 1] = nearest[1]; out[at + 2] = nearest[2]; }
    }
  }
}
const nearest = new Float64Array(3);

// The closest point of triangle t (9 floats) to p, into o (Ericson, Real-Time Collision Detection
// 5.1.5).
function closestOnTriangle(px, py, pz, t, o) {
  const ax = t[0], ay = t[1], az = t[2], bx = t[3], by = t[4], bz = t[5], cx = t[6], cy = t[7], cz = t[8];
  const abx = bx - ax, aby = by - ay, abz = bz - az, acx = cx - ax, acy = cy - ay, acz = cz - az;
  const apx = px - ax, apy = py - ay, apz = pz - az;
  const d1 = abx * apx + aby * apy + abz * apz, d2 = acx * apx + acy * apy + acz * apz;
  if (d1 <= 0 && d2 <= 0) { o[0] = ax; o[1] = ay; o[2] = az; return; }
  const bpx = px - bx, bpy = py - by, bpz = pz - bz;
  const d3 = abx * bpx + aby * bpy + abz * bpz, d4 = acx * bpx + acy * bpy + acz * bpz;
  if (d3 >= 0 && d4 <= d3) { o[0] = bx; o[1] = by; o[2] = bz; return; }
  const vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) { const v = d1 / (d1 - d3); o[0] = ax + v * abx; o[1] = ay + v * aby; o[2] = az + v * abz; return; }
  const cpx = px - cx, cpy = py - cy, cpz = pz - cz;
  const d5 = abx * cpx + aby * cpy + abz * cpz, d6 = acx * cpx + acy * cpy + acz * cpz;
  if (d6 >= 0 && d5 <= d6) { o[0] = cx; o[1] = cy; o[2] = cz; return; }
  const vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) { const w = d2 / (d2 - d6); o[0] = ax + w * acx; o[1] = ay + w * acy; o[2] = az + w * acz; return; }
  const va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    o[0] = bx + w * (cx - bx); o[1] = by + w * (cy - by); o[2] = bz + w * (cz - bz);
    return;
  }
  const denom = 1 / (va + vb + vc), v = vb * denom, w = vc * denom;
  o[0] = ax + abx * v + acx * w; o[1] = ay + aby * v + acy * w; o[2] = az + abz * v + acz * w;
}

// Moves every gliding vertex to where it is at `now`; finished ones end at their own position.
function glide(now) {
  if (!morphs.length) return;
  const p = slots.positions.array;
  let lo = Infinity, hi = -1, keep = 0;
  for (const m of morphs) {
    // A slot freed or reused since (its triangle removed again) is not this morph's any more.
    const owner = slots.slotsOf.get(m.id);
    if (!owner || !owner.includes(m.slot)) continue;
    const t = Math.min(1, (now - m.t0) / MORPH_MS);
    const e = t * t * (3 - 2 * t);
    const b = m.slot * 9;
    for (let k = 0; k < 9; ++k) p[b + k] = m.start[k] + (m.end[k] - m.start[k]) * e;
    lo = Math.min(lo, m.slot); hi = Math.max(hi, m.slot);
    if (t < 1) morphs[keep++] = m;
  }
  morphs.length = keep;
  state.morphing = keep;
  if (hi >= lo) slots.upload(lo, hi);
}

const slots = new Slots();
const material = new THREE.MeshStandardMaterial({ color: 0xd9c6a5, roughness: 0.55, metalness: 0.0, side: THREE.DoubleSide });
const mesh = new THREE.Mesh(slots.geometry, material);
mesh.frustumCulled = false;
scene.add(mesh);

function decode(buffer) {
  const v = new DataView(buffer);
  if (buffer.byteLength < 64 || v.getUint32(0, true) !== MAGIC) throw new Error('not a progiso frame');
  const flags = v.getUint32(4, true);
  const g = v.getUint32(56, true), a = v.getUint32(60, true);
  let at = 64;
  const gone = new BigUint64Array(buffer, at, g); at += 8 * g;
  const added = new BigUint64Array(buffer, at, a); at += 8 * a;
  const positions = new Float32Array(buffer, at, 9 * a); at += 36 * a;
  const normals = (flags & 2) ? new Float32Array(buffer, at, 9 * a) : null;
  return {
    rebuilt: (flags & 1) !== 0, running: (flags & 4) !== 0,
    isovalue: v.getFloat64(8, true), generation: Number(v.getBigUint64(16, true)),
    splits: Number(v.getBigUint64(24, true)), triangles: Number(v.getBigUint64(32, true)),
    nextError: v.getFloat64(40, true), stride: v.getUint32(48, true), sequence: v.getUint32(52, true),
    gone, added, positions, normals, bytes: buffer.byteLength,
  };
}

// What tests and the status line read.
const state = window.progiso = {
  frames: 0, bytes: 0, isovalue: NaN, splits: 0, triangles: 0, nextError: 0, running: false,
  fps: 0, sequence: 0, latencies: [], arrivals: [], connected: false, morphing: 0, morphed: 0, morphReach: 0, views: 0, budget: 0,
};
const sentAt = new Map();  // iso request sequence -> time sent
const pendingLatency = [];  // send times of requests answered by a frame not yet drawn
let sequence = 0;
let framed = 0;
// A frame applied and not yet drawn: the server sends the next once the page says "ack" after
// drawing, so frames never queue up in the socket or the browser when drawing is the slow part.
let unacknowledged = false;
let ws;

function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { state.connected = true; fitBudget = 0; fitDisplay(); };
  ws.onclose = () => { state.connected = false; statusLine.textContent = 'disconnected'; };
  ws.onmessage = (event) => {
    const f = decode(event.data);
    slots.apply(f);
    unacknowledged = true;
    state.frames += 1; state.bytes += f.bytes;
    state.isovalue = f.isovalue; state.splits = f.splits; state.triangles = f.triangles;
    state.nextError = f.nextError; state.running = f.running; state.shown = slots.liveTriangles();
    if (f.sequence > state.sequence && sentAt.has(f.sequence)) {
      // On the page now (arrived and applied); on screen when the next frame is drawn.
      state.arrivals.push(performance.now() - sentAt.get(f.sequence));
      pendingLatency.push(sentAt.get(f.sequence));
      for (const k of sentAt.keys()) if (k <= f.sequence) sentAt.delete(k);
    }
    state.sequence = f.sequence;
    // Framed on the first cut with some detail (the coarsest may cover a corner only), and
    // again when the first isovalue's refinement ends.
    if ((!framed && f.triangles > 256) || (framed === 1 && !f.running)) { frame(); framed = framed ? 2 : 1; }
    if (!slider.dataset.ready) {
      slider.dataset.ready = '1';
    }
  };
}

// Points the camera at the live slots (the pool's storage beyond them is zero).
function frame() {
  const p = slots.positions.array, n = slots.count * 9;
  const box = new THREE.Box3();
  const v = new THREE.Vector3();
  for (let i = 0; i < n; i += 3) box.expandByPoint(v.set(p[i], p[i + 1], p[i + 2]));
  const s = box.getBoundingSphere(new THREE.Sphere());
  if (box.isEmpty() || !isFinite(s.radius) || s.radius === 0) return;
  controls.target.copy(s.center);
  camera.position.copy(s.center).add(new THREE.Vector3(0.9, 0.7, 1.6).multiplyScalar(s.radius * 1.6));
  camera.near = s.radius / 100; camera.far = s.radius * 100;
  camera.updateProjectionMatrix();
  controls.update();
  viewChanged();
}

function send(text) { if (ws && ws.readyState === WebSocket.OPEN) ws.send(text); }

// View-dependent refinement: the camera goes to the server (eye, orbit target, the frustum's four
// side planes, physical coordinates), at most every VIEW_MS while it moves and once when it
// stops; the server refines first where it looks (apps/progiso/view/view_server.hpp).
const VIEW_MS = 100;
let viewSentAt = -Infinity, viewTimer = null, lastView = '';
const frustum = new THREE.Frustum(), viewProjection = new THREE.Matrix4();
function sendView() {
  viewSentAt = performance.now();
  camera.updateMatrixWorld();
  frustum.setFromProjectionMatrix(viewProjection.multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse));
  const words = [...camera.position.toArray(), ...controls.target.toArray()];
  for (let k = 0; k < 4; ++k) words.push(...frustum.planes[k].normal.toArray(), frustum.planes[k].constant);
  if (!words.every(Number.isFinite)) return;
  const text = 'view ' + words.map((x) => String(Number(x.toPrecision(7)))).join(' ');
  if (text !== lastView && ws && ws.readyState === WebSocket.OPEN) { lastView = text; ws.send(text); state.views += 1; }
}
function viewChanged() {
  const wait = VIEW_MS - (performance.now() - viewSentAt);
  if (wait <= 0) sendView();
  else if (!viewTimer) viewTimer = setTimeout(() => { viewTimer = null; sendView(); }, wait);
}
controls.addEventListener('change', () => { dirty = true; viewChanged(); });

function setIso(w) {
  sequence += 1;
  sentAt.set(sequence, performance.now());
  send(`iso ${w} ${sequence}`);
  isoText.textContent = Number(w).toPrecision(5);
}
window.progisoSetIso = setIso;

slider.addEventListener('input', () => setIso(Number(slider.value)));
document.getElementById('pause').addEventListener('click', (e) => {
  const paused = e.target.textContent === 'resume';
  send(paused ? 'resume' : 'pause');
  e.target.textContent = paused ? 'pause' : 'resume';
});
document.getElementById('goal').addEventListener('click', () => {
  const kind = document.getElementById('goalKind').value;
  const value = Number(document.getElementById('goalValue').value) || 0;
  fitting = kind === 'fit';
  if (fitting) { fitBudget = 0; fitDisplay(); return; }
  send(kind === 'full' ? 'goal full' : kind === 'triangles' ? `goal triangles ${Math.max(1, Math.round(value))}` : `goal ${kind} ${value}`);
});

// Fit the display (the default goal): the paper's time-critical scenario from the display's
// side. The page asks for a cut of at most K triangles, K what it draws in FIT_MS at the rate it
// measures, so it keeps its frame rate on any GPU or on none; the server spends K where the
// camera looks (its view). The rate: triangles in the draw range per millisecond of animation
// frames, over each second (the time a draw call takes says nothing when the GPU runs behind;
// the time between frames does). Held at the display's refresh rate, the rate understates what
// it could draw, so K grows by half a second until frames slow. K moves when it is off by more
// than a quarter; the engine only refines, so a smaller K caps what a new isovalue refines to.
const FIT_MS = 25, FIT_FIRST = 50000, FIT_MIN = 20000;
let fitting = true, fitBudget = 0, drawRate = 0, drawnSum = 0, drawTime = 0, lastDrawn = 0;
// Called after each draw with the time the previous animation frame drew (0: it did not).
function measureDraw(now, previous) {
  if (!previous) return;  // the page draws on demand: only back-to-back draws time a draw
  drawnSum += slots.count;
  drawTime += now - previous;
  if (drawTime >= 1000) {
    drawRate = drawnSum / drawTime;
    drawnSum = 0;
    drawTime = 0;
  }
}
function fitDisplay() {
  if (!fitting) return;
  const k = drawRate ? Math.max(FIT_MIN, Math.round(drawRate * FIT_MS)) : FIT_FIRST;
  if (fitBudget && Math.abs(k - fitBudget) <= 0.25 * fitBudget) return;
  fitBudget = k;
  send(`goal triangles ${k}`);
  state.budget = k;
}
setInterval(fitDisplay, 1000);
document.getElementById('save').addEventListener('click', () => {
  // The cut on screen: the live slots as an indexed-by-order mesh, written by three's exporter.
  const n = slots.count * 9;
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(slots.positions.array.slice(0, n), 3));
  g.setAttribute('normal', new THREE.BufferAttribute(slots.normals.array.slice(0, n), 3));
  new GLTFExporter().parse(new THREE.Mesh(g, material), (glb) => {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(new Blob([glb], { type: 'model/gltf-binary' }));
    a.download = `progiso-${state.isovalue}.glb`;
    a.click();
  }, (err) => console.error(err), { binary: true });
});

// The slider's range comes from the page's URL (?min=&max=&iso=), which the server prints.
const params = new URLSearchParams(location.search);
slider.min = params.get('min') ?? '0';
slider.max = params.get('max') ?? '1';
slider.value = params.get('iso') ?? String((Number(slider.min) + Number(slider.max)) / 2);
isoText.textContent = Number(slider.value).toPrecision(5);

let last = performance.now(), count = 0;
function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== w || canvas.height !== h) {
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(1, h);
    camera.updateProjectionMatrix();
    dirty = true;
    viewChanged();
  }
}
// Drawn on demand: when a frame changed the surface, a geomorph moved, or the camera or the
// canvas changed. An idle page leaves the cores to the engine (and to a software rasteriser).
let dirty = true;
function loop(now) {
  resize();
  glide(performance.now());
  controls.update();
  if (dirty) {
    dirty = false;
    light.position.copy(camera.position);
    renderer.render(scene, camera);
    const drawn = performance.now();
    measureDraw(drawn, lastDrawn);
    lastDrawn = drawn;
    while (pendingLatency.length) state.latencies.push(drawn - pendingLatency.pop());
    count += 1;
  } else {
    lastDrawn = 0;
  }
  // Acknowledged once drawn (a frame that changed nothing on screen left nothing to draw).
  if (unacknowledged) { unacknowledged = false; send('ack'); }
  if (now - last >= 1000) { state.fps = count * 1000 / (now - last); count = 0; last = now; }
  if (state.connected) {
    statusLine.textContent =
      `isovalue ${state.isovalue.toPrecision(6)} · splits ${state.splits} · triangles ${state.triangles}` +
      ` · next error ${state.nextError.toPrecision(3)} · ${state.fps.toFixed(0)} fps` +
      (fitting ? ` · fit ${state.budget}` : '') +
      ` · ${state.running ? 'refining' : 'idle'} · ${(state.bytes / 1048576).toFixed(1)} MiB received`;
  }
  requestAnimationFrame(loop);
}
connect();
requestAnimationFrame(loop);
