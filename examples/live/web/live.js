// The live demo's page: draws the surface the server streams (GET /frame at the page's frame
// rate, GET /topology when a cut or a tear changes the triangles), sends the mouse's grasps,
// drags and cut strokes as commands (POST /command), and plots the grasper's force.
// window.live exposes the page's state to the browser test (test/browser.mjs).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const view = document.getElementById('view');
const overlay = document.getElementById('overlay');
const statusBox = document.getElementById('status');
const errorBox = document.getElementById('error');
const plot = document.getElementById('plot');

const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(window.devicePixelRatio);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2127);
const camera = new THREE.PerspectiveCamera(35, 1, 0.001, 10);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;
scene.add(new THREE.HemisphereLight(0xffffff, 0x444450, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 2.0);
scene.add(sun);
scene.add(camera);
camera.add(sun);  // the light comes from over the viewer's shoulder
sun.position.set(0.3, 0.5, 0.2);

const colours = { organ: 0x9c3b34, fat: 0xe8c66a, sheet: 0xd98c8c };
const material = new THREE.MeshStandardMaterial({ color: colours.organ, roughness: 0.55, metalness: 0.0,
                                                  side: THREE.DoubleSide });
const geometry = new THREE.BufferGeometry();
const mesh = new THREE.Mesh(geometry, material);
scene.add(mesh);
const grasper = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12), new THREE.MeshStandardMaterial({ color: 0x5bc0de }));
grasper.visible = false;
scene.add(grasper);

const live = window.live = {
  frames: 0, frameNumber: 0, topology: -1, vertices: 0, triangles: 0, positions: null, force: [0, 0, 0],
  grasping: false, status: null, lastReply: null, errors: [], fps: 0, sceneName: 'organ',
};

/// The screen position (CSS pixels) of a world point, for the browser test.
live.screenOf = (x, y, z) => {
  const v = new THREE.Vector3(x, y, z).project(camera);
  const r = renderer.domElement.getBoundingClientRect();
  return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height];
};

function resize() {
  const w = window.innerWidth, h = window.innerHeight;
  renderer.setSize(w, h);
  overlay.width = w; overlay.height = h;
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

// Commands go out one at a time, in order: on parallel connections the server could apply a
// release before its grasp, or a move before the grasp it drags.
let commandChain = Promise.resolve();
function command(body) {
  const send = async () => {
    try {
      const r = await fetch('/command', { method: 'POST', headers: { 'Content-Type': 'application/json' },
                                           body: JSON.stringify(body) });
      const reply = await r.json();
      live.lastReply = reply;
      if (!reply.ok) showError(reply.error);
      return reply;
    } catch (e) {
      showError(`server unreachable: ${e.message}`);
      return { ok: false, error: e.message };
    }
  };
  commandChain = commandChain.then(send);
  return commandChain;
}
function showError(text) {
  errorBox.textContent = text || '';
  if (text) live.errors.push(text);
}

// --- the surface --------------------------------------------------------------------------
let fitted = false;
async function loadTopology() {
  const buf = await (await fetch('/topology', { cache: 'no-store' })).arrayBuffer();
  const head = new Uint32Array(buf, 0, 2);
  geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(buf, 8, 3 * head[1]).slice(), 1));
  live.topology = head[0];
  live.triangles = head[1];
}

function fitCamera() {
  geometry.computeBoundingSphere();
  const s = geometry.boundingSphere;
  controls.target.copy(s.center);
  const d = s.radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * 1.05;
  camera.position.copy(s.center).add(new THREE.Vector3(0.25, -0.75, 0.6).normalize().multiplyScalar(d));
  camera.up.set(0, 0, 1);
  camera.near = d / 100; camera.far = d * 10;
  camera.updateProjectionMatrix();
  controls.update();
  grasper.scale.setScalar(s.radius / 40);
  fitted = true;
}

let inFlight = false, lastFpsTime = performance.now(), framesSince = 0;
async function pullFrame() {
  if (inFlight) return;
  inFlight = true;
  try {
    const buf = await (await fetch('/frame', { cache: 'no-store' })).arrayBuffer();
    const head = new Uint32Array(buf, 0, 4);
    if (head[0] !== 0x564c4650) throw new Error('not a frame');
    const st = new Float32Array(buf, 16, 12);
    const nv = head[2];
    if (head[1] !== live.topology) {
      await loadTopology();
      // The triangles may be newer than this frame's vertices: draw from the next frame.
      if (live.topology !== head[1]) return;
    }
    const data = new Float32Array(buf, 64, 6 * nv);
    let pos = geometry.getAttribute('position');
    if (!pos || pos.count !== nv) {
      geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * nv), 3));
      geometry.setAttribute('normal', new THREE.BufferAttribute(new Float32Array(3 * nv), 3));
      pos = geometry.getAttribute('position');
    }
    pos.array.set(data.subarray(0, 3 * nv));
    geometry.getAttribute('normal').array.set(data.subarray(3 * nv));
    pos.needsUpdate = true;
    geometry.getAttribute('normal').needsUpdate = true;
    geometry.computeBoundingSphere();  // the raycaster culls by it
    if (!fitted) fitCamera();
    live.positions = pos.array;
    live.vertices = nv;
    const fresh = head[3] !== live.frameNumber;
    live.frameNumber = head[3];
    live.force = [st[4], st[5], st[6]];
    live.grasping = st[7] > 0;
    live.frames++;
    framesSince++;
    updateStatus(st);
    if (fresh) recordForce(st[0], Math.hypot(st[4], st[5], st[6]), live.grasping);
  } catch (e) {
    statusBox.textContent = `waiting for the server (${e.message})`;
  } finally {
    inFlight = false;
  }
}

let statusJson = null, statusInFlight = false;
async function pullStatus() {
  if (statusInFlight) return;
  statusInFlight = true;
  try {
    statusJson = await (await fetch('/status', { cache: 'no-store' })).json();
    live.status = statusJson;
    if (statusJson.scene !== live.sceneName) {
      live.sceneName = statusJson.scene;
      document.getElementById('scene').value = statusJson.scene;
      material.color.setHex(colours[statusJson.scene] ?? 0xaaaaaa);
      fitted = false;
      forceHistory.length = 0;
    }
    document.getElementById('mode').textContent = statusJson.mode === 'realtime' ? 'real time' : 'accurate';
    if (statusJson.error) showError(`step failed, last good state shown: ${statusJson.error}`);
  } catch (e) { /* the frame loop reports it */ } finally {
    statusInFlight = false;
  }
}
setInterval(pullStatus, 250);

function updateStatus(st) {
  const now = performance.now();
  if (now - lastFpsTime > 1000) {
    live.fps = framesSince * 1000 / (now - lastFpsTime);
    framesSince = 0;
    lastFpsTime = now;
  }
  const s = statusJson;
  const f = Math.hypot(st[4], st[5], st[6]);
  statusBox.textContent =
    `t = ${st[0].toFixed(2)} s   ${st[3] > 0 ? 'real time' : 'accurate'}   ${(st[8] * 100).toFixed(0)}% of wall clock\n` +
    `step ${st[1].toFixed(1)} ms (median ${s ? s.median_ms.toFixed(1) : '-'} ms)   ${st[2].toFixed(0)} dofs\n` +
    `${live.triangles} triangles   ${live.fps.toFixed(0)} frames/s\n` +
    `grasper force ${live.grasping ? f.toFixed(3) + ' N' : '-'}`;
}

// --- the force plot -----------------------------------------------------------------------
const forceHistory = [];
function recordForce(t, f, grasping) {
  // A reset (here or from another page) starts the time again.
  if (forceHistory.length > 0 && t < forceHistory[forceHistory.length - 1][0]) forceHistory.length = 0;
  forceHistory.push([t, grasping ? f : NaN]);
  while (forceHistory.length > 0 && forceHistory[0][0] < t - 10) forceHistory.shift();
  drawPlot();
}
function drawPlot() {
  const g = plot.getContext('2d');
  const w = plot.width, h = plot.height, left = 44, bottom = 22, top = 20;
  g.clearRect(0, 0, w, h);
  g.fillStyle = '#e8e8e8';
  g.font = '12px system-ui, sans-serif';
  g.fillText('grasper force (N), last 10 s', left, 14);
  let fmax = 0.1;
  for (const [, f] of forceHistory) if (Number.isFinite(f) && f > fmax) fmax = f;
  fmax *= 1.1;
  g.strokeStyle = '#667';
  g.beginPath(); g.moveTo(left, top); g.lineTo(left, h - bottom); g.lineTo(w - 8, h - bottom); g.stroke();
  g.fillText(fmax.toPrecision(2), 4, top + 8);
  g.fillText('0', 30, h - bottom + 4);
  if (forceHistory.length === 0) return;
  const t1 = forceHistory[forceHistory.length - 1][0], t0 = t1 - 10;
  g.fillText(`${t0.toFixed(0)} s`, left - 8, h - 6);
  g.fillText(`${t1.toFixed(0)} s`, w - 36, h - 6);
  g.strokeStyle = '#5bc0de';
  g.lineWidth = 2;
  g.beginPath();
  let pen = false;
  for (const [t, f] of forceHistory) {
    if (!Number.isFinite(f)) { pen = false; continue; }
    const x = left + (t - t0) / 10 * (w - 8 - left), y = h - bottom - f / fmax * (h - bottom - top);
    if (pen) g.lineTo(x, y); else g.moveTo(x, y);
    pen = true;
  }
  g.stroke();
  g.lineWidth = 1;
}

// --- the mouse: grasp and drag, or draw a cut ---------------------------------------------
const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
let cutMode = false, dragging = false, grasped = false, stroke = null;
const dragPlane = new THREE.Plane();
let moveInFlight = false, pendingTarget = null;

function pick(event) {
  const r = renderer.domElement.getBoundingClientRect();
  pointer.set((event.clientX - r.left) / r.width * 2 - 1, -(event.clientY - r.top) / r.height * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  const hits = raycaster.intersectObject(mesh, false);
  return hits.length > 0 ? hits[0] : null;
}

function barycentric(hit) {
  const p = geometry.getAttribute('position');
  const A = new THREE.Vector3().fromBufferAttribute(p, hit.face.a);
  const B = new THREE.Vector3().fromBufferAttribute(p, hit.face.b);
  const C = new THREE.Vector3().fromBufferAttribute(p, hit.face.c);
  const b = new THREE.Triangle(A, B, C).getBarycoord(hit.point, new THREE.Vector3());
  // Clamp round-off outside the triangle, renormalise.
  const v = [Math.max(0, b.x), Math.max(0, b.y), Math.max(0, b.z)];
  const s = v[0] + v[1] + v[2];
  return s > 0 ? v.map(x => x / s) : null;  // a degenerate triangle: no point
}

async function sendMove() {
  if (moveInFlight || !pendingTarget || !grasped) return;
  moveInFlight = true;
  const t = pendingTarget;
  pendingTarget = null;
  await command({ cmd: 'move', target: [t.x, t.y, t.z] });
  moveInFlight = false;
  if (pendingTarget) sendMove();
}

function addHit(hit) {
  const bary = hit ? barycentric(hit) : null;
  if (bary) stroke.hits.push({ triangle: hit.faceIndex, bary });
}

renderer.domElement.addEventListener('pointerdown', async (event) => {
  if (event.button !== 0) return;
  const hit = pick(event);
  if (cutMode) {
    controls.enabled = false;
    // A stroke that starts (or ends) off the tissue cuts through its edge there.
    // The triangles the stroke is drawn on: a cut or tear meanwhile renumbers them.
    stroke = { screen: [[event.clientX, event.clientY]], hits: [], openStart: !hit, lastHit: !!hit,
               topology: live.topology };
    addHit(hit);
    return;
  }
  if (!hit) return;  // orbit
  controls.enabled = false;
  dragging = true;
  dragPlane.setFromNormalAndCoplanarPoint(camera.getWorldDirection(new THREE.Vector3()), hit.point);
  grasper.position.copy(hit.point);
  grasper.visible = true;
  const reply = await command({ cmd: 'grasp', point: [hit.point.x, hit.point.y, hit.point.z] });
  if (!reply.ok) { dragging = false; grasper.visible = false; controls.enabled = true; return; }
  if (!dragging) return;  // the button went up meanwhile: the release follows the grasp
  grasped = true;
  sendMove();  // where the mouse went meanwhile
});

renderer.domElement.addEventListener('pointermove', (event) => {
  if (stroke) {
    stroke.screen.push([event.clientX, event.clientY]);
    const hit = pick(event);
    addHit(hit);
    stroke.lastHit = !!hit;
    drawStroke();
    return;
  }
  if (!dragging) return;
  const r = renderer.domElement.getBoundingClientRect();
  pointer.set((event.clientX - r.left) / r.width * 2 - 1, -(event.clientY - r.top) / r.height * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  const target = raycaster.ray.intersectPlane(dragPlane, new THREE.Vector3());
  if (!target) return;
  grasper.position.copy(target);
  pendingTarget = target;
  sendMove();
});

async function endPointer() {
  if (stroke) {
    const s = stroke;
    stroke = null;
    controls.enabled = true;
    setTimeout(() => overlay.getContext('2d').clearRect(0, 0, overlay.width, overlay.height), 400);
    if (s.topology !== live.topology) {
      showError('the surface changed while the stroke was drawn: draw it again');
      return;
    }
    const dir = camera.getWorldDirection(new THREE.Vector3());
    const reply = await command({ cmd: 'cut', stroke: s.hits, direction: [dir.x, dir.y, dir.z], topology: s.topology,
                                  open_start: s.openStart, open_end: !s.lastHit });
    if (reply.ok) showError('');
    return;
  }
  if (!dragging) return;
  dragging = false;
  grasped = false;
  pendingTarget = null;
  grasper.visible = false;
  controls.enabled = true;
  await command({ cmd: 'release' });  // after the grasp, in order
}
renderer.domElement.addEventListener('pointerup', endPointer);
renderer.domElement.addEventListener('pointerleave', endPointer);

function drawStroke() {
  const g = overlay.getContext('2d');
  g.clearRect(0, 0, overlay.width, overlay.height);
  g.strokeStyle = '#ff5a4a';
  g.lineWidth = 3;
  g.beginPath();
  stroke.screen.forEach(([x, y], i) => (i ? g.lineTo(x, y) : g.moveTo(x, y)));
  g.stroke();
}

// --- the panel ----------------------------------------------------------------------------
document.getElementById('scene').addEventListener('change', async (e) => {
  showError('');
  await command({ cmd: 'scene', name: e.target.value });
  fitted = false;
});
document.getElementById('reset').addEventListener('click', async () => {
  showError('');
  await command({ cmd: 'reset' });
  forceHistory.length = 0;
});
document.getElementById('mode').addEventListener('click', async () => {
  const next = statusJson && statusJson.mode === 'realtime' ? 'accurate' : 'realtime';
  await command({ cmd: 'mode', mode: next });
  pullStatus();
});
document.getElementById('cut').addEventListener('click', (e) => {
  cutMode = !cutMode;
  e.target.classList.toggle('on', cutMode);
  e.target.textContent = cutMode ? 'Cutting: draw' : 'Cut';
});
document.getElementById('save').addEventListener('click', async () => {
  const r = await command({ cmd: 'save' });
  if (r.ok) errorBox.textContent = `wrote ${r.file}`;
});

renderer.setAnimationLoop(() => {
  pullFrame();
  controls.update();
  renderer.render(scene, camera);
});
