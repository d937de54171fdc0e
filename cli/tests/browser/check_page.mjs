// Loads an animcodec HTML page (viewer or sweep report) in Debian's Chromium, headless, and
// prints one JSON object the Rust test (cli/tests/view.rs) asserts on:
//   node check_page.mjs PAGE.html SCREENSHOT.png [SAMPLES.json]
// SAMPLES.json = {"panel": i, "triangles": [[a,b,c], ...]}: the colour drawn at each
// triangle's projected centroid in viewer panel i, frame 0.
import { chromium } from 'playwright-core';
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';

// NO_WEBGL=1 starts Chromium with WebGL switched off (the viewer must say so, visibly);
// FULL_PAGE=1 takes the screenshot of the whole page; VIEWPORT=WxH (default 1280x720).
const [pagePath, shotPath, samplesPath] = process.argv.slice(2);
const noWebgl = process.env.NO_WEBGL === '1';
const [vw, vh] = (process.env.VIEWPORT || '1280x720').split('x').map(Number);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    ...(noWebgl ? ['--disable-webgl', '--disable-3d-apis'] : [])],
});
const out = { consoleErrors: [] };
try {
  const page = await browser.newPage({ viewport: { width: vw, height: vh } });
  page.on('console', (m) => { if (m.type() === 'error') out.consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => out.consoleErrors.push(String(e)));
  const t0 = Date.now();
  await page.goto('file://' + resolve(pagePath));
  await page.waitForFunction(() => window.animcodecViewer || window.animcodecReport, null, { timeout: 180000 });
  out.loadSeconds = (Date.now() - t0) / 1000;
  out.kind = await page.evaluate(() => (window.animcodecViewer ? 'viewer' : 'report'));
  if (out.kind === 'report') {
    out.reportPoints = await page.evaluate(() => window.animcodecReport.points);
    out.reportViewers = await page.evaluate(() => window.animcodecReport.viewers.length);
    out.plotPoints = await page.evaluate(() => document.querySelectorAll('svg.rd circle.point').length);
    // Hovering a point shows its parameters and metrics.
    // The last point drawn is on top of any it overlaps.
    await page.locator('svg.rd circle.point').last().hover();
    out.tooltip = await page.evaluate(() => document.querySelector('.tooltip').textContent);
    out.table = await page.evaluate(() => {
      const t = document.querySelector('table.rows');
      const heads = [...t.querySelectorAll('th')].map((h) => h.textContent);
      const first = t.querySelector('tr.on-envelope, tr:nth-child(3)');
      const box = t.getBoundingClientRect();
      // Every column's right edge, so a test can ask whether bytes/KG/STED are on screen.
      const right = Object.fromEntries([...t.querySelectorAll('th')].map((h) => [h.textContent, h.getBoundingClientRect().right]));
      return { heads, width: box.width, right, firstRowTitle: first.getAttribute('title'), paramCells: t.querySelectorAll('td.param').length };
    });
    // How much of each plot's width each codec's points spread over (log axes keep a
    // low-rate codec from being squeezed into a corner by a high-rate one).
    out.plotSpread = await page.evaluate(() => [...document.querySelectorAll('svg.rd')].map((svg) => {
      const frame = svg.querySelector('rect.frame');
      const width = Number(frame.getAttribute('width'));
      const byCodec = {};
      for (const c of svg.querySelectorAll('circle.point')) {
        const k = c.getAttribute('data-codec');
        const x = Number(c.getAttribute('cx'));
        byCodec[k] = byCodec[k] || [x, x];
        byCodec[k] = [Math.min(byCodec[k][0], x), Math.max(byCodec[k][1], x)];
      }
      return { metric: svg.dataset.metric, spread: Object.fromEntries(Object.entries(byCodec).map(([k, [a, b]]) => [k, (b - a) / width])),
        envelopeLines: svg.querySelectorAll('polyline.envelope').length };
    }));
  }
  const viewer = out.kind === 'viewer' ? 'window.animcodecViewer' : 'window.animcodecReport.viewers[0]';
  const hasViewer = await page.evaluate(`Boolean(${viewer})`);
  out.webgl = hasViewer ? await page.evaluate(`${viewer}.webgl !== false`) : null;
  if (hasViewer && !out.webgl) {
    // The message must be on screen: its box inside the viewport, not zero-sized.
    out.webglMessage = await page.evaluate(() => {
      const m = document.querySelector('.webgl-message');
      if (!m) return null;
      const r = m.getBoundingClientRect();
      return { text: m.textContent, visible: r.width > 100 && r.height > 20 && r.top >= 0 && r.bottom <= window.innerHeight };
    });
  }
  out.colorbarTicks = await page.evaluate(() => [...document.querySelectorAll('.colorbar .tick')].map((t) => t.textContent));
  if (hasViewer && out.webgl) {
    // Fingerprint of the drawn image: the frame slider must change it.
    const digest = (frame) => page.evaluate(`(() => {
      const v = ${viewer};
      v.setFrame(${frame});
      v.render();
      const c = document.createElement('canvas');
      c.width = v.canvas.width; c.height = v.canvas.height;
      const g = c.getContext('2d');
      g.drawImage(v.canvas, 0, 0);
      const d = g.getImageData(0, 0, c.width, c.height).data;
      let h = 0, lit = 0;
      for (let i = 0; i < d.length; i += 4) { h = (h * 31 + d[i] + 7 * d[i + 1] + 13 * d[i + 2]) >>> 0; if (d[i] + d[i + 1] + d[i + 2] < 600) lit++; }
      return { h, lit, frames: v.frameCount };
    })()`);
    const first = await digest(0);
    const mid = await digest(Math.floor(first.frames / 2));
    out.frameDigests = [first.h, mid.h];
    out.nonBackgroundPixels = first.lit;
    out.frameChangesImage = first.h !== mid.h;
    await page.evaluate(`${viewer}.setFrame(0)`);
    // Framing: the box of the reference (panel 0) as drawn at frame 0, as fractions of its
    // panel, and how far its centre is from the panel's centre.
    out.framing = await page.evaluate(`(() => {
      const v = ${viewer};
      const panel = document.querySelectorAll('.panel')[0].getBoundingClientRect();
      const canvas = v.canvas.getBoundingClientRect();
      const n = v.vertexCount;
      const stride = Math.max(1, Math.floor(n / 4000));
      let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
      for (let i = 0; i < n; i += stride) {
        const p = v.project(0, i);
        x0 = Math.min(x0, p.x); x1 = Math.max(x1, p.x); y0 = Math.min(y0, p.y); y1 = Math.max(y1, p.y);
      }
      const left = panel.left - canvas.left, top = panel.top - canvas.top;
      return {
        fillX: (x1 - x0) / panel.width, fillY: (y1 - y0) / panel.height,
        offX: ((x0 + x1) / 2 - left - panel.width / 2) / panel.width,
        offY: ((y0 + y1) / 2 - top - panel.height / 2) / panel.height,
      };
    })()`);
    if (samplesPath) {
      const samples = JSON.parse(readFileSync(samplesPath, 'utf8'));
      out.samples = await page.evaluate(`(() => {
        const v = ${viewer};
        const s = ${JSON.stringify(samples)};
        v.render();
        const c = document.createElement('canvas');
        c.width = v.canvas.width; c.height = v.canvas.height;
        const g = c.getContext('2d');
        g.drawImage(v.canvas, 0, 0);
        const ratio = v.canvas.width / v.canvas.getBoundingClientRect().width;
        return s.triangles.map((t) => {
          const p = t.map((i) => v.project(s.panel, i));
          const x = Math.round(ratio * (p[0].x + p[1].x + p[2].x) / 3);
          const y = Math.round(ratio * (p[0].y + p[1].y + p[2].y) / 3);
          const d = g.getImageData(x, y, 1, 1).data;
          return [d[0], d[1], d[2]];
        });
      })()`);
    }
  }
  await page.screenshot({ path: shotPath, fullPage: process.env.FULL_PAGE === '1' });
} catch (e) {
  out.failure = String(e && e.stack ? e.stack : e);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
