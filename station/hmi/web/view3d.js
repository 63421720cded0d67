// The panel's 3D views (three.js, Debian's libjs-three): one factory for the result's strain map,
// the live cloud of a scan and the two views of a comparison, so that they turn, zoom and draw alike.
'use strict';

// Thinning and strain colours: blue, cyan, green, yellow, red (the report's temperature map).
function ramp(t) {
  const stops = [[0.13, 0.25, 1], [0.13, 0.82, 1], [0.19, 0.88, 0.19], [0.94, 0.88, 0.13], [1, 0.13, 0.13]];
  const x = Math.min(Math.max(t, 0), 1) * (stops.length - 1);
  const i = Math.min(Math.floor(x), stops.length - 2);
  const f = x - i;
  return stops[i].map((a, k) => a + (stops[i + 1][k] - a) * f);
}
// Where a surface carries no strain (beyond the printed grid: the JSON has null there): grey.
const kNoStrainColour = [0.35, 0.35, 0.35];
// Thinning in % from thickness true strain; null where there is none.
function thinningOf(s) { return s === null || s === undefined || !Number.isFinite(s) ? null : (1 - Math.exp(s)) * 100; }
// The range of the values that are there, widened to include 0 and 1 %; by a loop, not Math.min(...v):
// a surface has more vertices than a call may take arguments.
function thinningRange(values, lo = 0, hi = 1) {
  for (const t of values) if (t !== null) { lo = Math.min(lo, t); hi = Math.max(hi, t); }
  return [lo, hi];
}
function thinningColours(thinning, lo, hi) {
  const colours = [];
  for (const t of thinning) colours.push(...(t === null ? kNoStrainColour : ramp((t - lo) / (hi - lo))));
  return colours;
}
// Differences: blue below zero, white at zero, red above (t in -1..1).
function divergingRamp(t) {
  const c = Math.min(Math.max(t, -1), 1);
  return c < 0 ? [1 + c * 0.87, 1 + c * 0.7, 1] : [1, 1 - c * 0.8, 1 - c * 0.87];
}

// A view in element `el`: drag to turn, pinch or wheel to zoom; `onTap(event)` for a tap that is
// not a drag. Drawn when something changes, not every frame: the panel PC also runs the scan.
// Returns null (and says so in the element) when the browser has no WebGL.
function makeView(el, onTap) {
  let renderer;
  try { renderer = new THREE.WebGLRenderer({ antialias: true }); } catch (e) {
    el.textContent = 'This browser cannot show 3D (WebGL is off); the PDF report has the maps.';
    return null;
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  el.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x0b0d10);
  const camera = new THREE.PerspectiveCamera(40, 1, 0.1, 10000);
  camera.up.set(0, 0, 1);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 1.0));
  const light = new THREE.DirectionalLight(0xffffff, 0.5);
  light.position.set(1, -1, 2);
  scene.add(light);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  const v = { el, renderer, scene, camera, controls, framed: false };
  let queued = false;
  v.draw = () => {
    if (queued) return;
    queued = true;
    requestAnimationFrame(() => { queued = false; renderer.render(scene, camera); });
  };
  v.resize = () => {
    if (!el.clientWidth) return;  // on a hidden tab: sized when shown
    renderer.setSize(el.clientWidth, el.clientHeight);
    camera.aspect = el.clientWidth / Math.max(el.clientHeight, 1);
    camera.updateProjectionMatrix();
    v.draw();
  };
  // Looks at a bounding sphere from the front, above and to the side.
  v.frame = (sphere) => {
    controls.target.copy(sphere.center);
    camera.position.set(sphere.center.x + sphere.radius * 1.2, sphere.center.y - sphere.radius * 1.8, sphere.center.z + sphere.radius * 1.8);
    camera.far = Math.max(10000, sphere.radius * 20);
    camera.updateProjectionMatrix();
    controls.update();
    v.framed = true;
  };
  // Replaces a named object of the scene (its geometry freed).
  v.put = (name, object) => {
    if (v[name] === object) return;
    if (v[name]) { scene.remove(v[name]); v[name].geometry.dispose(); }
    v[name] = object;
    if (object) scene.add(object);
    v.draw();
  };
  controls.addEventListener('change', v.draw);
  window.addEventListener('resize', v.resize);
  if (onTap) {
    // A tap picks; a drag turns the view (OrbitControls) and picks nothing.
    let down = null;
    renderer.domElement.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
    renderer.domElement.addEventListener('pointerup', (e) => {
      if (down && Math.abs(e.clientX - down[0]) + Math.abs(e.clientY - down[1]) <= 6) onTap(e);
      down = null;
    });
  }
  v.resize();
  return v;
}

// A mesh coloured per vertex: positions and indices as the API gives them, colours [r, g, b] each.
function colouredMesh(positions, indices, colours) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(positions, 3));
  g.setIndex(indices);
  g.computeVertexNormals();
  g.setAttribute('color', new THREE.Float32BufferAttribute(colours, 3));
  g.computeBoundingSphere();
  return new THREE.Mesh(g, new THREE.MeshLambertMaterial({ vertexColors: THREE.VertexColors, side: THREE.DoubleSide }));
}
