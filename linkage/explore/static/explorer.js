// The explorer's page: draws what the server computes (linkage.explore.app), integrates nothing itself.
// Panels: the chain in the plane (drag a hinge, flick to launch), the configuration space (chart-0 sphere or the
// torus of rod angles; drag a point of either, flick to launch), readouts and controls.
// A motion arrives over the WebSocket /api/stream in windows of samples; the page plays them at the chosen
// speed, showing at each frame the last sample whose time has come (no interpolation: what is shown is what the
// library computed). Test hook: window.linkageExplorer (see docs/explorer.md).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/OrbitControls.js';

const $ = (id) => document.getElementById(id);
const CHART_COLOURS = [0x4e9be6, 0xf28e2b, 0x59a14f, 0xe15759, 0xb07aa1, 0xedc948, 0x76b7b2, 0xff9da7, 0x9c755f,
                       0xbab0ac, 0x86bcb6, 0xd37295];
const WINDOW = 10;       // time units per streamed window
const RATE = 50;         // samples per time unit
const MAX_SAMPLES = 20000;

const S = {
  chain: { lengths: 4, L: 3, masses: 1 },
  space: null, spaceBuilds: 0,
  pose: null,                      // [[re, im], ...] of the chain at rest (no motion)
  samples: [], switches: [], chartIds: [], index: -1, clock: 0, maxError: 0,
  running: false, paused: false, speed: 1, method: null, precision: null,
  ws: null, wsReady: null, pendingMore: false, awaitingLaunch: null, lastLaunch: null, lastRelease: null,
  error: null, metrics: { tFlick: null, flickToFirstFrameMs: null, frames: 0, playSeconds: 0, fps: null },
};

// ---------------------------------------------------------------------------------------------- server
async function api(path, body) {
  const response = await fetch(path, { method: 'POST', headers: { 'Content-Type': 'application/json' },
                                       body: JSON.stringify(body) });
  const json = await response.json();
  if (!response.ok) throw new Error(`${json.field}: ${json.error}`);
  return json;
}

function chainBody() {
  return { lengths: S.chain.lengths, L: S.chain.L, masses: S.chain.masses };
}

function connect() {
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/api/stream`;
  S.ws = new WebSocket(url);
  S.wsReady = new Promise((resolve) => S.ws.addEventListener('open', resolve, { once: true }));
  S.ws.addEventListener('message', (event) => receive(JSON.parse(event.data)));
  S.ws.addEventListener('close', () => { S.running = false; setTimeout(connect, 500); });
}

function receive(message) {
  if (message.type === 'error') {
    S.running = false; S.pendingMore = false;
    showError(`${message.field}: ${message.error}`);
    if (S.awaitingLaunch) { S.awaitingLaunch.reject(new Error(message.error)); S.awaitingLaunch = null; }
    return;
  }
  if (message.type !== 'chunk') return;
  if (message.index === 0) {
    if (!S.awaitingLaunch) return;
    S.samples = []; S.switches = []; S.index = -1; S.clock = 0; S.maxError = 0; S.aim = true;
    S.chartIds = message.chartIds; S.method = message.method; S.precision = message.precision;
    S.running = true; S.paused = false; S.metrics.frames = 0; S.metrics.playSeconds = 0;
    clearPaths();
    S.metrics.tChunk = performance.now();
    S.awaitingLaunch.resolve(message); S.awaitingLaunch = null;
  } else if (S.awaitingLaunch || !S.running) {
    return;  // a window of a motion that a newer launch replaced
  }
  const first = message.index === 0 ? 0 : 1;  // a window starts where the last one ended: skip the repeat
  for (let k = first; k < message.times.length; k++) {
    S.samples.push({ t: message.times[k], hinges: message.hinges[k], error: message.energyError[k],
                     chart: message.chart[k], sphere: message.sphere ? message.sphere[k] : null,
                     angles: message.angles[k] });
  }
  S.switches.push(...message.switches);
  if (S.samples.length > MAX_SAMPLES) {
    const drop = S.samples.length - MAX_SAMPLES;
    S.samples.splice(0, drop); S.index -= drop;
  }
  S.pendingMore = false;
}

async function launch({ hinges, velocity }) {
  hideError();
  await S.wsReady;
  if (S.awaitingLaunch) S.awaitingLaunch.reject(new Error('replaced by a newer launch'));
  const started = new Promise((resolve, reject) => { S.awaitingLaunch = { resolve, reject }; });
  started.catch(() => {});
  S.lastLaunch = { ...chainBody(), hinges, velocity, method: $('c-method').value,
                   precision: $('c-precision').value, window: WINDOW, rate: RATE };
  S.metrics.tSent = performance.now();
  S.ws.send(JSON.stringify({ type: 'launch', ...S.lastLaunch }));
  return started;
}

function stop() {
  S.running = false;
  if (S.ws && S.ws.readyState === WebSocket.OPEN) S.ws.send(JSON.stringify({ type: 'stop' }));
}

// a slider's value with at most 4 significant digits: L = 2.3456789 shows as 2.346, a speed of 0.1 + 0.2 as 0.3
function sliderText(x) { return String(Number(Number(x).toPrecision(4))); }

function showError(text) { S.error = text; $('error').textContent = text; $('error').hidden = false; }
function hideError() { S.error = null; $('error').hidden = true; }

// ---------------------------------------------------------------------------------------------- views
function makeView(container, camera) {
  const renderer = new THREE.WebGLRenderer({ antialias: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  container.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1b1e23);
  return { container, renderer, scene, camera };
}

function resize(view, fit) {
  const w = view.container.clientWidth, h = view.container.clientHeight;
  view.renderer.setSize(w, h, false);
  fit(w / Math.max(h, 1));
}

// the chain: an orthographic camera on the plane
const chainView = makeView($('chain-view'), new THREE.OrthographicCamera(-1, 1, 1, -1, -10, 10));
const chainGroup = new THREE.Group();
chainView.scene.add(chainGroup);
const rodMaterial = new THREE.MeshBasicMaterial({ color: 0xdde1e6 });
const hingeMaterial = new THREE.MeshBasicMaterial({ color: 0x4e9be6 });
const pinMaterial = new THREE.MeshBasicMaterial({ color: 0xe15759 });
let rods = [], hingeDots = [], trail = null, scale = 1;

function fitChain(aspect) {
  const R = S.space ? S.space.lengths.reduce((a, b) => a + b, 0) : 4;
  const half = 0.5 * R + 0.35 * R / 4;
  const cam = chainView.camera, cx = S.chain.L / 2;
  const hx = aspect >= 1 ? half * aspect : half, hy = aspect >= 1 ? half : half / aspect;
  Object.assign(cam, { left: cx - hx, right: cx + hx, top: hy, bottom: -hy });
  cam.updateProjectionMatrix();
  scale = R;
}

function buildChain() {
  chainGroup.clear();
  const n = S.space.n, width = 0.012 * scale;
  rods = Array.from({ length: n }, () => {
    const m = new THREE.Mesh(new THREE.PlaneGeometry(1, width), rodMaterial); chainGroup.add(m); return m;
  });
  hingeDots = Array.from({ length: n - 1 }, () => {
    const m = new THREE.Mesh(new THREE.CircleGeometry(0.03 * scale, 24), hingeMaterial);
    m.position.z = 0.1; chainGroup.add(m); return m;
  });
  for (const x of [0, S.chain.L]) {
    const pin = new THREE.Mesh(new THREE.PlaneGeometry(0.06 * scale, 0.06 * scale), pinMaterial);
    pin.position.set(x, 0, 0.1); chainGroup.add(pin);
  }
  trail = new THREE.Line(new THREE.BufferGeometry().setAttribute('position',
    new THREE.BufferAttribute(new Float32Array(3 * 4000), 3)), new THREE.LineBasicMaterial({ color: 0xf28e2b }));
  trail.geometry.setDrawRange(0, 0);
  chainGroup.add(trail);
}

function drawChain(hinges) {
  const pts = [[0, 0], ...hinges, [S.chain.L, 0]];
  rods.forEach((rod, k) => {
    const [x0, y0] = pts[k], [x1, y1] = pts[k + 1];
    rod.position.set((x0 + x1) / 2, (y0 + y1) / 2, 0);
    rod.rotation.z = Math.atan2(y1 - y0, x1 - x0);
    rod.scale.x = Math.hypot(x1 - x0, y1 - y0);
  });
  hingeDots.forEach((dot, k) => dot.position.set(hinges[k][0], hinges[k][1], 0.1));
}

// the configuration space: a perspective camera that orbits
const spaceView = makeView($('space-view'), new THREE.PerspectiveCamera(40, 1, 0.01, 100));
spaceView.camera.position.set(2.2, 1.6, 2.6);
const orbit = new OrbitControls(spaceView.camera, spaceView.renderer.domElement);
const sphereGroup = new THREE.Group(), torusGroup = new THREE.Group(), fanGroup = new THREE.Group();
spaceView.scene.add(sphereGroup, torusGroup, fanGroup);
spaceView.scene.add(new THREE.AmbientLight(0xffffff, 1.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.5); sun.position.set(3, 4, 5); spaceView.scene.add(sun);
let sphereMesh = null, spherePath = null, torusPath = null, torusCloud = null, marker = null, switchMarkers = null;

function curvatureColours(values) {
  const sorted = values.map(Math.abs).sort((a, b) => a - b);
  const top = sorted[Math.floor(0.9 * (sorted.length - 1))] || 1;  // the 90th percentile: a peak washes out the rest
  const out = [];
  for (const K of values) {  // diverging: blue < 0 < red, white at 0, saturated beyond the percentile
    const s = Math.max(-1, Math.min(1, K / top));
    const g = 0.62;  // a mid grey, so that the paths' colours stand out
    const c = s >= 0 ? new THREE.Color(g + 0.3 * s, g - 0.35 * s, g - 0.4 * s)
                     : new THREE.Color(g + 0.4 * s, g + 0.2 * s, g - 0.3 * s);
    out.push(c.r, c.g, c.b);
  }
  return out;
}

function logColours(values) {  // positive maps (bending, stiffness): dark blue to yellow on a log scale
  const logs = values.map((v) => Math.log(Math.max(v, 1e-300)));
  const lo = Math.min(...logs), span = Math.max(...logs) - lo || 1;
  return logs.flatMap((l) => { const c = new THREE.Color().setHSL(0.66 - 0.5 * (l - lo) / span, 0.7, 0.35 + 0.25 * (l - lo) / span);
                               return [c.r, c.g, c.b]; });
}

function colourSphere() {
  if (!sphereMesh) return;
  const kind = $('c-colour').value, sphere = S.space.sphere;
  const colours = kind === 'none' ? sphere.vertices.flatMap(() => [0.6, 0.62, 0.66])
                : kind === 'curvature' ? curvatureColours(sphere.curvature) : logColours(sphere[kind]);
  sphereMesh.geometry.setAttribute('color', new THREE.Float32BufferAttribute(colours, 3));
}

function pathLine(capacity) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * capacity), 3));
  geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * capacity), 3));
  geometry.setDrawRange(0, 0);
  return new THREE.Line(geometry, new THREE.LineBasicMaterial({ vertexColors: true }));
}

function pad3(v) { return [v[0] ?? 0, v[1] ?? 0, v[2] ?? 0]; }
// chart 0's sphere coordinates (sin phi_4, cos phi_4 cos t, cos phi_4 sin t) drawn with the poles up and down;
// paths a little outside the surface so that it does not hide them
function picture(s, r = 1) { const v = pad3(s); return [r * v[1], r * v[0], r * v[2]]; }
function unpicture(p) { return [p[1], p[0], p[2]]; }
function torusPoint(angles) { return pad3(angles.slice(0, S.space.n === 3 ? 2 : 3).map((a) => a / Math.PI)); }

function buildSpace() {
  sphereGroup.clear(); torusGroup.clear(); fanGroup.clear();
  const sp = S.space;
  sphereMesh = null;
  if (sp.sphere) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(sp.sphere.vertices.flatMap((v) => picture(v)), 3));
    g.setIndex(sp.sphere.faces.flat());
    g.computeVertexNormals();
    sphereMesh = new THREE.Mesh(g, new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide,
                                                                   transparent: true, opacity: 0.9 }));
    sphereGroup.add(sphereMesh);
    sphereGroup.add(new THREE.LineSegments(new THREE.WireframeGeometry(g),
      new THREE.LineBasicMaterial({ color: 0x000000, transparent: true, opacity: 0.12 })));
    colourSphere();
  } else if (sp.circle) {
    const g = new THREE.BufferGeometry().setFromPoints(sp.circle.points.map((p) => new THREE.Vector3(...picture(p))));
    sphereGroup.add(new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0x9aa3ad })));
  }
  // the torus of rod angles: the cube [-pi, pi]^3 scaled to [-1, 1]^3, the space as points
  const box = new THREE.LineSegments(new THREE.EdgesGeometry(new THREE.BoxGeometry(2, 2, sp.n === 3 ? 0 : 2)),
                                     new THREE.LineBasicMaterial({ color: 0x5a616b }));
  torusGroup.add(box);
  const cloud = new THREE.BufferGeometry();
  cloud.setAttribute('position', new THREE.Float32BufferAttribute(sp.torus.angles.flatMap(torusPoint), 3));
  torusCloud = new THREE.Points(cloud, new THREE.PointsMaterial({ color: 0x9aa3ad, size: 0.02 }));
  torusGroup.add(torusCloud);
  spherePath = pathLine(MAX_SAMPLES + 2); torusPath = pathLine(MAX_SAMPLES + 2);
  torusPath = new THREE.Points(torusPath.geometry, new THREE.PointsMaterial({ vertexColors: true, size: 0.03 }));
  sphereGroup.add(spherePath); torusGroup.add(torusPath);
  if (marker) spaceView.scene.remove(marker, switchMarkers);  // those of the space shown before
  marker = new THREE.Mesh(new THREE.SphereGeometry(0.035, 16, 12), new THREE.MeshBasicMaterial({ color: 0xffffff }));
  spaceView.scene.add(marker);
  switchMarkers = new THREE.Group();
  spaceView.scene.add(switchMarkers);
  showView();
}

function showView() {
  const torus = $('c-view').value === 'torus' || !(S.space.sphere || S.space.circle || (S.space.hasAtlas));
  sphereGroup.visible = !torus; torusGroup.visible = torus; fanGroup.visible = !torus;
  if (S.space.n > 3) spaceView.camera.position.setLength(torus ? 5.5 : 3.8);  // the whole cube in sight, or the sphere
  $('space-name').textContent = torus ? S.space.torus.name : (S.space.sphere
    ? 'the sphere S^2 in chart 0\'s picture (latitude phi_4, longitude t)'
    : S.space.circle ? 'the circle S^1 in chart 0\'s picture'
    : `projection of S^${S.space.n - 2} in chart 0's picture onto its first three coordinates`);
}

function clearPaths() {
  for (const p of [spherePath, torusPath]) if (p) p.geometry.setDrawRange(0, 0);
  if (trail) trail.geometry.setDrawRange(0, 0);
  if (switchMarkers) switchMarkers.clear();
}

function spacePoint(sample) {
  const torus = torusGroup.visible;
  return torus ? torusPoint(sample.angles) : (sample.sphere ? picture(sample.sphere, 1.01) : null);
}

// the paths grow sample by sample up to the one shown
let drawn = 0;
function extendPaths() {
  if (S.index < drawn - 1 || drawn > S.index + 1) drawn = 0;
  for (; drawn <= S.index; drawn++) {
    const s = S.samples[drawn], c = new THREE.Color(CHART_COLOURS[Math.max(0, s.chart) % CHART_COLOURS.length]);
    if (s.sphere) setVertex(spherePath, drawn, picture(s.sphere, 1.01), c);
    setVertex(torusPath, drawn, torusPoint(s.angles), c);
    const mid = s.hinges[Math.floor((S.space.n - 1) / 2)];
    const pos = trail.geometry.attributes.position, k = drawn % 4000;
    pos.setXYZ(k, mid[0], mid[1], 0.05); pos.needsUpdate = true;
    trail.geometry.setDrawRange(0, Math.min(drawn + 1, 4000));
  }
  for (const p of [spherePath, torusPath]) p.geometry.setDrawRange(0, drawn);
  const passed = S.switches.filter((sw) => sw.t <= (S.samples[S.index]?.t ?? -1));
  while (switchMarkers.children.length < passed.length) {
    const sw = passed[switchMarkers.children.length];
    const at = S.samples.find((s) => s.t >= sw.t) ?? S.samples[S.index];
    const p = spacePoint(at);
    if (!p) break;
    const dot = new THREE.Mesh(new THREE.SphereGeometry(0.028, 12, 8), new THREE.MeshBasicMaterial({ color: 0xffffff }));
    dot.position.set(...p); switchMarkers.add(dot);
  }
}

function setVertex(line, k, p, colour) {
  const pos = line.geometry.attributes.position, col = line.geometry.attributes.color;
  pos.setXYZ(k, p[0], p[1], p[2]); col.setXYZ(k, colour.r, colour.g, colour.b);
  pos.needsUpdate = true; col.needsUpdate = true;
}

// ---------------------------------------------------------------------------------------------- interaction
function worldOfPointer(event) {
  const rect = chainView.renderer.domElement.getBoundingClientRect(), cam = chainView.camera;
  const x = cam.left + (event.clientX - rect.left) / rect.width * (cam.right - cam.left);
  const y = cam.top - (event.clientY - rect.top) / rect.height * (cam.top - cam.bottom);
  return [x, y];
}

function screenOfHinge(k) {
  const rect = chainView.renderer.domElement.getBoundingClientRect(), cam = chainView.camera;
  const h = currentHinges()[k];
  return { x: rect.left + (h[0] - cam.left) / (cam.right - cam.left) * rect.width,
           y: rect.top + (cam.top - h[1]) / (cam.top - cam.bottom) * rect.height };
}

function screenOfAngles(angles) {  // where rod angles are drawn in the torus view: page pixels, distance from the eye
  const rect = spaceCanvas.getBoundingClientRect(), q = new THREE.Vector3(...torusPoint(angles));
  const depth = q.distanceTo(spaceView.camera.position), p = q.project(spaceView.camera);
  return { x: rect.left + (p.x + 1) / 2 * rect.width, y: rect.top + (1 - p.y) / 2 * rect.height, depth };
}

function currentHinges() {
  return S.index >= 0 && S.samples.length ? S.samples[S.index].hinges : S.pose;
}

// a drag records (time of the pointer event, hinges there); the release launches with the velocity of the last
// ~80 ms of it, unless the pointer rested for holdMs (HOLD_MS unless a test sets it) before it, or that velocity
// is below restSpeed (REST_SPEED of the chain's size per second unless a test sets it); S.lastRelease says which
const HOLD_MS = 250, REST_SPEED = 0.02;
let holdMs = HOLD_MS, restSpeed = REST_SPEED;
function makeDrag(project) {
  let history = [], busy = null, target = null;
  async function pump() {
    while (target !== null) {
      const { goal, time } = target; target = null;
      try {
        S.pose = await project(goal);
        history.push({ time, hinges: S.pose });
        drawChain(S.pose);
      } catch (err) { showError(err.message); }
    }
    busy = null;
  }
  return {
    start() {
      stop(); S.index = -1; S.samples = []; clearPaths(); S.lastRelease = null;
      history = [{ time: performance.now(), hinges: S.pose }];
    },
    pending() { return busy !== null; },
    move(goal) { target = { goal, time: performance.now() }; if (!busy) busy = pump(); },
    async release() {
      S.metrics.tFlick = performance.now(); S.metrics.flickToFirstFrameMs = null;
      S.lastRelease = 'pending';
      if (busy) await busy;
      const last = history[history.length - 1];
      if (S.metrics.tFlick - last.time > holdMs) {  // held still, then released: the chain stays posed
        S.lastRelease = `held ${(S.metrics.tFlick - last.time).toFixed(0)} ms`; return;
      }
      const old = [...history].reverse().find((e) => last.time - e.time >= 80) ?? history[0];
      const dt = (last.time - old.time) / 1000;
      if (dt <= 0) { S.lastRelease = 'not moved'; return; }
      const v = last.hinges.map((h, k) => [(h[0] - old.hinges[k][0]) / dt, (h[1] - old.hinges[k][1]) / dt]);
      const speed = Math.sqrt(v.reduce((a, [x, y]) => a + x * x + y * y, 0));
      if (speed < restSpeed * scale) {  // released at rest: the chain stays posed
        S.lastRelease = `at rest: speed ${speed.toPrecision(3)} over ${(1000 * dt).toFixed(0)} ms`; return;
      }
      try {
        const tangent = await api('/api/project', { ...chainBody(), hinges: last.hinges, velocity: v });
        await launch({ hinges: last.hinges, velocity: tangent.velocity });
        S.lastRelease = 'launched';
      } catch (err) { S.lastRelease = `error: ${err.message}`; showError(err.message); }
    },
  };
}

const chainCanvas = chainView.renderer.domElement;
let hingeDrag = null;
const chainDrag = makeDrag(async ([x, y]) => (await api('/api/project',
  { ...chainBody(), hinges: S.pose, hinge: hingeDrag, target: [x, y] })).hinges);
chainCanvas.addEventListener('pointerdown', (event) => {
  const [x, y] = worldOfPointer(event), hinges = currentHinges();
  let best = -1, bestDist = 0.08 * scale;
  hinges.forEach((h, k) => { const d = Math.hypot(h[0] - x, h[1] - y); if (d < bestDist) { best = k; bestDist = d; } });
  if (best < 0) return;
  S.pose = hinges; hingeDrag = best;
  chainCanvas.setPointerCapture(event.pointerId);
  chainDrag.start();
});
chainCanvas.addEventListener('pointermove', (event) => { if (hingeDrag !== null) chainDrag.move(worldOfPointer(event)); });
chainCanvas.addEventListener('pointerup', () => {
  if (hingeDrag === null) return;
  hingeDrag = null; chainDrag.release();
});

// the configuration space takes drags too: on the sphere (or the circle) the pointer's point of chart 0's
// picture is posed (/api/pose with `sphere`); in the torus of rod angles a drag starts at a configuration of the
// cloud under the pointer, and the chain is posed at the configuration, reached from the last pose, whose rod
// angles lie on the pointer's line of sight through the cube (n = 3: nearest the pointer's point of the plane)
const spaceCanvas = spaceView.renderer.domElement, raycaster = new THREE.Raycaster();
raycaster.params.Points.threshold = 0.04;
let spaceDragging = false;
function pointerRay(event) {
  const rect = spaceCanvas.getBoundingClientRect();
  const ndc = new THREE.Vector2((event.clientX - rect.left) / rect.width * 2 - 1,
                                -(event.clientY - rect.top) / rect.height * 2 + 1);
  raycaster.setFromCamera(ndc, spaceView.camera);
  return raycaster.ray;
}
function planeHit(ray) {  // where the ray meets the plane z = 0 of the flat pictures (n = 3)
  return Math.abs(ray.direction.z) < 1e-9 ? null : ray.at(-ray.origin.z / ray.direction.z, new THREE.Vector3());
}
function sphereGoal(event) {
  const ray = pointerRay(event);
  if (sphereMesh) {
    const hit = raycaster.intersectObject(sphereMesh)[0];
    return hit ? { sphere: unpicture(hit.point.toArray()) } : null;
  }
  const p = S.space.circle ? planeHit(ray) : null;  // the circle S^1 in the plane
  return p && Math.abs(Math.hypot(p.x, p.y) - 1) < 0.15 ? { sphere: unpicture(p.toArray()).slice(0, 2) } : null;
}
function torusGoal(event) {
  const ray = pointerRay(event), k = S.space.n === 3 ? 2 : 3;
  if (k === 2) { const p = planeHit(ray); return p ? { angles: [p.x * Math.PI, p.y * Math.PI] } : null; }
  // the line of sight, from its point nearest the pose shown (the angles' scale: the cube [-1, 1]^3 is [-pi, pi]^3)
  const near = ray.closestPointToPoint(new THREE.Vector3(...torusPoint(rodAngles(S.pose))), new THREE.Vector3());
  return { angles: near.toArray().map((x) => x * Math.PI), direction: ray.direction.toArray() };
}
function rodAngles(hinges) {
  const pts = [[0, 0], ...hinges, [S.chain.L, 0]];
  return pts.slice(1).map(([x, y], k) => Math.atan2(y - pts[k][1], x - pts[k][0]));
}
const spaceDrag = makeDrag(async (goal) => (await api('/api/pose',
  goal.sphere ? { ...chainBody(), sphere: goal.sphere } : { ...chainBody(), ...goal, hinges: S.pose })).hinges);
spaceCanvas.addEventListener('pointerdown', (event) => {
  let seed = currentHinges(), goal;
  if (torusGroup.visible) {
    pointerRay(event);
    const hit = raycaster.intersectObject(torusCloud)[0];
    if (!hit) return;
    seed = S.space.torus.hinges[hit.index];
    S.pose = seed; goal = torusGoal(event);
  } else {
    goal = sphereGoal(event);
  }
  if (!goal) return;
  orbit.enabled = false; spaceDragging = true;
  S.pose = seed; spaceDrag.start(); spaceDrag.move(goal);
}, { capture: true });
spaceCanvas.addEventListener('pointermove', (event) => {
  if (!spaceDragging) return;
  const goal = torusGroup.visible ? torusGoal(event) : sphereGoal(event);
  if (goal) spaceDrag.move(goal);
});
spaceCanvas.addEventListener('pointerup', () => {
  if (!spaceDragging) return;
  spaceDragging = false; orbit.enabled = true; spaceDrag.release();
});

// ---------------------------------------------------------------------------------------------- controls
function readLengths(text) {
  const parts = text.split(',').map((s) => s.trim()).filter((s) => s);
  return parts.length === 1 && Number.isInteger(Number(parts[0])) ? Number(parts[0]) : parts.map(Number);
}

async function rebuild() {
  stop(); hideError();
  try {
    S.space = await api('/api/space', chainBody());
  } catch (err) { showError(err.message); throw err; }
  S.pose = S.space.start; S.samples = []; S.index = -1; S.spaceBuilds += 1;
  $('topology').textContent = S.space.topology;
  const charts = $('c-method').options[0];  // 'charts'
  charts.disabled = !S.space.hasAtlas;
  if (!S.space.hasAtlas && $('c-method').value === 'charts') { $('c-method').value = 'hinges'; S.methodForced = true; }
  if (S.space.hasAtlas && S.methodForced) { $('c-method').value = 'charts'; S.methodForced = false; }
  if (S.space.n === 3) spaceView.camera.position.set(0, 0, 3.4);  // a plane picture: seen from above
  $('c-L').max = S.space.lengths.reduce((a, b) => a + b, 0);  // L ranges up to the rods' total length
  $('c-L').value = S.chain.L; $('c-L-out').textContent = sliderText(S.chain.L);
  resize(chainView, fitChain); buildChain(); buildSpace(); drawChain(S.pose);
  return S.space;
}

async function setLength(L) { S.chain.L = L; return rebuild(); }

$('c-L').addEventListener('input', () => { $('c-L-out').textContent = sliderText($('c-L').value); });
$('c-L').addEventListener('change', () => setLength(Number($('c-L').value)).catch(() => {}));
$('c-apply').addEventListener('click', () => {
  S.chain.lengths = readLengths($('c-lengths').value);
  const masses = $('c-masses').value.split(',').map(Number);
  S.chain.masses = masses.length === 1 ? masses[0] : masses;
  rebuild().catch(() => {});
});
$('c-speed').addEventListener('input', () => { S.speed = Number($('c-speed').value); $('c-speed-out').textContent = sliderText(S.speed); });
$('c-pause').addEventListener('click', () => { S.paused = !S.paused; $('c-pause').textContent = S.paused ? 'play' : 'pause'; });
$('c-step').addEventListener('click', () => { S.paused = true; $('c-pause').textContent = 'play'; stepOne(); });
$('c-view').addEventListener('change', () => { showView(); drawn = 0; clearPaths(); extendPaths(); });
$('c-colour').addEventListener('change', colourSphere);
$('c-fan').addEventListener('click', () => fan().catch((err) => showError(err.message)));

function stepOne() {
  if (S.index + 1 < S.samples.length) { S.index += 1; S.clock = S.samples[S.index].t; }
}

// a fan of geodesics from the current configuration: 8 directions in a plane of the tangent space
async function fan() {
  const hinges = currentHinges(), n1 = hinges.length;
  const masses = Array.isArray(S.chain.masses) ? S.chain.masses : Array(n1).fill(S.chain.masses);
  const dot = (a, b) => a.reduce((s, [x, y], k) => s + masses[k] * (x * b[k][0] + y * b[k][1]), 0);
  const project = async (v) => (await api('/api/project', { ...chainBody(), hinges, velocity: v })).velocity;
  let a = await project(hinges.map(([x, y]) => [-y, x]));
  let b = await project(hinges.map((_, k) => [k % 2 ? 1 : 0, k % 2 ? 0 : 1]));
  const ab = dot(a, b) / dot(a, a);
  b = b.map(([x, y], k) => [x - ab * a[k][0], y - ab * a[k][1]]);
  const unit = (v) => { const s = Math.sqrt(dot(v, v)); return v.map(([x, y]) => [x / s, y / s]); };
  a = unit(a); b = unit(b);
  fanGroup.clear();
  const paths = await Promise.all(Array.from({ length: 8 }, (_, j) => {
    const th = (2 * Math.PI * j) / 8;
    const v = a.map(([x, y], k) => [Math.cos(th) * x + Math.sin(th) * b[k][0], Math.cos(th) * y + Math.sin(th) * b[k][1]]);
    return api('/api/motion', { ...chainBody(), hinges, velocity: v, T: 2, samples: 81,
                                method: $('c-method').value });
  }));
  for (const p of paths) {
    if (!p.sphere) continue;
    const g = new THREE.BufferGeometry().setFromPoints(p.sphere.map((s) => new THREE.Vector3(...picture(s, 1.01))));
    fanGroup.add(new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0xedc948 })));
  }
}

// ---------------------------------------------------------------------------------------------- play
let lastFrame = performance.now(), shown = -2;
function frame(now) {
  const dt = Math.min(0.1, (now - lastFrame) / 1000);
  lastFrame = now;
  if (S.running && !S.paused && S.samples.length) {
    S.clock += dt * S.speed;
    S.metrics.frames += 1; S.metrics.playSeconds += dt;
    while (S.index + 1 < S.samples.length && S.samples[S.index + 1].t <= S.clock) S.index += 1;
    const last = S.samples[S.samples.length - 1];
    if (S.clock > last.t) S.clock = last.t;  // waiting for the next window
    if (!S.pendingMore && last.t - S.clock < 0.5 * WINDOW && S.ws.readyState === WebSocket.OPEN) {
      S.pendingMore = true; S.ws.send(JSON.stringify({ type: 'more' }));
    }
  }
  if (S.index >= 0 && S.index < S.samples.length) {
    const s = S.samples[S.index];
    S.maxError = Math.max(S.maxError, s.error);
    if (shown !== S.index) {
      drawChain(s.hinges); extendPaths();
      const p = spacePoint(s);
      marker.visible = !!p; if (p) marker.position.set(...p);
      if (p && S.aim && S.space.sphere && sphereGroup.visible) {  // a new motion on S^2: turn to where it starts
        const at = new THREE.Vector3(...p).normalize().multiplyScalar(spaceView.camera.position.length());
        spaceView.camera.position.copy(at.add(new THREE.Vector3(0, 0.6, 0))); S.aim = false;
      }
      shown = S.index;
    }
    if (S.metrics.tFlick !== null && S.metrics.flickToFirstFrameMs === null) {
      S.metrics.flickToFirstFrameMs = now - S.metrics.tFlick;
    }
    readouts(s);
  } else if (marker) {  // at rest or dragged: the pose, where the torus of rod angles shows it
    marker.visible = torusGroup.visible && !!S.pose;
    if (marker.visible) marker.position.set(...torusPoint(rodAngles(S.pose)));
  }
  orbit.update();
  chainView.renderer.render(chainView.scene, chainView.camera);
  spaceView.renderer.render(spaceView.scene, spaceView.camera);
  requestAnimationFrame(frame);
}

function passedSwitches() {
  const t = S.index >= 0 ? S.samples[S.index].t : -1;
  return S.switches.filter((sw) => sw.t <= t).length;
}

function readouts(s) {
  $('r-t').textContent = s.t.toFixed(3);
  $('r-energy').textContent = S.maxError.toExponential(2);
  $('r-chart').textContent = s.chart >= 0 ? S.chartIds[s.chart] : 'none (hinge coordinates)';
  $('r-switches').textContent = passedSwitches();
  $('r-method').textContent = S.method; $('r-precision').textContent = S.precision;
  $('r-status').textContent = S.running ? (S.paused ? 'paused' : 'playing') : 'stopped';
}

window.addEventListener('resize', () => { resize(chainView, fitChain); resize(spaceView, (a) => {
  spaceView.camera.aspect = a; spaceView.camera.updateProjectionMatrix(); }); });

// ---------------------------------------------------------------------------------------------- test hook
window.linkageExplorer = {
  state() {
    const s = S.index >= 0 ? S.samples[S.index] : null;
    return { t: s ? s.t : 0, hinges: s ? s.hinges : S.pose, energyError: s ? S.maxError : 0,
             chart: s && s.chart >= 0 ? S.chartIds[s.chart] : null, switches: s ? passedSwitches() : 0,
             running: S.running && !S.paused };
  },
  launch,
  setLength,
  pause() { S.paused = true; $('c-pause').textContent = 'play'; return this.state(); },
  resume() { S.paused = false; $('c-pause').textContent = 'pause'; return this.state(); },
  setSpeed(v) { S.speed = v; $('c-speed').value = v; $('c-speed-out').textContent = sliderText(v); },
  // a test driving the mouse from another process sets a longer hold: its own latency under load is no rest
  setHoldMs(ms) { const old = holdMs; holdMs = ms; return old; },
  // ... and a lower rest speed: under load its pointer steps can arrive in one burst, long after the press
  setRestSpeed(v) { const old = restSpeed; restSpeed = v; return old; },
  lastRelease: () => S.lastRelease,
  hingeScreen: screenOfHinge,
  cubeScreen: screenOfAngles,
  dragPending: () => chainDrag.pending() || spaceDrag.pending(),
  lastLaunch: () => S.lastLaunch,
  space: () => ({ n: S.space.n, L: S.space.L, topology: S.space.topology, builds: S.spaceBuilds,
                  vertices: S.space.sphere ? S.space.sphere.vertices.length : 0,
                  switchMarkers: switchMarkers ? switchMarkers.children.length : 0 }),
  error: () => S.error,
  metrics() {
    const m = S.metrics;
    return { flickToFirstFrameMs: m.flickToFirstFrameMs, fps: m.playSeconds > 0 ? m.frames / m.playSeconds : null,
             flickToLaunchMs: m.tSent - m.tFlick, launchToFirstWindowMs: m.tChunk - m.tSent };
  },
  ready: null,
};

async function start() {
  const config = await (await fetch('/api/config')).json();
  S.chain = { lengths: config.lengths, L: config.L, masses: 1 };
  $('c-lengths').value = Array.isArray(config.lengths) ? config.lengths.join(',') : String(config.lengths);
  resize(spaceView, (a) => { spaceView.camera.aspect = a; spaceView.camera.updateProjectionMatrix(); });
  connect();
  await rebuild();
  await S.wsReady;
  requestAnimationFrame(frame);
}
window.linkageExplorer.ready = start();
