// The orbatlas map viewer (docs/viewer.md): the atlas's maps, the chosen map's
// points and keyframes in 3D, the live sessions' cameras as they are tracked,
// the merges, and the sessions' figures. It polls small routes of the server's
// API (GET /v1/live four times a second; /v1/maps and /v1/merges every two
// seconds) and loads a map's points as a binary buffer, capped in number.
'use strict';
(function () {
  const POINT_CAP = 150000;    // level of detail: at most this many points drawn
  const LIVE_POLL_MS = 250;
  const MAP_POLL_MS = 2000;
  const TRAIL = 600;           // positions kept per live session
  const SESSION_COLOURS = [0xff5533, 0x33ddff, 0xffdd33, 0x66ff66, 0xff66ff, 0xffaa66];

  // What a test (or a person with the console open) can read: the page writes
  // it into <pre id="status"> as JSON after every poll.
  const status = {maps: [], map: null, points: 0, points_total: 0, keyframes: 0, live: [], merges: 0,
                  polls: 0, renders: 0, webgl: false, errors: []};
  window.orbatlasViewer = status;
  const note = (text) => { status.errors.push(text); document.getElementById('message').textContent = text; };
  window.addEventListener('error', (e) => note('error: ' + e.message));
  window.addEventListener('unhandledrejection', (e) => note('error: ' + (e.reason && e.reason.message || e.reason)));
  const consoleError = console.error.bind(console);
  console.error = (...args) => { status.errors.push(args.map(String).join(' ')); consoleError(...args); };

  // The token (GET /?token=T once; kept for the tab) goes on every data request.
  const params = new URLSearchParams(location.search);
  if (params.get('token')) sessionStorage.setItem('orbatlas-token', params.get('token'));
  const token = sessionStorage.getItem('orbatlas-token') || '';
  const headers = token ? {Authorization: 'Bearer ' + token} : {};
  async function get(path, binary) {
    const reply = await fetch(path, {headers});
    if (!reply.ok) {
      let message = reply.status + ' ' + path;
      try { message += ': ' + (await reply.json()).error.message; } catch (_) { /* not JSON */ }
      throw new Error(message);
    }
    return binary ? reply.arrayBuffer() : reply.json();
  }

  // The scene: the map's frame has z up (gravity along -z once known); three.js has y up.
  const view = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
  status.webgl = !!renderer.getContext();
  view.appendChild(renderer.domElement);
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

  // The chosen map.
  let chosen = null;      // map id
  let loaded = {keyframes: -1, points: -1, at: 0};
  let framed = false;

  async function loadPoints(id) {
    const buffer = await get('/v1/maps/' + id + '/points.bin?max=' + POINT_CAP, true);
    if (id !== chosen) return;
    const xyz = new Float32Array(buffer);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(xyz, 3));
    // Coloured by height (z in the map's frame).
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
    layers.points.add(new THREE.Points(geometry, new THREE.PointsMaterial({size: 2, sizeAttenuation: false, vertexColors: true})));
    status.points = xyz.length / 3;
  }

  async function loadKeyframes(id) {
    const reply = await get('/v1/maps/' + id + '/keyframes');
    if (id !== chosen) return;
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
    status.keyframes = reply.keyframes.length;
  }

  function frameMap(summary) {
    if (framed || !summary || !summary.bounds_m) return;
    const b = summary.bounds_m, min = b.min, max = b.max;
    // Map frame (x, y, z) is three.js (x, z, -y) under world's rotation.
    const centre = new THREE.Vector3((min[0] + max[0]) / 2, (min[2] + max[2]) / 2, -(min[1] + max[1]) / 2);
    const size = Math.max(max[0] - min[0], max[1] - min[1], max[2] - min[2], 1);
    controls.target.copy(centre);
    camera.position.set(centre.x + 0.6 * size, centre.y + 0.8 * size, centre.z + 0.9 * size);
    controls.update();
    framed = true;
  }

  function choose(id) {
    chosen = id;
    loaded = {keyframes: -1, points: -1, at: 0};
    framed = false;
    status.map = id;
    clear(layers.points);
    clear(layers.keyframes);
    clear(layers.graph);
    for (const li of document.querySelectorAll('#maps li')) li.classList.toggle('chosen', Number(li.dataset.map) === id);
    refreshMaps().catch((e) => note(e.message));
  }

  async function refreshMaps() {
    const reply = await get('/v1/maps');
    status.maps = reply.maps.map((m) => m.id);
    const list = document.getElementById('maps');
    list.innerHTML = '';
    for (const m of reply.maps) {
      const li = document.createElement('li');
      li.dataset.map = m.id;
      li.textContent = 'map ' + m.id + ': ' + m.keyframes + ' keyframes, ' + m.map_points + ' points' +
                       (m.live_session !== undefined && m.live_session !== null ? ' (live)' : '');
      li.classList.toggle('chosen', m.id === chosen);
      li.addEventListener('click', () => choose(m.id));
      list.appendChild(li);
    }
    if (chosen === null || !status.maps.includes(chosen)) {
      if (!reply.maps.length) return;
      const wanted = Number(params.get('map'));
      chosen = status.maps.includes(wanted) ? wanted : reply.maps[0].id;
      status.map = chosen;
      loaded = {keyframes: -1, points: -1, at: 0};
      framed = false;
    }
    const summary = reply.maps.find((m) => m.id === chosen);
    status.points_total = summary.map_points;
    frameMap(summary);
    // A growing map is reloaded at most every few seconds.
    const now = performance.now();
    if ((summary.keyframes !== loaded.keyframes || summary.map_points !== loaded.points) &&
        (loaded.at === 0 || now - loaded.at > 4000)) {
      loaded = {keyframes: summary.keyframes, points: summary.map_points, at: now};
      await Promise.all([loadPoints(chosen), loadKeyframes(chosen)]);
    }
  }

  async function refreshMerges() {
    const reply = await get('/v1/merges');
    const all = (reply.merges || []).concat(reply.live_merges || []);
    status.merges = all.length;
    const list = document.getElementById('merges');
    list.innerHTML = '';
    for (const m of all.slice(-8)) {
      const li = document.createElement('li');
      li.textContent = 'map ' + m.source_map + ' into map ' + m.target_map +
                       (m.session !== undefined ? ' (live, session ' + m.session + ')' : '');
      list.appendChild(li);
    }
    if (!all.length) list.innerHTML = '<li>none yet</li>';
  }

  // Live sessions: a frustum and a trail each, in the chosen map.
  const trails = new Map();  // session id -> {points: [], frames, t}
  async function refreshLive() {
    const reply = await get('/v1/live');
    status.polls += 1;
    clear(layers.live);
    const rows = [];
    status.live = [];
    for (const s of reply.sessions) {
      const colour = SESSION_COLOURS[s.id % SESSION_COLOURS.length];
      let trail = trails.get(s.id);
      if (!trail) trails.set(s.id, trail = {points: [], frames: s.frames, t: performance.now(), fps: 0});
      const now = performance.now();
      if (now - trail.t > 1000) {
        trail.fps = (s.frames - trail.frames) * 1000 / (now - trail.t);
        trail.frames = s.frames;
        trail.t = now;
      }
      status.live.push({id: s.id, map: s.map, pose: s.pose ? s.pose.p : null});
      if (s.pose && s.map === chosen) {
        const last = trail.points.slice(-3);
        if (!last.length || last[0] !== s.pose.p[0] || last[1] !== s.pose.p[1] || last[2] !== s.pose.p[2])
          trail.points.push(...s.pose.p);
        if (trail.points.length > 3 * TRAIL) trail.points.splice(0, trail.points.length - 3 * TRAIL);
        const marker = [];
        frustum(marker, s.pose.p, s.pose.q, 0.25);
        layers.live.add(segments(marker, colour));
        if (trail.points.length >= 6) {
          const geometry = new THREE.BufferGeometry();
          geometry.setAttribute('position', new THREE.Float32BufferAttribute(trail.points, 3));
          layers.live.add(new THREE.Line(geometry, new THREE.LineBasicMaterial({color: colour})));
        }
      }
      rows.push('<tr><td>' + s.id + ' ' + escapeHtml(s.name) + '</td><td>' + (s.map === null ? '-' : s.map) +
                '</td><td>' + s.frames + '</td><td>' + s.tracked + '</td><td>' + s.skipped_frames + '</td><td>' +
                (s.tracking_p50_ms === null ? '-' : s.tracking_p50_ms.toFixed(1)) + '</td><td>' +
                trail.fps.toFixed(1) + '</td></tr>');
    }
    document.querySelector('#sessions tbody').innerHTML = rows.join('') ||
        '<tr><td colspan="7">no live session</td></tr>';
    document.getElementById('status').textContent = JSON.stringify(status);
  }

  function escapeHtml(text) {
    return String(text).replace(/[&<>"']/g, (c) => ({'&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;',
                                                       "'": '&#39;'}[c]));
  }

  for (const [box, layer] of [['show-points', 'points'], ['show-keyframes', 'keyframes'], ['show-graph', 'graph']]) {
    const input = document.getElementById(box);
    const apply = () => { layers[layer].visible = input.checked; };
    input.addEventListener('change', apply);
    apply();
  }

  // Polling loops: each waits for its reply before the next (no pile-up on a slow server).
  function every(ms, task) {
    const run = () => task().catch((e) => note(e.message)).finally(() => setTimeout(run, ms));
    run();
  }
  every(MAP_POLL_MS, async () => { await refreshMaps(); await refreshMerges(); });
  every(LIVE_POLL_MS, refreshLive);

  function draw() {
    controls.update();
    renderer.render(scene, camera);
    status.renders += 1;
    requestAnimationFrame(draw);
  }
  draw();
})();
