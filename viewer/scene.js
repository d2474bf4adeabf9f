// The viewer's 3D view (docs/viewer.md): a three.js scene of the chosen map's
// points, keyframes, spanning tree and loops, and the live sessions' cameras and
// trails. createMapScene(view) throws when the browser cannot draw (no WebGL);
// the page (app.js) then keeps its side panel and says why the view is empty.
'use strict';
window.createMapScene = function createMapScene(view) {
  if (typeof THREE === 'undefined' || !THREE.OrbitControls) {
    const error = new Error("the 3D view's scripts (three.js) did not load");
    error.scriptsMissing = true;
    throw error;
  }
  // three.js reports a failed context through console.error before it throws;
  // that message is the reason, not an error of the page.
  const said = [];
  const consoleError = console.error;
  console.error = (...args) => said.push(args.map(String).join(' '));
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
    if (!renderer.getContext()) throw new Error('no WebGL context');
  } catch (e) {
    throw new Error([e.message].concat(said.filter((s) => !s.includes(e.message))).join('; '));
  } finally {
    console.error = consoleError;
  }
  view.appendChild(renderer.domElement);

  // The map's frame has z up (gravity along -z once known); three.js has y up.
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x111114);
  const camera = new THREE.PerspectiveCamera(55, 1, 0.05, 1000);
  camera.position.set(8, 10, 14);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  const world = new THREE.Group();
  world.rotation.x = -Math.PI / 2;
  scene.add(world);
  scene.add(new THREE.GridHelper(40, 40, 0x333340, 0x222228));
  const layers = {points: new THREE.Group(), keyframes: new THREE.Group(), graph: new THREE.Group(),
                  live: new THREE.Group()};
  for (const layer of Object.values(layers)) world.add(layer);

  function resize() {
    const w = Math.max(1, view.clientWidth), h = Math.max(1, view.clientHeight);
    renderer.setSize(w, h);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
  window.addEventListener('resize', resize);
  resize();

  function clear(group) {
    while (group.children.length) {
      const child = group.children.pop();
      if (child.geometry) child.geometry.dispose();
      if (child.material) child.material.dispose();
    }
  }

  // A camera frustum's 8 segments (16 vertices) at position p, rotation q = [w, x, y, z].
  function frustum(out, p, q, size) {
    const quat = new THREE.Quaternion(q[1], q[2], q[3], q[0]);
    const c = new THREE.Vector3(p[0], p[1], p[2]);
    const corners = [[-1, -0.75], [1, -0.75], [1, 0.75], [-1, 0.75]].map(([x, y]) =>
      new THREE.Vector3(x * size, y * size, size * 1.2).applyQuaternion(quat).add(c));
    for (let i = 0; i < 4; ++i) {
      out.push(c.x, c.y, c.z, corners[i].x, corners[i].y, corners[i].z);
      const n = corners[(i + 1) % 4];
      out.push(corners[i].x, corners[i].y, corners[i].z, n.x, n.y, n.z);
    }
  }

  function segments(vertices, colour) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.Float32BufferAttribute(vertices, 3));
    return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({color: colour}));
  }

  const api = {
    // The map's points (x, y, z floats), coloured by height (z in the map's frame).
    showPoints(xyz) {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(xyz, 3));
      let lo = Infinity, hi = -Infinity;
      for (let i = 2; i < xyz.length; i += 3) { lo = Math.min(lo, xyz[i]); hi = Math.max(hi, xyz[i]); }
      const colours = new Float32Array(xyz.length);
      const colour = new THREE.Color();
      for (let i = 0; i < xyz.length; i += 3) {
        const t = hi > lo ? (xyz[i + 2] - lo) / (hi - lo) : 0.5;
        colour.setHSL(0.62 - 0.55 * t, 0.6, 0.55);
        colours[i] = colour.r; colours[i + 1] = colour.g; colours[i + 2] = colour.b;
      }
      geometry.setAttribute('color', new THREE.BufferAttribute(colours, 3));
      clear(layers.points);
      layers.points.add(new THREE.Points(geometry, new THREE.PointsMaterial({size: 2, sizeAttenuation: false,
                                                                              vertexColors: true})));
    },

    // The keyframes (GET /v1/maps/{id}/keyframes): frusta, spanning tree, loop edges.
    showKeyframes(reply) {
      const frusta = [], tree = [], loops = [];
      const where = new Map();
      for (const kf of reply.keyframes) {
        frustum(frusta, kf.p, kf.q, 0.08);
        where.set(kf.id, kf.p);
      }
      for (const kf of reply.keyframes) {
        const parent = kf.parent === null ? undefined : where.get(kf.parent);
        if (parent) tree.push(...kf.p, ...parent);
      }
      for (const [a, b] of reply.loop_edges) {
        if (where.has(a) && where.has(b)) loops.push(...where.get(a), ...where.get(b));
      }
      clear(layers.keyframes);
      clear(layers.graph);
      layers.keyframes.add(segments(frusta, 0x5588ff));
      layers.graph.add(segments(tree, 0x33aa55));
      layers.graph.add(segments(loops, 0xff3355));
    },

    clearMap() {
      clear(layers.points);
      clear(layers.keyframes);
      clear(layers.graph);
    },

    // Looks at a map's bounds (GET /v1/maps: bounds_m {min, max}).
    frame(bounds) {
      const min = bounds.min, max = bounds.max;
      // Map frame (x, y, z) is three.js (x, z, -y) under world's rotation.
      const centre = new THREE.Vector3((min[0] + max[0]) / 2, (min[2] + max[2]) / 2, -(min[1] + max[1]) / 2);
      const size = Math.max(max[0] - min[0], max[1] - min[1], max[2] - min[2], 1);
      controls.target.copy(centre);
      camera.position.set(centre.x + 0.6 * size, centre.y + 0.8 * size, centre.z + 0.9 * size);
      controls.update();
    },

    // The live sessions in the chosen map: [{colour, pose: {p, q}, trail: [x, y, z, ...]}].
    showLive(sessions) {
      clear(layers.live);
      for (const s of sessions) {
        const marker = [];
        frustum(marker, s.pose.p, s.pose.q, 0.25);
        layers.live.add(segments(marker, s.colour));
        if (s.trail.length >= 6) {
          const geometry = new THREE.BufferGeometry();
          geometry.setAttribute('position', new THREE.Float32BufferAttribute(s.trail, 3));
          layers.live.add(new THREE.Line(geometry, new THREE.LineBasicMaterial({color: s.colour})));
        }
      }
    },

    setVisible(layer, visible) { layers[layer].visible = visible; },

    // Draws on every animation frame; onFrame runs after each.
    start(onFrame) {
      const draw = () => {
        controls.update();
        renderer.render(scene, camera);
        onFrame();
        requestAnimationFrame(draw);
      };
      draw();
    },
  };
  return api;
};
