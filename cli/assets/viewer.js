// animcodec viewer: plays a reference animation and candidates side by side with one shared
// camera, each candidate coloured by its per-vertex error; and the rate-distortion report of
// `animcodec sweep --html`. Data layout: see cli/src/viewer.rs. Rendering is three.js's.

const HEAT_STOPS = [
  [0.0, [0.12, 0.22, 0.85]],
  [0.25, [0.05, 0.75, 0.9]],
  [0.5, [0.2, 0.8, 0.25]],
  [0.75, [0.98, 0.85, 0.1]],
  [1.0, [0.9, 0.1, 0.08]],
];

function heatColor(t) {
  for (let i = 1; i < HEAT_STOPS.length; i++) {
    const [t1, c1] = HEAT_STOPS[i];
    if (t <= t1) {
      const [t0, c0] = HEAT_STOPS[i - 1];
      const u = (t - t0) / (t1 - t0);
      return c0.map((x, k) => x + u * (c1[k] - x));
    }
  }
  return HEAT_STOPS[HEAT_STOPS.length - 1][1];
}

const HEAT_LUT = (() => {
  const lut = new Float32Array(256 * 3);
  for (let i = 0; i < 256; i++) lut.set(heatColor(i / 255), 3 * i);
  return lut;
})();

function base64Bytes(text) {
  const bin = atob(text);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

// zlib data (RFC 1950) inflated by the browser's own DecompressionStream.
async function inflate(text) {
  const stream = new Blob([base64Bytes(text)]).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

function fmt(x, digits = 4) {
  if (x === null || x === undefined) return 'n/a';
  if (typeof x !== 'number') return String(x);
  if (Number.isInteger(x) && Math.abs(x) < 1e12) return String(x);
  const a = Math.abs(x);
  return a >= 1e-3 && a < 1e5 ? x.toPrecision(digits) : x.toExponential(digits - 1);
}

function el(tag, attrs = {}, children = []) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === 'text') e.textContent = v;
    else if (k === 'class') e.className = v;
    else e.setAttribute(k, v);
  }
  for (const c of children) e.appendChild(c);
  return e;
}

function headerLines(anim) {
  const lines = [];
  const info = anim.info || {};
  const first = ['codec', 'params', 'bytes', 'bpvf'];
  const keys = [...first.filter((k) => k in info), ...Object.keys(info).filter((k) => !first.includes(k))];
  // Parameters as `k=v` on a line of their own (hosvd has 21), the rest on one line.
  const simple = keys.filter((k) => k !== 'params' || typeof info[k] !== 'object' || info[k] === null);
  if (simple.length) {
    lines.push(simple.map((k) => `${k} ${typeof info[k] === 'object' ? JSON.stringify(info[k]) : fmt(info[k])}`).join(' · '));
  }
  if (info.params && typeof info.params === 'object') {
    lines.push(Object.entries(info.params).map(([k, v]) => `${k}=${typeof v === 'object' ? JSON.stringify(v) : v}`).join(' '));
  }
  if (anim.metrics) {
    const m = anim.metrics;
    lines.push(`KG ${fmt(m.kg)} % · STED ${fmt(m.sted)} · Hausdorff ${fmt(m.hausdorff)} · RMSE ${fmt(m.rmse)}`);
    // Issue 41: with several parts, the worst one's KG against its own spread.
    if (m.parts > 1) lines.push(`worst of ${m.parts} parts: KG ${fmt(m.worst_part_kg)} % of its own spread`);
  }
  return lines;
}

async function mountViewer(root, data, THREE, OrbitControls) {
  root.classList.add('viewer');
  root.innerHTML = '';
  const status = el('div', { class: 'status', text: 'loading…' });
  root.appendChild(status);
  const started = performance.now();
  const V = data.vertex_count;
  const F = data.frame_count;
  const lo = data.box_min;
  const hi = data.box_max;
  const step = [0, 1, 2].map((k) => (hi[k] - lo[k]) / 65535);

  const triBytes = await inflate(data.triangles);
  const index = new Uint32Array(triBytes.buffer, triBytes.byteOffset, triBytes.byteLength / 4);
  const anims = [];
  for (const a of data.animations) {
    const bytes = await inflate(a.positions);
    const q = new Uint16Array(bytes.buffer, bytes.byteOffset, bytes.byteLength / 2);
    const per = V * 3;
    if (q.length !== per * F) throw new Error(`${a.label}: ${q.length} coordinates, expected ${per * F}`);
    for (let i = per; i < q.length; i++) q[i] = q[i] + q[i - per]; // undo the frame deltas (wrapping u16)
    const heat = a.heat ? await inflate(a.heat) : null;
    anims.push({ meta: a, q, heat });
  }

  // Per-frame centre and size of the reference: an animation that travels (a walk across
  // the scene) is followed by the camera, framed by its own size rather than the whole path.
  const centres = new Float32Array(F * 3);
  const frameHalf = [0, 0, 0]; // largest half-extent of one frame, per axis
  const refLo = [Infinity, Infinity, Infinity];
  const refHi = [-Infinity, -Infinity, -Infinity];
  {
    const q = anims[0].q;
    for (let f = 0; f < F; f++) {
      const mn = [Infinity, Infinity, Infinity];
      const mx = [-Infinity, -Infinity, -Infinity];
      for (let j = 0; j < V * 3; j++) {
        const k = j % 3;
        const x = q[f * V * 3 + j];
        if (x < mn[k]) mn[k] = x;
        if (x > mx[k]) mx[k] = x;
      }
      for (let k = 0; k < 3; k++) {
        centres[3 * f + k] = lo[k] + 0.5 * (mn[k] + mx[k]) * step[k];
        frameHalf[k] = Math.max(frameHalf[k], 0.5 * (mx[k] - mn[k]) * step[k]);
        refLo[k] = Math.min(refLo[k], lo[k] + mn[k] * step[k]);
        refHi[k] = Math.max(refHi[k], lo[k] + mx[k] * step[k]);
      }
    }
  }

  // Layout: controls, a grid of panels over one canvas, the colour bar.
  const controls = el('div', { class: 'controls' });
  const play = el('button', { text: 'pause', title: 'play / pause (space)' });
  const slider = el('input', { type: 'range', min: '0', max: String(F - 1), value: '0', step: '1', 'aria-label': 'frame' });
  const frameLabel = el('span', { class: 'frame-label' });
  const speed = el('select', { 'aria-label': 'speed' });
  for (const s of [0.25, 0.5, 1, 2, 4]) speed.appendChild(el('option', { value: String(s), text: `${s}×` }));
  speed.value = '1';
  const reset = el('button', { text: 'reset camera' });
  const heatToggle = el('input', { type: 'checkbox', checked: '' });
  const followToggle = el('input', { type: 'checkbox' });
  controls.append(play, slider, frameLabel, el('label', { text: 'speed ' }, [speed]), reset,
    el('label', { class: 'heat-toggle', text: ' heat map' }, [heatToggle]),
    el('label', { class: 'follow-toggle', text: ' follow' }, [followToggle]));
  const title = el('div', { class: 'title', text: data.title || '' });
  const stage = el('div', { class: 'stage' });
  const canvas = el('canvas', { class: 'gl' });
  const grid = el('div', { class: 'grid' });
  stage.append(canvas, grid);
  const cols = Math.min(anims.length, 3);
  grid.style.gridTemplateColumns = `repeat(${cols}, minmax(0, 1fr))`;
  const panels = anims.map((a, i) => {
    const p = el('div', { class: 'panel', 'data-index': String(i) });
    p.appendChild(el('div', { class: 'panel-title', text: a.meta.label }));
    for (const line of headerLines(a.meta)) p.appendChild(el('div', { class: 'panel-info', text: line }));
    grid.appendChild(p);
    return p;
  });
  const bar = el('div', { class: 'colorbar' });
  const unit = data.heat_unit;
  const maxText = (data.heat_metric === 'euclidean'
    ? `≥ ${fmt(data.heat_max)} ${unit} = ${fmt((100 * data.heat_max) / data.diagonal)} % of the bounding-box diagonal`
    : `≥ ${fmt(data.heat_max)} (${unit})`) + ` [${data.heat_max_rule}; largest ${fmt(data.heat_largest)}]`;
  // The ramp with five labelled ticks (0, ¼, ½, ¾ and all of the top value), then what the
  // top means.
  const rampBox = el('div', { class: 'ramp-box' }, [el('div', { class: 'ramp' })]);
  const ticks = el('div', { class: 'ticks' });
  for (let i = 0; i <= 4; i++) {
    const t = el('span', { class: 'tick', text: fmt((i / 4) * data.heat_max, 3) });
    t.style.left = `${25 * i}%`;
    ticks.appendChild(t);
  }
  rampBox.appendChild(ticks);
  bar.append(rampBox, el('span', { text: maxText }), el('span', { class: 'heat-name', text: ` heat: ${data.heat_metric}` }));
  root.removeChild(status);
  root.append(title, controls, stage);
  if (anims.length > 1) root.append(bar);
  const ramp = bar.querySelector('.ramp');
  ramp.style.background = `linear-gradient(to right, ${HEAT_STOPS.map(([t, c]) =>
    `rgb(${c.map((x) => Math.round(255 * x)).join(',')}) ${100 * t}%`).join(', ')})`;

  // three.js: one renderer, one scene per panel, one shared camera. Without WebGL (disabled,
  // blocked, no GPU and no software fallback) the panels would stay empty: say so instead; the
  // panel headers (sizes, KG, STED) and a report's plots and table do not need it.
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  } catch (e) {
    const why = e && e.message ? e.message : String(e);
    const message = el('div', { class: 'webgl-message', role: 'alert' }, [
      el('strong', { text: 'The 3D view cannot start: this browser gave the page no WebGL context.' }),
      el('p', { text: `(${why}) Turn on hardware acceleration or WebGL in the browser's settings, or open ` +
        'the file in another browser. The numbers in the panel headers are exact without it.' }),
    ]);
    stage.appendChild(message);
    controls.style.display = 'none';
    bar.style.display = 'none';
    return {
      webgl: false, message: message.textContent, loadSeconds: (performance.now() - started) / 1000,
      frameCount: F, vertexCount: V, canvas, pause() {}, setFrame() {}, frame: () => 0, render() {}, project: () => null,
    };
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setScissorTest(true);
  // Framed on the reference's own box (the shared box also holds the candidates' errors).
  const boxCenter = new THREE.Vector3(...[0, 1, 2].map((k) => (refLo[k] + refHi[k]) / 2));
  const boxHalf = [0, 1, 2].map((k) => (refHi[k] - refLo[k]) / 2);
  const boxRadius = Math.max(1e-9, Math.hypot(...boxHalf));
  let follow = false;
  followToggle.checked = follow;
  const frameCentre = (f) => new THREE.Vector3(centres[3 * f], centres[3 * f + 1], centres[3 * f + 2]);
  const center = () => (follow ? frameCentre(frame) : boxCenter);
  const fitHalf = () => (follow ? frameHalf : boxHalf);
  const radius = boxRadius;
  const camera = new THREE.PerspectiveCamera(35, 1, radius / 100, radius * 100);
  // Fit the box, seen from +z, in the panel: its face nearest the camera (the widest in view)
  // must fit both fields of view; 6 % margin. (A bounding sphere left a flat model at half the
  // panel.)
  const home = () => {
    const r = panels[0].getBoundingClientRect();
    const aspect = r.width / Math.max(1, r.height);
    const tanV = Math.tan(THREE.MathUtils.degToRad(camera.fov / 2));
    const [hx, hy, hz] = fitHalf();
    const distance = Math.max(1e-9, 1.06 * (hz + Math.max(hx / (tanV * aspect), hy / tanV)));
    const c = center();
    camera.position.set(c.x, c.y, c.z + distance);
    camera.up.set(0, 1, 0);
    orbit.target.copy(c);
    orbit.update();
  };
  let frame = 0;
  const orbit = new OrbitControls(camera, grid);
  // Follow the reference's frame centre when framing the whole path would leave the model off
  // centre (it travels more than a tenth of the panel) or small (its frames fit a view 20 %
  // closer): the model then fills its panel at every frame; unticking "follow" frames the path.
  {
    const r = panels[0].getBoundingClientRect();
    const aspect = r.width / Math.max(1, r.height);
    const tanV = Math.tan(THREE.MathUtils.degToRad(camera.fov / 2));
    const distance = (h) => h[2] + Math.max(h[0] / (tanV * aspect), h[1] / tanV);
    const whole = Math.max(1e-12, distance(boxHalf));
    let drift = 0; // largest offset of a frame's centre, as a fraction of the panel
    for (let f = 0; f < F; f++) {
      drift = Math.max(drift, Math.abs(centres[3 * f] - boxCenter.x) / (2 * whole * tanV * aspect),
        Math.abs(centres[3 * f + 1] - boxCenter.y) / (2 * whole * tanV));
    }
    follow = drift > 0.1 || distance(frameHalf) < 0.8 * whole;
    followToggle.checked = follow;
  }
  home();
  const meshes = anims.map((a, i) => {
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0xf4f4f4);
    scene.add(new THREE.AmbientLight(0xffffff, 1.4));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(1, 2, 3);
    scene.add(sun);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(V * 3), 3));
    geometry.setIndex(new THREE.BufferAttribute(index, 1));
    const colors = new Float32Array(V * 3).fill(0.75);
    geometry.setAttribute('color', new THREE.BufferAttribute(colors, 3));
    const material = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide });
    const mesh = new THREE.Mesh(geometry, material);
    scene.add(mesh);
    return { scene, geometry, mesh, index: i };
  });

  let playing = true;
  let shown = -1;
  let heatOn = true;
  function showFrame(f) {
    frame = Math.max(0, Math.min(F - 1, Math.round(f)));
    if (frame === shown) return;
    if (follow && shown >= 0) {
      // Move camera and target with the reference's centre, keeping the user's view angle.
      const d = frameCentre(frame).sub(frameCentre(shown));
      camera.position.add(d);
      orbit.target.add(d);
      orbit.update();
    }
    shown = frame;
    const base = frame * V * 3;
    anims.forEach((a, i) => {
      const pos = meshes[i].geometry.attributes.position;
      const arr = pos.array;
      for (let j = 0; j < V * 3; j++) arr[j] = lo[j % 3] + a.q[base + j] * step[j % 3];
      pos.needsUpdate = true;
      meshes[i].geometry.computeVertexNormals();
      paint(i);
    });
    slider.value = String(frame);
    frameLabel.textContent = `frame ${frame + 1} / ${F}`;
    render();
  }
  function paint(i) {
    const a = anims[i];
    const col = meshes[i].geometry.attributes.color;
    const arr = col.array;
    if (a.heat && heatOn) {
      const off = frame * V;
      for (let v = 0; v < V; v++) {
        const c = 3 * a.heat[off + v];
        arr[3 * v] = HEAT_LUT[c];
        arr[3 * v + 1] = HEAT_LUT[c + 1];
        arr[3 * v + 2] = HEAT_LUT[c + 2];
      }
    } else {
      arr.fill(0.75);
    }
    col.needsUpdate = true;
  }
  function render() {
    const rect = canvas.getBoundingClientRect();
    if (canvas.width !== Math.round(rect.width * renderer.getPixelRatio()) ||
        canvas.height !== Math.round(rect.height * renderer.getPixelRatio())) {
      renderer.setSize(rect.width, rect.height, false);
    }
    for (const m of meshes) {
      const r = panels[m.index].getBoundingClientRect();
      const x = r.left - rect.left;
      const y = rect.bottom - r.bottom;
      renderer.setViewport(x, y, r.width, r.height);
      renderer.setScissor(x, y, r.width, r.height);
      camera.aspect = r.width / Math.max(1, r.height);
      camera.updateProjectionMatrix();
      renderer.render(m.scene, camera);
    }
  }

  play.onclick = () => { playing = !playing; play.textContent = playing ? 'pause' : 'play'; };
  slider.oninput = () => { playing = false; play.textContent = 'play'; showFrame(Number(slider.value)); };
  reset.onclick = () => { home(); render(); };
  followToggle.onchange = () => { follow = followToggle.checked; home(); render(); };
  heatToggle.onchange = () => { heatOn = heatToggle.checked; anims.forEach((_, i) => paint(i)); render(); };
  orbit.addEventListener('change', render);
  window.addEventListener('resize', render);
  document.addEventListener('keydown', (e) => { if (e.code === 'Space' && e.target === document.body) { e.preventDefault(); play.onclick(); } });
  let last = performance.now();
  let position = 0;
  function tick(now) {
    const dt = Math.min(0.25, (now - last) / 1000);
    last = now;
    if (playing && F > 1) {
      position = (position + dt * (data.fps || 30) * Number(speed.value)) % F;
      showFrame(Math.floor(position));
    }
    requestAnimationFrame(tick);
  }
  showFrame(0);
  requestAnimationFrame(tick);

  const api = {
    loadSeconds: (performance.now() - started) / 1000,
    frameCount: F,
    vertexCount: V,
    canvas,
    pause() { playing = false; play.textContent = 'play'; },
    setFrame(f) { api.pause(); position = f; showFrame(f); },
    frame: () => frame,
    render,
    // Where vertex `v` of panel `i` is drawn, in CSS pixels relative to the canvas.
    project(i, v) {
      const p = new THREE.Vector3().fromBufferAttribute(meshes[i].geometry.attributes.position, v);
      const rect = canvas.getBoundingClientRect();
      const r = panels[i].getBoundingClientRect();
      camera.aspect = r.width / Math.max(1, r.height);
      camera.updateProjectionMatrix();
      p.project(camera);
      return { x: r.left - rect.left + ((p.x + 1) / 2) * r.width, y: r.top - rect.top + ((1 - p.y) / 2) * r.height };
    },
  };
  return api;
}

// The sweep report: interactive rate-distortion plots (bpvf against KG and STED, both axes
// logarithmic so a 0.3-bpvf codec and a 30-bpvf one stay readable side by side; each codec's
// lower envelope drawn as its line, every other point faint; hover for a point's parameters
// and metrics), the table (the parameters that vary as columns, the full set on hover), and a
// viewer per chosen point.
async function mountReport(root, data, THREE, OrbitControls) {
  root.appendChild(el('h1', { text: data.title }));
  root.appendChild(el('p', { text: `${data.input}: ${data.frames} frames × ${data.vertices} vertices; ${data.rows.length} points` }));
  const codecs = [...new Set(data.rows.map((r) => r.codec))];
  const palette = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#17becf', '#8c564b', '#e377c2'];
  const colour = (codec) => palette[codecs.indexOf(codec) % palette.length];
  const envelope = {};
  for (const metric of ['kg', 'sted']) envelope[metric] = new Set((data.envelope && data.envelope[metric]) || []);
  const tip = el('div', { class: 'tooltip' });
  document.body.appendChild(tip);
  const plots = el('div', { class: 'plots' });
  root.appendChild(plots);
  const legend = el('div', { class: 'legend' });
  codecs.forEach((c) => legend.appendChild(el('span', { style: `color:${colour(c)}`, text: `● ${c} ` })));
  legend.appendChild(el('span', { class: 'legend-note', text: ' line and filled dots: the codec\'s lower envelope; open dots: its other points' }));
  root.appendChild(legend);
  for (const metric of ['kg', 'sted']) plots.appendChild(plot(metric));
  root.appendChild(table());
  const viewers = [];
  for (const v of data.viewers || []) {
    root.appendChild(el('h2', { text: `decoded: ${v.title}` }));
    const box = el('div');
    root.appendChild(box);
    viewers.push(await mountViewer(box, v, THREE, OrbitControls));
  }
  return { viewers, points: data.rows.length };

  // Ticks of a log axis over [a, b] (powers of ten): every decade, with 2 and 5 between
  // when the axis spans at most three decades.
  function logTicks(a, b) {
    const ticks = [];
    const mantissas = b - a <= 3 ? [1, 2, 5] : [1];
    for (let e = Math.floor(a); e <= Math.ceil(b); e++) {
      for (const m of mantissas) {
        const t = Math.log10(m) + e;
        if (t >= a - 1e-9 && t <= b + 1e-9) ticks.push({ at: t, major: m === 1, value: m * 10 ** e });
      }
    }
    return ticks;
  }

  function tickLabel(value) {
    const e = Math.round(Math.log10(value));
    if (Math.abs(value - 10 ** e) < 1e-9 * value && (e < -3 || e > 4)) return `1e${e}`;
    return value >= 1e-3 && value < 1e5 ? String(Number(value.toPrecision(3))) : value.toExponential(0);
  }

  function plot(metric) {
    const W = 560, H = 380, M = { l: 60, r: 14, t: 24, b: 40 };
    const rows = data.rows.map((r, i) => ({ r, i })).filter(({ r }) => r[metric] > 0 && r.bpvf > 0);
    const ns = 'http://www.w3.org/2000/svg';
    const svg = document.createElementNS(ns, 'svg');
    svg.setAttribute('viewBox', `0 0 ${W} ${H}`);
    svg.setAttribute('class', 'rd');
    svg.dataset.metric = metric;
    const xs = rows.map(({ r }) => Math.log10(r.bpvf));
    const ys = rows.map(({ r }) => Math.log10(r[metric]));
    // A little room around the points; at least a decade on each axis.
    const span = (v) => {
      let [a, b] = [Math.min(...v), Math.max(...v)];
      if (!Number.isFinite(a)) [a, b] = [0, 1];
      const pad = Math.max(0.05 * (b - a), 0.5 * Math.max(0, 1 - (b - a)));
      return [a - pad, b + pad];
    };
    const [x0, x1] = span(xs);
    const [y0, y1] = span(ys);
    const X = (x) => M.l + ((x - x0) / (x1 - x0)) * (W - M.l - M.r);
    const Y = (y) => H - M.b - ((y - y0) / (y1 - y0)) * (H - M.t - M.b);
    const add = (tag, attrs, text) => {
      const e = document.createElementNS(ns, tag);
      for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
      if (text !== undefined) e.textContent = text;
      svg.appendChild(e);
      return e;
    };
    add('text', { x: W / 2, y: 16, 'text-anchor': 'middle', class: 'axis-title' }, `${metric === 'kg' ? 'KG (%)' : 'STED'} against bpvf (log–log)`);
    for (const t of logTicks(y0, y1)) {
      add('line', { x1: M.l, x2: W - M.r, y1: Y(t.at), y2: Y(t.at), class: t.major ? 'gridline' : 'gridline minor' });
      add('text', { x: M.l - 6, y: Y(t.at) + 4, 'text-anchor': 'end', class: 'y-tick' }, tickLabel(t.value));
    }
    for (const t of logTicks(x0, x1)) {
      add('line', { x1: X(t.at), x2: X(t.at), y1: M.t, y2: H - M.b, class: t.major ? 'gridline' : 'gridline minor' });
      add('text', { x: X(t.at), y: H - M.b + 16, 'text-anchor': 'middle', class: 'x-tick' }, tickLabel(t.value));
    }
    add('rect', { x: M.l, y: M.t, width: W - M.l - M.r, height: H - M.t - M.b, class: 'frame' });
    add('text', { x: W / 2, y: H - 6, 'text-anchor': 'middle' }, 'bits per vertex per frame');
    const at = ({ r }) => [X(Math.log10(r.bpvf)), Y(Math.log10(r[metric]))];
    // Envelope lines first, then the faint points, then the envelope points on top: a line
    // must not take the pointer from a point.
    for (const c of codecs) {
      const pts = rows.filter((p) => p.r.codec === c && envelope[metric].has(p.i)).sort((a, b) => a.r.bpvf - b.r.bpvf);
      add('polyline', { points: pts.map((p) => at(p).join(',')).join(' '), class: 'envelope', stroke: colour(c), 'pointer-events': 'none' });
    }
    const ordered = [...rows.filter((p) => !envelope[metric].has(p.i)), ...rows.filter((p) => envelope[metric].has(p.i))];
    for (const p of ordered) {
      const r = p.r;
      const onEnvelope = envelope[metric].has(p.i);
      const [cx, cy] = at(p);
      const dot = add('circle', {
        cx, cy, r: onEnvelope ? 4 : 3, class: onEnvelope ? 'point on-envelope' : 'point off-envelope',
        fill: onEnvelope ? colour(r.codec) : '#fff', stroke: colour(r.codec), 'data-codec': r.codec,
      });
      dot.addEventListener('mouseenter', (ev) => {
        tip.textContent = `${r.series || r.codec}${onEnvelope ? ' (on its lower envelope)' : ''}\n${JSON.stringify(r.params)}\n` +
          `${r.bytes} bytes, ${fmt(r.bpvf)} bpvf\n` +
          `KG ${fmt(r.kg)} %${(r.parts || 0) > 1 ? ` (worst part ${fmt(r.worst_part_kg)} %)` : ''}, STED ${fmt(r.sted)}\nHausdorff ${fmt(r.hausdorff)}, MSE ${fmt(r.mse)}, RMSE ${fmt(r.rmse)}\n` +
          `max error ${fmt(r.max_error)}; encode ${fmt(r.encode_seconds, 3)} s, decode ${fmt(r.decode_seconds, 3)} s`;
        tip.style.display = 'block';
        tip.style.left = `${ev.pageX + 12}px`;
        tip.style.top = `${ev.pageY + 12}px`;
      });
      dot.addEventListener('mouseleave', () => { tip.style.display = 'none'; });
    }
    return svg;
  }

  // The parameters whose value differs between two rows of the same codec, per codec in the
  // order it declares them: a sweep over `ss` shows an `ss` column, not 21 keys of JSON.
  function varyingParams() {
    const columns = [];
    for (const c of codecs) {
      const rows = data.rows.filter((r) => r.codec === c);
      for (const k of Object.keys(rows[0].params || {})) {
        if (new Set(rows.map((r) => JSON.stringify((r.params || {})[k]))).size > 1) columns.push({ codec: c, key: k });
      }
    }
    return columns;
  }

  function table() {
    const params = varyingParams();
    // The worst part's KG (issue 41) only when some row has several parts.
    const parted = data.rows.some((r) => (r.parts || 0) > 1);
    const metrics = ['bytes', 'bpvf', 'kg', ...(parted ? ['worst_part_kg'] : []), 'sted', 'hausdorff', 'rmse', 'max_error', 'encode_seconds', 'decode_seconds'];
    const heads = { kg: 'KG (%)', worst_part_kg: 'worst part KG (%)', sted: 'STED', max_error: 'max error', encode_seconds: 'enc s', decode_seconds: 'dec s' };
    const t = el('table', { class: 'rows' });
    // Two header rows: the codec each group of parameter columns belongs to, then the names.
    const groups = [];
    for (const p of params) {
      if (groups.length && groups[groups.length - 1].codec === p.codec) groups[groups.length - 1].span++;
      else groups.push({ codec: p.codec, span: 1 });
    }
    const spanRows = (text, attrs = {}) => el('th', { rowspan: '2', text, ...attrs });
    t.appendChild(el('tr', {}, [
      spanRows('codec'),
      ...groups.map((g) => el('th', { colspan: String(g.span), class: 'param-group', text: g.codec, title: `parameters of ${g.codec} that vary between its rows` })),
      spanRows('envelope', { title: 'on the codec\'s lower envelope by KG and/or STED' }),
      ...metrics.map((m) => spanRows(heads[m] || m)),
    ]));
    t.appendChild(el('tr', {}, params.map((p) => el('th', { class: 'param', text: p.key, title: `${p.codec}: ${p.key}` }))));
    data.rows.forEach((r, i) => {
      const on = ['kg', 'sted'].filter((m) => envelope[m].has(i)).map((m) => (m === 'kg' ? 'KG' : 'STED'));
      const cells = [
        el('td', { class: 'codec', text: r.codec }),
        ...params.map((p) => el('td', { class: 'param', text: r.codec === p.codec && r.params && p.key in r.params ? fmt(r.params[p.key]) : '' })),
        el('td', { class: 'envelope', text: on.join(' · ') }),
        ...metrics.map((m) => el('td', { text: fmt(r[m]) })),
      ];
      t.appendChild(el('tr', { class: on.length ? 'on-envelope' : '', title: `${r.series || r.codec} ${JSON.stringify(r.params)}` }, cells));
    });
    return t;
  }
}
