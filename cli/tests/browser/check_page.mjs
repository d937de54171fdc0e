// Loads an animcodec HTML page (viewer or sweep report) in Debian's Chromium, headless, and
// prints one JSON object the Rust test (cli/tests/view.rs) asserts on:
//   node check_page.mjs PAGE.html SCREENSHOT.png [SAMPLES.json]
// SAMPLES.json = {"panel": i, "triangles": [[a,b,c], ...]}: the colour drawn at each
// triangle's projected centroid in viewer panel i, frame 0.
import { chromium } from 'playwright-core';
import { readFileSync } from 'node:fs';
import { resolve } from 'node:path';

const [pagePath, shotPath, samplesPath] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const out = { consoleErrors: [] };
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
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
    await page.hover('svg.rd circle.point');
    out.tooltip = await page.evaluate(() => document.querySelector('.tooltip').textContent);
  }
  const viewer = out.kind === 'viewer' ? 'window.animcodecViewer' : 'window.animcodecReport.viewers[0]';
  const hasViewer = await page.evaluate(`Boolean(${viewer})`);
  if (hasViewer) {
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
  await page.screenshot({ path: shotPath });
} catch (e) {
  out.failure = String(e && e.stack ? e.stack : e);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
