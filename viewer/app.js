// The orbatlas map viewer (docs/viewer.md): the atlas's maps, the chosen map's
// points and keyframes in 3D, the live sessions' cameras as they are tracked,
// the merges, and the sessions' figures. It polls small routes of the server's
// API (GET /v1/live four times a second; /v1/maps and /v1/merges every two
// seconds) and loads a map's points as a binary buffer, capped in number. The
// 3D drawing is scene.js's; without WebGL the page works without it.
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
                  polls: 0, renders: 0, webgl: false, no_3d: null, errors: []};
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

  // The 3D view, where the browser can draw it (WebGL); without it the side
  // panel still lists the maps, live sessions and merges, and the view says why
  // it is empty.
  const view = document.getElementById('view');
  let scene = null;
  try {
    scene = window.createMapScene(view);
    status.webgl = true;
  } catch (e) {
    status.no_3d = (e.scriptsMissing ? 'No 3D view: ' + e.message + ' (reload the page). '
                                     : 'No 3D view: this browser cannot draw with WebGL (' + e.message + '). ') +
                   'The maps, live sessions and merges are listed on the left.';
    const reason = document.createElement('p');
    reason.id = 'no-3d';
    reason.textContent = status.no_3d;
    view.appendChild(reason);
  }

  // The chosen map.
  let chosen = null;      // map id
  let loaded = {keyframes: -1, points: -1, at: 0};
  let framed = false;

  async function loadPoints(id) {
    const buffer = await get('/v1/maps/' + id + '/points.bin?max=' + POINT_CAP, true);
    if (id !== chosen) return;
    const xyz = new Float32Array(buffer);
    scene.showPoints(xyz);
    status.points = xyz.length / 3;
  }

  async function loadKeyframes(id) {
    const reply = await get('/v1/maps/' + id + '/keyframes');
    if (id !== chosen) return;
    scene.showKeyframes(reply);
    status.keyframes = reply.keyframes.length;
  }

  function frameMap(summary) {
    if (framed || !scene || !summary || !summary.bounds_m) return;
    scene.frame(summary.bounds_m);
    framed = true;
  }

  function choose(id) {
    chosen = id;
    loaded = {keyframes: -1, points: -1, at: 0};
    framed = false;
    status.map = id;
    if (scene) scene.clearMap();
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
    // A growing map is reloaded at most every few seconds (only to be drawn).
    const now = performance.now();
    if (scene && (summary.keyframes !== loaded.keyframes || summary.map_points !== loaded.points) &&
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
    const rows = [], drawn = [];
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
        drawn.push({colour, pose: s.pose, trail: trail.points});
      }
      rows.push('<tr><td>' + s.id + ' ' + escapeHtml(s.name) + '</td><td>' + (s.map === null ? '-' : s.map) +
                '</td><td>' + s.frames + '</td><td>' + s.tracked + '</td><td>' + s.skipped_frames + '</td><td>' +
                (s.tracking_p50_ms === null ? '-' : s.tracking_p50_ms.toFixed(1)) + '</td><td>' +
                trail.fps.toFixed(1) + '</td></tr>');
    }
    if (scene) scene.showLive(drawn);
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
    input.disabled = !scene;
    const apply = () => { if (scene) scene.setVisible(layer, input.checked); };
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

  if (scene) scene.start(() => { status.renders += 1; });
})();
