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
  if (keys.length) {
    lines.push(keys.map((k) => `${k} ${typeof info[k] === 'object' ? JSON.stringify(info[k]) : fmt(info[k])}`).join(' · '));
  }
  if (anim.metrics) {
    const m = anim.metrics;
    lines.push(`KG ${fmt(m.kg)} % · STED ${fmt(m.sted)} · Hausdorff ${fmt(m.hausdorff)} · RMSE ${fmt(m.rmse)}`);
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
  let frameRadius = 0;
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
      for (let k = 0; k < 3; k++) centres[3 * f + k] = lo[k] + 0.5 * (mn[k] + mx[k]) * step[k];
      frameRadius = Math.max(frameRadius, 0.5 * Math.hypot(...[0, 1, 2].map((k) => (mx[k] - mn[k]) * step[k])));
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
  bar.append(el('span', { text: '0' }), el('div', { class: 'ramp' }),
    el('span', { text: maxText }), el('span', { class: 'heat-name', text: ` heat: ${data.heat_metric}` }));
  root.removeChild(status);
  root.append(title, controls, stage);
  if (anims.length > 1) root.append(bar);
  const ramp = bar.querySelector('.ramp');
  ramp.style.background = `linear-gradient(to right, ${HEAT_STOPS.map(([t, c]) =>
    `rgb(${c.map((x) => Math.round(255 * x)).join(',')}) ${100 * t}%`).join(', ')})`;

  // three.js: one renderer, one scene per panel, one shared camera.
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setScissorTest(true);
  const boxCenter = new THREE.Vector3((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2);
  const boxRadius = Math.max(1e-9, 0.5 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]));
  let follow = frameRadius < 0.5 * boxRadius;
  followToggle.checked = follow;
  const frameCentre = (f) => new THREE.Vector3(centres[3 * f], centres[3 * f + 1], centres[3 * f + 2]);
  const center = () => (follow ? frameCentre(frame) : boxCenter);
  const fitRadius = () => (follow ? Math.max(1e-9, frameRadius) : boxRadius);
  const radius = boxRadius;
  const camera = new THREE.PerspectiveCamera(35, 1, radius / 100, radius * 100);
  // Fit the bounding sphere in the narrower of the panel's two fields of view.
  const home = () => {
    const r = panels[0].getBoundingClientRect();
    const aspect = r.width / Math.max(1, r.height);
    const half = THREE.MathUtils.degToRad(camera.fov / 2);
    const distance = (1.1 * fitRadius()) / Math.sin(Math.min(half, Math.atan(Math.tan(half) * aspect)));
    const c = center();
    camera.position.set(c.x, c.y, c.z + distance);
    camera.up.set(0, 1, 0);
    orbit.target.copy(c);
    orbit.update();
  };
  let frame = 0;
  const orbit = new OrbitControls(camera, grid);
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

// The sweep report: an interactive rate-distortion plot (bpvf against KG and STED, log
// scale, hover for a point's parameters and metrics), the table, and a viewer per chosen point.
async function mountReport(root, data, THREE, OrbitControls) {
  root.appendChild(el('h1', { text: data.title }));
  root.appendChild(el('p', { text: `${data.input}: ${data.frames} frames × ${data.vertices} vertices; ${data.rows.length} points` }));
  const codecs = [...new Set(data.rows.map((r) => r.series || r.codec))];
  const palette = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#17becf', '#8c564b', '#e377c2'];
  const tip = el('div', { class: 'tooltip' });
  document.body.appendChild(tip);
  const plots = el('div', { class: 'plots' });
  root.appendChild(plots);
  const legend = el('div', { class: 'legend' });
  codecs.forEach((c, i) => legend.appendChild(el('span', { style: `color:${palette[i % palette.length]}`, text: `● ${c} ` })));
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

  function plot(metric) {
    const W = 520, H = 360, M = { l: 60, r: 12, t: 24, b: 40 };
    const rows = data.rows.filter((r) => r[metric] > 0 && r.bpvf > 0);
    const ns = 'http://www.w3.org/2000/svg';
    const svg = document.createElementNS(ns, 'svg');
    svg.setAttribute('viewBox', `0 0 ${W} ${H}`);
    svg.setAttribute('class', 'rd');
    const xs = rows.map((r) => r.bpvf);
    const ys = rows.map((r) => Math.log10(r[metric]));
    const [x0, x1] = [0, Math.max(...xs, 1) * 1.05];
    const [y0, y1] = [Math.floor(Math.min(...ys, 0)), Math.ceil(Math.max(...ys, 0))];
    const X = (x) => M.l + ((x - x0) / (x1 - x0)) * (W - M.l - M.r);
    const Y = (y) => H - M.b - ((y - y0) / Math.max(1e-9, y1 - y0)) * (H - M.t - M.b);
    const add = (tag, attrs, text) => {
      const e = document.createElementNS(ns, tag);
      for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
      if (text !== undefined) e.textContent = text;
      svg.appendChild(e);
      return e;
    };
    add('text', { x: W / 2, y: 16, 'text-anchor': 'middle', class: 'axis-title' }, `${metric === 'kg' ? 'KG (%)' : 'STED'} against bpvf`);
    for (let e = y0; e <= y1; e++) {
      add('line', { x1: M.l, x2: W - M.r, y1: Y(e), y2: Y(e), class: 'gridline' });
      add('text', { x: M.l - 6, y: Y(e) + 4, 'text-anchor': 'end' }, `1e${e}`);
    }
    const xStep = x1 > 40 ? 10 : x1 > 10 ? 2 : 1;
    for (let x = 0; x <= x1; x += xStep) add('text', { x: X(x), y: H - M.b + 16, 'text-anchor': 'middle' }, String(x));
    add('text', { x: W / 2, y: H - 6, 'text-anchor': 'middle' }, 'bits per vertex per frame');
    const seriesPoints = (c) => rows.filter((r) => (r.series || r.codec) === c).sort((a, b) => a.bpvf - b.bpvf);
    // Every series' line first, then every point: a later series' line must not cover (and
    // take the pointer from) an earlier series' points.
    codecs.forEach((c, ci) => {
      const pts = seriesPoints(c);
      add('polyline', {
        points: pts.map((r) => `${X(r.bpvf)},${Y(Math.log10(r[metric]))}`).join(' '),
        fill: 'none',
        stroke: palette[ci % palette.length],
        'pointer-events': 'none',
      });
    });
    codecs.forEach((c, ci) => {
      const pts = seriesPoints(c);
      const color = palette[ci % palette.length];
      for (const r of pts) {
        const dot = add('circle', { cx: X(r.bpvf), cy: Y(Math.log10(r[metric])), r: 4, fill: color, class: 'point' });
        dot.addEventListener('mouseenter', (ev) => {
          tip.textContent = `${r.codec} ${JSON.stringify(r.params)}\n${r.bytes} bytes, ${fmt(r.bpvf)} bpvf\n` +
            `KG ${fmt(r.kg)} %, STED ${fmt(r.sted)}\nHausdorff ${fmt(r.hausdorff)}, MSE ${fmt(r.mse)}, RMSE ${fmt(r.rmse)}\n` +
            `max error ${fmt(r.max_error)}; encode ${fmt(r.encode_seconds, 3)} s, decode ${fmt(r.decode_seconds, 3)} s`;
          tip.style.display = 'block';
          tip.style.left = `${ev.pageX + 12}px`;
          tip.style.top = `${ev.pageY + 12}px`;
        });
        dot.addEventListener('mouseleave', () => { tip.style.display = 'none'; });
      }
    });
    return svg;
  }

  function table() {
    const cols = ['codec', 'params', 'bytes', 'bpvf', 'kg', 'sted', 'hausdorff', 'mse', 'rmse', 'max_error', 'encode_seconds', 'decode_seconds'];
    const t = el('table', { class: 'rows' });
    t.appendChild(el('tr', {}, cols.map((c) => el('th', { text: c }))));
    for (const r of data.rows) {
      t.appendChild(el('tr', {}, cols.map((c) => el('td', { text: c === 'params' ? JSON.stringify(r.params) : fmt(r[c]) }))));
    }
    return t;
  }
}
