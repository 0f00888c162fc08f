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

const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
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
    if (frame.rebuilt) this.clear();
    const pos = () => this.positions.array;
    let lo = Infinity, hi = -1;
    for (const id of frame.gone) {
      const slots = this.slotsOf.get(id);
      if (!slots) continue;
      this.slotsOf.delete(id);
      for (const s of slots) {
        const p = pos(), b = s * 9;
        for (let k = 3; k < 9; ++k) p[b + k] = p[b + (k % 3)];
        this.free.push(s);
        lo = Math.min(lo, s); hi = Math.max(hi, s);
      }
    }
    const n = frame.added.length;
    if (this.count + n > this.capacity) this.grow(this.count + n);
    const p = this.positions.array, q = this.normals.array;
    for (let i = 0; i < n; ++i) {
      const s = this.free.length ? this.free.pop() : this.count++;
      p.set(frame.positions.subarray(i * 9, i * 9 + 9), s * 9);
      if (frame.normals) q.set(frame.normals.subarray(i * 9, i * 9 + 9), s * 9);
      const id = frame.added[i];
      const list = this.slotsOf.get(id);
      if (list) list.push(s); else this.slotsOf.set(id, [s]);
      lo = Math.min(lo, s); hi = Math.max(hi, s);
    }
    this.geometry.setDrawRange(0, this.count * 3);
    if (hi >= lo) {
      // Upload only the slots written.
      for (const attr of [this.positions, this.normals]) {
        attr.clearUpdateRanges();
        attr.addUpdateRange(lo * 9, (hi - lo + 1) * 9);
        attr.needsUpdate = true;
      }
    }
  }
  liveTriangles() { let t = 0; for (const v of this.slotsOf.values()) t += v.length; return t; }
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
  fps: 0, sequence: 0, latencies: [], arrivals: [], connected: false,
};
const sentAt = new Map();  // iso request sequence -> time sent
const pendingLatency = [];  // send times of requests answered by a frame not yet drawn
let sequence = 0;
let framed = 0;
let ws;

function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { state.connected = true; };
  ws.onclose = () => { state.connected = false; statusLine.textContent = 'disconnected'; };
  ws.onmessage = (event) => {
    const f = decode(event.data);
    slots.apply(f);
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
}

function send(text) { if (ws && ws.readyState === WebSocket.OPEN) ws.send(text); }

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
  send(kind === 'full' ? 'goal full' : `goal ${kind} ${value}`);
});
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
  }
}
function loop(now) {
  resize();
  light.position.copy(camera.position);
  controls.update();
  renderer.render(scene, camera);
  const drawn = performance.now();
  while (pendingLatency.length) state.latencies.push(drawn - pendingLatency.pop());
  count += 1;
  if (now - last >= 1000) { state.fps = count * 1000 / (now - last); count = 0; last = now; }
  if (state.connected) {
    statusLine.textContent =
      `isovalue ${state.isovalue.toPrecision(6)} · splits ${state.splits} · triangles ${state.triangles}` +
      ` · next error ${state.nextError.toPrecision(3)} · ${state.fps.toFixed(0)} fps` +
      ` · ${state.running ? 'refining' : 'idle'} · ${(state.bytes / 1048576).toFixed(1)} MiB received`;
  }
  requestAnimationFrame(loop);
}
connect();
requestAnimationFrame(loop);
