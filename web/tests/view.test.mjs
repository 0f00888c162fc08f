// `progiso view` in a real browser: Debian's Chromium, headless, with software WebGL, driven by
// playwright-core. Run by ctest (view.browser):
//   node web/tests/view.test.mjs PROGISO_EXE VOLUME DIMS TYPE ISO OTHER_ISO [SCREENSHOT.png]
// Checks that the page shows a surface, that moving the slider shows the new isovalue's surface,
// that triangles grow while refining, and reports the slider-to-screen latency and the frame rate.
// Exit 77 (ctest: skipped) when Chromium or the npm modules are not installed.
import { spawn } from 'node:child_process';
import { existsSync, writeFileSync } from 'node:fs';
import { createInterface } from 'node:readline';

const [exe, volume, dims, type, iso, otherIso, screenshot] = process.argv.slice(2);
const chromium = process.env.PROGISO_CHROMIUM ?? '/usr/bin/chromium';
if (!existsSync(volume)) { console.log(`skipped: no ${volume}`); process.exit(77); }
if (!existsSync(chromium)) { console.log(`skipped: no ${chromium}`); process.exit(77); }
let playwright;
try { playwright = await import('playwright-core'); } catch { console.log('skipped: no playwright-core (npm ci in web/)'); process.exit(77); }

function fail(message) { console.error(`FAIL: ${message}`); process.exitCode = 1; }

const server = spawn(exe, ['view', volume, '--dims', dims, '--type', type, '--iso', iso, '--port', '0', '--threads', '2'],
                     { stdio: ['ignore', 'pipe', 'inherit'] });
const url = await new Promise((resolve, reject) => {
  const timer = setTimeout(() => reject(new Error('no URL printed in 30 s')), 30000);
  createInterface({ input: server.stdout }).on('line', (line) => {
    const m = line.match(/(http:\/\/\S+)/);
    if (m) { clearTimeout(timer); resolve(m[1]); }
  });
  server.on('exit', (code) => reject(new Error(`progiso view exited with ${code}`)));
});
console.log(`page: ${url}`);

const browser = await playwright.chromium.launch({
  executablePath: chromium, headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
         '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
});
try {
  const page = await browser.newPage({ viewport: { width: 960, height: 640 } });
  page.on('pageerror', (e) => fail(`page error: ${e.message}`));
  await page.goto(url);
  const state = () => page.evaluate(() => ({ ...window.progiso, latencies: window.progiso.latencies.slice(),
                                             arrivals: window.progiso.arrivals.slice() }));
  const waitFor = async (what, pred, ms = 60000) => {
    const until = Date.now() + ms;
    for (;;) {
      const s = await state();
      if (pred(s)) return s;
      if (Date.now() > until) { fail(`timed out waiting for ${what}: ${JSON.stringify({ ...s, latencies: s.latencies.length })}`); return s; }
      await new Promise((r) => setTimeout(r, 20));
    }
  };
  // Pixels of the canvas that are not the background.
  const painted = () => page.evaluate(() => {
    const c = document.getElementById('view');
    const o = document.createElement('canvas');
    o.width = c.width; o.height = c.height;
    const g = o.getContext('2d');
    g.drawImage(c, 0, 0);
    const d = g.getImageData(0, 0, o.width, o.height).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x15) + Math.abs(d[i + 1] - 0x18) + Math.abs(d[i + 2] - 0x1d) > 24) n++;
    return n / (o.width * o.height);
  });

  const moves = Number(process.env.PROGISO_VIEW_MOVES ?? 10);
  // 1. A surface on the canvas.
  const first = await waitFor('a first surface', (s) => s.frames > 0 && s.shown > 0);
  await waitFor('the end of refinement', (s) => !s.running);
  await new Promise((r) => setTimeout(r, 200));
  const cover = await painted();
  const s1 = await state();
  console.log(`surface: ${s1.shown} triangles on screen, ${(100 * cover).toFixed(1)}% of the canvas painted, ` +
              `the page's budget ${s1.budget} triangles (fit the display), ${s1.views} views sent`);
  if (!(cover > 0.02)) fail(`the canvas shows no surface (${cover})`);
  if (!(first.shown > 0)) fail('no triangles');
  // The camera went to the server once the page framed the surface (view-dependent refinement).
  if (!((await state()).views > 0)) fail('the page never sent its view');

  // 2. Triangles grow while refining: paused, a new isovalue shows its coarse cut; resumed, it
  // refines to the finest.
  await page.click('#pause');
  const w0 = Number(otherIso);
  await page.evaluate((v) => window.progisoSetIso(v), w0);
  const coarse = await waitFor('the coarse cut of a new isovalue, paused', (s) => s.isovalue === w0 && !s.running);
  await page.click('#pause');  // resume
  const grow = [coarse.shown];
  for (;;) {
    const x = await state();
    if (x.shown !== grow[grow.length - 1]) grow.push(x.shown);
    if (!x.running && x.isovalue === w0 && x.splits > coarse.splits) break;
    await new Promise((r) => setTimeout(r, 10));
  }
  console.log(`triangles while the new isovalue refined: ${grow.join(' ')}`);
  if (!(grow[grow.length - 1] > grow[0])) fail(`triangles did not grow: ${grow.join(' ')}`);
  // Geomorphs: pieces of the refinement glided in from the coarser surface.
  // (A frame may bring the whole refinement at once when the engine outruns the frame thread;
  // such a frame, and a new isovalue's, appear at once by design: then there is nothing to check.)
  const g = await state();
  console.log(`pieces that glided in from the coarser surface (geomorphs): ${g.morphed}, ` +
              `the farthest start ${g.morphReach.toFixed(3)} from its end`);
  // (A split whose new vertices lie on the coarser triangles glides nowhere: only many can tell.)
  if (g.morphed >= 100 && !(g.morphReach > 0)) fail('geomorphs started every vertex at its own position');
  await new Promise((r) => setTimeout(r, 200));
  const c = await painted();
  console.log(`after the slider: isovalue ${w0}, ${grow[grow.length - 1]} triangles, ${(100 * c).toFixed(1)}% painted`);
  if (!(c > 0.02)) fail('the new isovalue shows no surface');

  // 3. The slider: latency from a move to the new isovalue's first frame, on the page and on screen.
  const before = await state();
  const base = before.latencies.length, arrivalBase = before.arrivals.length;
  for (let k = 0; k < moves; ++k) {
    const w = k % 2 === 0 ? Number(iso) : Number(otherIso);
    await page.evaluate((v) => window.progisoSetIso(v), w);
    await waitFor(`isovalue ${w}`, (s) => s.isovalue === w && s.latencies.length > base + k, 20000);
  }
  const report = (what, values) => {
    const v = values.slice().sort((a, b) => a - b);
    const pct = (p) => v[Math.min(v.length - 1, Math.ceil(p / 100 * v.length) - 1)];
    console.log(`${what} (${v.length} moves): median ${pct(50).toFixed(1)} ms, p99 ${pct(99).toFixed(1)} ms, max ${v[v.length - 1].toFixed(1)} ms`);
  };
  const end = await state();
  report('slider to the new isovalue\'s first frame on the page', end.arrivals.slice(arrivalBase));
  report('slider to that frame on screen', end.latencies.slice(base));

  // 4. Frame rate and bytes while refining a third isovalue (to the page's own budget).
  const start = await state();
  const w3 = Number(otherIso) * 0.5 + Number(iso) * 0.5;
  await page.evaluate((v) => window.progisoSetIso(v), w3);
  const t0 = Date.now();
  const after = await waitFor('refinement of a third isovalue', (s) => !s.running && s.isovalue === w3 && s.frames > start.frames);
  const seconds = (Date.now() - t0) / 1000;
  console.log(`while refining: ${after.fps.toFixed(0)} fps, ${((after.bytes - start.bytes) / seconds / 1e6).toFixed(2)} MB/s over ${seconds.toFixed(2)} s, ` +
              `${((after.bytes - start.bytes) / Math.max(1, after.triangles)).toFixed(1)} bytes per final triangle`);
  // 5. The README's screenshot, in the middle of a refinement: paused part way.
  if (screenshot && !existsSync(screenshot)) {
    await page.click('#pause');
    const w = Number(iso) * 0.6 + Number(otherIso) * 0.4;
    await page.evaluate((v) => window.progisoSetIso(v), w);
    await waitFor('the paused isovalue', (s) => s.isovalue === w);
    await page.click('#pause');  // resume
    await new Promise((r) => setTimeout(r, Number(process.env.PROGISO_VIEW_SHOT_MS ?? 30)));
    await page.click('#pause');
    await new Promise((r) => setTimeout(r, 1500));
    const x = await state();
    writeFileSync(screenshot, await page.screenshot());
    console.log(`screenshot (paused part way: ${x.splits} splits, ${x.shown} triangles): ${screenshot}`);
  }
} catch (e) {
  fail(e.stack ?? String(e));
} finally {
  await browser.close();
  server.kill('SIGTERM');
}
if (!process.exitCode) console.log('ok');
