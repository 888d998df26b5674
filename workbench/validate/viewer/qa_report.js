// qa_report.html's page: the part in 3D (three.js), its defects as numbered markers, its coverage
// as a second texture layer, the photos with their circles and each defect's close-ups.
// The page says how it went on <body>: data-loaded ("part" once the part is drawn, "no-webgl"),
// data-markers-drawn (markers inside the view), data-markers (each marker's place, CSS px)
// and data-error (the first error, if any).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const body = document.body;
const data = JSON.parse(document.getElementById('qa-data').textContent);

function fail(message) {
  if (!body.dataset.error) body.dataset.error = String(message);
}
window.addEventListener('error', (event) => fail(event.message));
window.addEventListener('unhandledrejection', (event) => fail(event.reason));

function element(tag, text, attributes = {}) {
  const node = document.createElement(tag);
  if (text !== undefined && text !== null) node.textContent = text;
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  return node;
}

// --- the verdict, the table, the photos ------------------------------------------------------
const verdict = document.getElementById('verdict');
verdict.textContent = data.verdict;
verdict.classList.add(data.verdict);
document.getElementById('reason').textContent = data.reason;
document.getElementById('figures').textContent =
  `${data.photos_scored} photo(s) scored; tolerance ${data.tolerance_mm} mm, ` +
  `largest accepted defect ${data.max_defect_mm2} mm²; positions in print mm from the film's top-left corner, y down.`;

const rows = new Map();
const markers = new Map();
const tbody = document.querySelector('#defects tbody');
for (const d of data.defects) {
  const row = element('tr', null, { 'data-defect': d.number, tabindex: '0' });
  const cells = [
    d.number, d.kind, d.area_mm2.toFixed(2), `${d.centre_mm[0].toFixed(1)}, ${d.centre_mm[1].toFixed(1)}`,
    d.view ?? '', d.photos.join(', '),
  ];
  for (const text of cells) row.appendChild(element('td', String(text)));
  row.addEventListener('click', () => select(d.number));
  row.addEventListener('keydown', (event) => { if (event.key === 'Enter') select(d.number); });
  tbody.appendChild(row);
  rows.set(d.number, row);
}
const none = document.getElementById('no-defects');
none.hidden = data.defects.length > 0;
if (!data.photos_scored) none.textContent = 'No photo was scored: no defect was sought.';

function select(number, scroll = true) {
  const d = data.defects.find((x) => x.number === number);
  for (const [n, row] of rows) row.classList.toggle('selected', n === number);
  for (const [n, marker] of markers) marker.classList.toggle('selected', n === number);
  const pane = document.getElementById('closeups');
  pane.replaceChildren();
  pane.appendChild(element('h2', `Defect ${d.number}: ${d.kind}, ${d.area_mm2.toFixed(2)} mm² at ` +
    `(${d.centre_mm[0].toFixed(1)}, ${d.centre_mm[1].toFixed(1)}) mm on the print`));
  if (!d.closeups.length) pane.appendChild(element('p', 'No picture shows it closer.'));
  const shots = element('div', null, { class: 'shots' });
  for (const c of d.closeups) {
    const figure = element('figure');
    figure.appendChild(element('img', null, { src: c.src, alt: c.label }));
    figure.appendChild(element('figcaption', c.label));
    shots.appendChild(figure);
  }
  pane.appendChild(shots);
  if (scroll) pane.scrollIntoView({ block: 'nearest' });
}

const photos = document.getElementById('photos');
const shots = element('div', null, { class: 'shots' });
for (const p of data.photos) {
  const figure = element('figure');
  if (p.src) figure.appendChild(element('img', null, { src: p.src, alt: `${p.name}, its defects circled` }));
  figure.appendChild(element('figcaption', `${p.name}: ${p.verdict}${p.reason ? ': ' + p.reason : ''}`));
  shots.appendChild(figure);
}
photos.appendChild(shots);

const legend = document.getElementById('legend');
for (const item of data.legend) {
  const entry = element('span');
  entry.appendChild(element('span', null, { class: 'swatch', style: `background:${item.colour}` }));
  entry.appendChild(document.createTextNode(`${item.name}: ${(100 * item.share).toFixed(1)} %`));
  legend.appendChild(entry);
}

// --- the part in 3D ----------------------------------------------------------------------------
const viewer = document.getElementById('viewer');
const canvas = document.getElementById('part');
const overlay = document.getElementById('markers');

function note(text) {
  const p = document.getElementById('viewer-note');
  p.textContent = text;
  p.hidden = false;
}

async function start() {
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
  } catch (error) {
    note('This browser gives the page no WebGL: the part is not drawn. The defects and photos are complete.');
    body.dataset.loaded = 'no-webgl';
    return;
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xeef0f3);
  const camera = new THREE.PerspectiveCamera(30, 1, 1, 1e5);
  camera.up.fromArray(data.camera.up).normalize();
  camera.position.fromArray(data.camera.position);
  scene.add(camera);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x808080, 2.0));
  const lamp = new THREE.DirectionalLight(0xffffff, 1.2);
  lamp.position.set(0.3, 0.5, 1);
  camera.add(lamp); // a lamp at the eye: every face the camera sees is lit
  const controls = new OrbitControls(camera, canvas);
  controls.target.fromArray(data.camera.target);
  controls.update();
  controls.saveState();

  const layers = {};
  let part = null;
  const raycaster = new THREE.Raycaster();
  const points = data.defects.filter((d) => d.point).map((d) => ({ d, at: new THREE.Vector3().fromArray(d.point) }));
  for (const { d } of points) {
    const marker = element('button', String(d.number), { class: 'marker', type: 'button', title: `defect ${d.number}: ${d.kind}` });
    marker.addEventListener('click', () => select(d.number));
    overlay.appendChild(marker);
    markers.set(d.number, marker);
  }

  function render() {
    renderer.render(scene, camera);
    const width = canvas.clientWidth, height = canvas.clientHeight;
    const placed = [];
    for (const { d, at } of points) {
      const marker = markers.get(d.number);
      const p = at.clone().project(camera);
      const inside = p.z > -1 && p.z < 1 && Math.abs(p.x) <= 1 && Math.abs(p.y) <= 1;
      marker.hidden = !inside;
      if (!inside) continue;
      const x = (p.x + 1) / 2 * width, y = (1 - p.y) / 2 * height;
      marker.style.left = `${x}px`;
      marker.style.top = `${y}px`;
      // behind the part: the surface is hit first on the way from the eye to the point
      let behind = false;
      if (part) {
        const direction = at.clone().sub(camera.position);
        const distance = direction.length();
        raycaster.set(camera.position, direction.normalize());
        const hit = raycaster.intersectObject(part, true)[0];
        behind = hit !== undefined && hit.distance < distance - 0.01 * distance;
      }
      marker.classList.toggle('behind', behind);
      const box = viewer.getBoundingClientRect();
      placed.push({ number: d.number, x: Math.round(box.left + window.scrollX + canvas.clientLeft + x),
        y: Math.round(box.top + window.scrollY + canvas.clientTop + y), behind });
    }
    body.dataset.markersDrawn = String(placed.length);
    body.dataset.markers = JSON.stringify(placed);
  }

  function resize() {
    const width = canvas.clientWidth, height = canvas.clientHeight;
    if (!width || !height) return;
    renderer.setSize(width, height, false);
    camera.aspect = width / height;
    camera.updateProjectionMatrix();
    render();
  }
  new ResizeObserver(resize).observe(viewer);
  controls.addEventListener('change', render);
  document.getElementById('reset').addEventListener('click', () => { controls.reset(); render(); });

  const buttons = document.querySelectorAll('#toolbar button[data-layer]');
  function show(layer) {
    for (const [name, node] of Object.entries(layers)) node.visible = name === layer;
    for (const b of buttons) b.setAttribute('aria-pressed', String(b.dataset.layer === layer));
    legend.hidden = layer !== 'coverage';
    render();
  }
  for (const b of buttons) b.addEventListener('click', () => show(b.dataset.layer));

  const glb = await window.qaGunzip(document.getElementById('qa-glb').textContent);
  new GLTFLoader().parse(glb, '', (gltf) => {
    part = gltf.scene;
    for (const name of ['print', 'coverage']) {
      const node = part.getObjectByName(name);
      if (node) layers[name] = node;
    }
    document.querySelector('#toolbar button[data-layer="coverage"]').disabled = !layers.coverage;
    scene.add(part);
    // from where the photo was taken, at the distance where the part fills the view (its bounding
    // sphere's, a little less: seen at a slant, a flat part leaves the sphere's rim empty)
    const size = new THREE.Box3().setFromObject(part).getSize(new THREE.Vector3()).length();
    resize();
    const half = THREE.MathUtils.degToRad(camera.fov / 2);
    const fit = 0.8 * (size / 2) / Math.sin(Math.min(half, Math.atan(Math.tan(half) * camera.aspect)));
    const away = camera.position.clone().sub(controls.target).normalize();
    camera.position.copy(controls.target).addScaledVector(away, fit);
    camera.near = fit / 100;
    camera.far = 100 * fit;
    camera.updateProjectionMatrix();
    controls.update();
    controls.saveState();
    show('print');
    if (data.defects.length) select(data.defects[0].number, false);
    body.dataset.loaded = 'part';
  }, (error) => {
    note('The part could not be drawn: ' + (error && error.message ? error.message : error));
    fail(error && error.message ? error.message : error);
  });
}

start().catch((error) => fail(error && error.message ? error.message : error));
