// End-to-end test of the museum-guide web client (web/index.html, app.js, style.css)
// served by `mvkp serve`, in Debian's Chromium driven by playwright-core.
//
// The camera is Chromium's fake capture device playing a video made by make_video.py
// (samples/starry_night.jpg perspective-warped onto another sample). Checks:
//   - the card shows the right title within 2 s of page.goto (and never another one),
//     with artist, year and link; the outline polygon is drawn where the painting is;
//     screenshot to $E2E_SCREENSHOT (default $OUT/e2e-screenshot.png, OUT defaulting
//     to the directory of $MVKP, i.e. the build directory)
//   - ?debug=1 shows the latency corner (and it is hidden without it)
//   - no camera (getUserMedia refused): the upload fallback recognises a photo of the
//     painting, says so for a photo without any exhibit, and hides the link of an
//     exhibit that has none
//   - a camera seeing no exhibit: the hint stays, no card, no outline
//   - four exhibits at once (issue 20; two more added with `mvkp db add` while the
//     server runs): all four outlined where they are within the budget, and kept in
//     >= 95 % of the overlay samples and of the server's answers over 10 s; prev lists
//     them; tapping each outline shows its card, which stays while it is in view
// Exits non-zero on any failure; the server is stopped in every case.
//
// Env: MVKP (mvkp binary, required), SAMPLES (repo samples/, required), OUT,
// E2E_SCREENSHOT, CHROMIUM (default /usr/bin/chromium), E2E_TITLE_BUDGET_MS (2000).
// Run through run.sh, which installs Chromium and playwright-core when missing.
import { spawn, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import readline from 'node:readline';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const MVKP = process.env.MVKP;
const SAMPLES = process.env.SAMPLES;
if (!MVKP || !SAMPLES) {
  console.error('browser_test: set MVKP=<mvkp binary> and SAMPLES=<repo>/samples');
  process.exit(2);
}
const OUT = process.env.OUT || path.dirname(path.resolve(MVKP));
const SCREENSHOT = process.env.E2E_SCREENSHOT || path.join(OUT, 'e2e-screenshot.png');
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const TITLE_BUDGET_MS = Number(process.env.E2E_TITLE_BUDGET_MS || 2000);
const TITLE = 'The Starry Night';
// A phone held upright: the 640x480 camera frames are letterboxed in the middle.
const PHONE = { viewport: { width: 412, height: 915 }, deviceScaleFactor: 2, isMobile: true, hasTouch: true };

let passed = 0;
const failures = [];
function check(desc, cond, detail = '') {
  if (cond) {
    passed++;
    console.log('ok:', desc);
  } else {
    failures.push(desc);
    console.log('FAIL:', desc, detail);
  }
}

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'mvkp-e2e-'));
let server = null;
const serverLog = [];
const browsers = [];

function killServer() {
  if (server && server.exitCode === null && server.signalCode === null) server.kill('SIGKILL');
}
process.on('exit', () => {
  killServer();
  fs.rmSync(tmp, { recursive: true, force: true });
});
for (const sig of ['SIGINT', 'SIGTERM', 'SIGHUP']) {
  process.on(sig, () => {
    console.error('browser_test: ' + sig + ', stopping');
    process.exit(1);  // the exit handler kills the server
  });
}
// Well below CTest's TIMEOUT, so that a hang still ends with a message and a clean-up.
const watchdog = setTimeout(() => {
  console.error('FAIL: browser_test did not finish within 240 s');
  console.error('server log (last lines):\n' + serverLog.join('\n'));
  process.exit(1);
}, 240000);
watchdog.unref();

function fatal(msg) {
  console.error('FAIL: ' + msg);
  if (serverLog.length) console.error('server log (last lines):\n' + serverLog.join('\n'));
  process.exit(1);
}

function run(cmd, args) {
  const r = spawnSync(cmd, args, { encoding: 'utf8', timeout: 300000 });
  if (r.status !== 0) fatal('setup: ' + [cmd, ...args].join(' ') + '\n' + (r.stdout || '') + (r.stderr || '') + (r.error || ''));
}

// Starts `mvkp serve DB --port 0`; the chosen port is in the first JSON line on stderr.
function startServer(db) {
  return new Promise((resolve, reject) => {
    server = spawn(MVKP, ['serve', db, '--host', '127.0.0.1', '--port', '0'], { stdio: ['ignore', 'ignore', 'pipe'] });
    const timer = setTimeout(() => reject(new Error('no listening line from mvkp serve within 60 s')), 60000);
    server.on('error', (e) => { clearTimeout(timer); reject(e); });
    server.on('exit', (code, sig) => {
      clearTimeout(timer);
      reject(new Error('mvkp serve exited early: ' + (code ?? sig)));
    });
    let first = true;
    readline.createInterface({ input: server.stderr }).on('line', (line) => {
      serverLog.push(line);
      if (serverLog.length > 40) serverLog.shift();
      if (!first) return;
      first = false;
      clearTimeout(timer);
      try {
        resolve(JSON.parse(line).port);
      } catch {
        reject(new Error('unexpected first line from mvkp serve: ' + line));
      }
    });
  });
}

async function stopServer() {
  if (!server || server.exitCode !== null || server.signalCode !== null) return;
  const exited = new Promise((ok) => server.once('exit', ok));
  server.kill('SIGTERM');
  const t = setTimeout(() => server.kill('SIGKILL'), 20000);
  await exited;
  clearTimeout(t);
}

async function launch(video) {
  const b = await chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    timeout: 120000,
    args: ['--no-sandbox', '--disable-dev-shm-usage', '--use-fake-device-for-media-stream',
           '--use-fake-ui-for-media-stream', '--use-file-for-fake-video-capture=' + video,
           '--autoplay-policy=no-user-gesture-required'],
  });
  browsers.push(b);
  return b;
}

// A page that records what it throws or logs as an error, and every title its card shows.
async function newPage(browser, initScript) {
  const context = await browser.newContext(PHONE);
  context.setDefaultTimeout(30000);
  if (initScript) await context.addInitScript(initScript);
  await context.addInitScript(() => {
    window.__titles = [];
    const note = () => {
      const card = document.getElementById('card');
      const title = document.getElementById('card-title');
      if (!card || !title || card.hidden) return;
      const last = window.__titles[window.__titles.length - 1];
      if (!last || last.title !== title.textContent) window.__titles.push({ t: performance.now(), title: title.textContent });
    };
    new MutationObserver(note).observe(document, { subtree: true, childList: true, characterData: true, attributes: true });
  });
  const page = await context.newPage();
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push('uncaught: ' + e.message));
  page.on('console', (m) => {
    if (m.type() === 'error' && !(page.allowedErrors && page.allowedErrors.test(m.text()))) page.errors.push('console: ' + m.text());
  });
  return page;
}

function noErrors(page, what) {
  check(what + ': no script or console errors', page.errors.length === 0, page.errors.join('\n'));
}

// Looks for the overlay's green outline along the edges of `quad` (frame pixels of a
// fw x fh frame), mapped as app.js maps it (object-fit: contain letterboxing).
// Returns {edgeHits, samples, corners, centreGreen, green}.
function outlineAt(page, quad, fw, fh) {
  return page.evaluate(([quad, fw, fh]) => {
    const c = document.getElementById('overlay');
    const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    const s = Math.min(c.width / fw, c.height / fh);
    const ox = (c.width - fw * s) / 2, oy = (c.height - fh * s) / 2;
    const pt = ([x, y]) => [ox + x * s, oy + y * s];
    const isGreen = (x, y) => {
      if (x < 0 || y < 0 || x >= c.width || y >= c.height) return false;
      const i = (Math.round(y) * c.width + Math.round(x)) * 4;
      return px[i + 3] > 128 && px[i + 1] > 180 && px[i] < 140 && px[i + 2] < 140;
    };
    const r = Math.round(8 * devicePixelRatio);  // tolerance: 8 CSS px (~12 frame px here)
    const near = ([x, y]) => {
      for (let dy = -r; dy <= r; dy += 1) for (let dx = -r; dx <= r; dx += 1) if (isGreen(x + dx, y + dy)) return true;
      return false;
    };
    let edgeHits = 0, samples = 0, corners = 0;
    for (let k = 0; k < 4; k++) {
      const a = pt(quad[k]), b = pt(quad[(k + 1) % 4]);
      if (near(a)) corners++;
      for (let i = 0; i < 16; i++) {
        const t = (i + 0.5) / 16;
        samples++;
        if (near([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])) edgeHits++;
      }
    }
    const cx = quad.reduce((v, q) => v + q[0], 0) / 4, cy = quad.reduce((v, q) => v + q[1], 0) / 4;
    let green = 0;
    for (let i = 0; i < px.length; i += 4) if (px[i + 3] > 128 && px[i + 1] > 180 && px[i] < 140 && px[i + 2] < 140) green++;
    return { edgeHits, samples, corners, centreGreen: near(pt([cx, cy])), green };
  }, [quad, fw, fh]);
}

async function waitForOutline(page, quad, fw, fh, ms) {
  const end = Date.now() + ms;
  let o;
  for (;;) {
    o = await outlineAt(page, quad, fw, fh);
    if ((o.edgeHits >= 0.9 * o.samples && o.corners === 4 && !o.centreGreen) || Date.now() > end) return o;
    await page.waitForTimeout(100);
  }
}

const cardState = (page) => page.evaluate(() => ({
  hidden: document.getElementById('card').hidden,
  title: document.getElementById('card-title').textContent,
  artist: document.getElementById('card-artist').textContent,
  year: document.getElementById('card-year').textContent,
  linkVisible: !!document.getElementById('card-link').offsetParent,
  href: document.getElementById('card-link').getAttribute('href'),
  hint: document.getElementById('hint').hidden ? null : document.getElementById('hint').textContent,
  uploadVisible: !!document.getElementById('upload').offsetParent,
}));

const waitTitle = (page, title, timeout) => page.waitForFunction((t) =>
  !document.getElementById('card').hidden && document.getElementById('card-title').textContent === t,
  title, { polling: 'raf', timeout });

async function main() {
  if (!fs.existsSync(CHROMIUM)) fatal(CHROMIUM + ' is missing (apt-get install chromium; run.sh does it)');
  fs.mkdirSync(path.dirname(SCREENSHOT), { recursive: true });

  // Fake camera video, photos, and a database of two exhibits.
  run('/usr/bin/python3', [path.join(HERE, 'make_video.py'), SAMPLES, tmp]);
  const scene = JSON.parse(fs.readFileSync(path.join(tmp, 'scene.json'), 'utf8'));
  const db = path.join(tmp, 'museum.db');
  run(MVKP, ['db', 'create', db]);
  run(MVKP, ['db', 'add', db, '--id', 'starry', '--image', path.join(SAMPLES, 'starry_night.jpg'), '--title', TITLE,
             '--artist', 'Vincent van Gogh', '--year', '1889', '--url', 'https://example.org/starry']);
  run(MVKP, ['db', 'add', db, '--id', 'building', '--image', path.join(SAMPLES, 'building.jpg'), '--title', 'Building']);

  const port = await startServer(db).catch((e) => fatal(e.message));
  const base = 'http://127.0.0.1:' + port;
  console.log('server on', base);
  server.on('exit', (code, sig) => { if (!stopping) fatal('mvkp serve died during the test: ' + (code ?? sig)); });

  // 1. Camera pointed at the painting.
  const cam = await launch(path.join(tmp, 'scene.y4m'));
  console.log('browser', cam.version());
  let page = await newPage(cam);
  const t0 = Date.now();
  await page.goto(base + '/');
  try {
    await waitTitle(page, TITLE, 30000);
  } catch (e) {
    fatal('the card never showed "' + TITLE + '": ' + JSON.stringify(await cardState(page)) + ' ' + page.errors.join('; '));
  }
  const elapsed = Date.now() - t0;
  const titles = await page.evaluate(() => window.__titles);
  console.log(`time to title: ${elapsed} ms from page.goto (in page: ${titles[0].t.toFixed(0)} ms after navigation start)`);
  check(`"${TITLE}" shown within ${TITLE_BUDGET_MS} ms of page.goto (${elapsed} ms)`, elapsed <= TITLE_BUDGET_MS);
  let st = await cardState(page);
  check('card: artist, year and link', st.artist === 'Vincent van Gogh' && st.year === '1889' && st.linkVisible
        && st.href === 'https://example.org/starry', JSON.stringify(st));
  check('hint hidden while the painting is recognised', st.hint === null, JSON.stringify(st));
  check('upload fallback hidden when the camera works', !st.uploadVisible, JSON.stringify(st));
  const o = await waitForOutline(page, scene.quad, scene.width, scene.height, 5000);
  check(`outline drawn around the painting (${o.edgeHits}/${o.samples} edge samples, ${o.corners}/4 corners)`,
        o.edgeHits >= 0.9 * o.samples && o.corners === 4 && !o.centreGreen, JSON.stringify(o));
  check('debug corner hidden without ?debug=1', await page.locator('#debug').isHidden());
  await page.waitForTimeout(1000);  // a few more frames: the card must stay, and never show another exhibit
  const later = await page.evaluate(() => window.__titles);
  check('the card never showed another exhibit', later.every((x) => x.title === TITLE), JSON.stringify(later));
  await page.screenshot({ path: SCREENSHOT });
  console.log('screenshot:', SCREENSHOT);
  noErrors(page, 'camera page');
  await page.context().close();

  // 2. ?debug=1: the latency corner.
  page = await newPage(cam);
  await page.goto(base + '/?debug=1');
  try {
    await page.waitForFunction(() => {
      const d = document.getElementById('debug');
      return !d.hidden && /frames [1-9]/.test(d.textContent) && /starry/.test(d.textContent);
    }, null, { timeout: 30000 });
    const text = await page.locator('#debug').textContent();
    const box = await page.locator('#debug').boundingBox();
    check('?debug=1: latency corner with round trip, server time and frames',
          /round trip \d+ ms/.test(text) && /server \d+(\.\d)? ms/.test(text) && /frames \d+/.test(text), text);
    check('?debug=1: the corner is in the top right and on screen', box && box.y < 100 && box.x + box.width <= PHONE.viewport.width
          && box.x > PHONE.viewport.width / 2, JSON.stringify(box));
  } catch (e) {
    check('?debug=1: latency corner shown', false, e.message);
  }
  noErrors(page, 'debug page');
  await page.context().close();

  // 2b. A busy server (503, Retry-After: 1): the client backs off instead of
  // retrying every frame, says so, and recovers when the server does.
  page = await newPage(cam);
  page.allowedErrors = /503/;
  let busyPosts = 0;
  await page.route('**/api/recognize*', (route) => {
    busyPosts++;
    return route.fulfill({ status: 503, headers: { 'Retry-After': '1', 'Content-Type': 'application/json' },
                           body: '{"error": "busy"}' });
  });
  await page.goto(base + '/');
  await page.waitForTimeout(3000);
  const during = busyPosts;
  check(`503: the client backs off (${during} requests in 3 s, at most 4)`, during >= 1 && during <= 4);
  check('503: the hint says the server is busy', /busy/i.test(await page.locator('#hint').textContent()),
        await page.locator('#hint').textContent());
  await page.unroute('**/api/recognize*');
  try {
    await waitTitle(page, TITLE, 30000);
    check('503: recovers once the server answers', true);
  } catch (e) {
    check('503: recovers once the server answers', false, JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'busy page');
  await page.context().close();

  // 3. No camera (permission refused): the upload fallback.
  page = await newPage(cam, () => {
    navigator.mediaDevices.getUserMedia = () => Promise.reject(new DOMException('Permission denied', 'NotAllowedError'));
  });
  await page.goto(base + '/');
  try {
    await page.locator('#upload').waitFor({ state: 'visible', timeout: 10000 });
    check('no camera: the upload fallback is offered', true);
  } catch (e) {
    check('no camera: the upload fallback is offered', false, JSON.stringify(await cardState(page)));
  }
  await page.setInputFiles('#file', path.join(tmp, 'photo.jpg'));
  try {
    await waitTitle(page, TITLE, 15000);
    check('upload: a photo of the painting shows its card', true);
    // The photo is the video's layout scaled up, so the painting is at the same frame coordinates.
    const u = await waitForOutline(page, scene.quad, scene.width, scene.height, 3000);
    check(`upload: outline drawn around the painting (${u.edgeHits}/${u.samples})`,
          u.edgeHits >= 0.9 * u.samples && u.corners === 4, JSON.stringify(u));
    check('upload: the photo is shown under the outline', await page.evaluate(() =>
      [...document.querySelectorAll('#stage img')].some((i) => i.offsetParent && i.naturalWidth > 0)));
    await page.screenshot({ path: SCREENSHOT.replace(/(\.png)?$/, '-upload.png') });
  } catch (e) {
    check('upload: a photo of the painting shows its card', false, JSON.stringify(await cardState(page)));
  }
  st = await cardState(page);
  check('upload: another photo can be chosen afterwards', st.uploadVisible, JSON.stringify(st));
  await page.setInputFiles('#file', path.join(SAMPLES, 'baboon.jpg'));
  try {
    await page.waitForFunction(() => document.getElementById('card').hidden && !document.getElementById('hint').hidden
      && /No painting/.test(document.getElementById('hint').textContent), null, { timeout: 15000 });
    check('upload: a photo without an exhibit says so and hides the card', true);
    const g = await outlineAt(page, scene.quad, scene.width, scene.height);
    check('upload: no outline left from the previous photo', g.green === 0, JSON.stringify(g));
  } catch (e) {
    check('upload: a photo without an exhibit says so and hides the card', false, JSON.stringify(await cardState(page)));
  }
  await page.setInputFiles('#file', path.join(tmp, 'building.jpg'));
  try {
    await waitTitle(page, 'Building', 15000);
    st = await cardState(page);
    check('upload: an exhibit without a link shows no link', !st.linkVisible && st.hint === null, JSON.stringify(st));
  } catch (e) {
    check('upload: a photo of another exhibit shows its card', false, JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'upload page');
  await page.context().close();

  // 4. Camera pointed at a wall without any exhibit: the hint stays. The first answers
  // are lost (connection problem), and the hint must come back once they arrive.
  const empty = await launch(path.join(tmp, 'empty.y4m'));
  page = await newPage(empty);
  page.allowedErrors = /ERR_FAILED/;
  let dropped = 0;
  await page.route('**/api/recognize*', (route) => (++dropped <= 2 ? route.abort('failed') : route.continue()));
  await page.goto(base + '/?debug=1');
  try {
    await page.waitForFunction(() => /Connection problem/.test(document.getElementById('hint').textContent), null, { timeout: 15000 });
    check('lost answers: the hint says so', true);
  } catch (e) {
    check('lost answers: the hint says so', false, JSON.stringify(await cardState(page)));
  }
  try {
    await page.waitForFunction(() => {
      const m = /frames (\d+)/.exec(document.getElementById('debug').textContent);
      return m && Number(m[1]) >= 5;
    }, null, { timeout: 30000 });
    st = await cardState(page);
    const g = await outlineAt(page, scene.quad, scene.width, scene.height);
    check('no exhibit in view (after the lost answers): the hint is shown, no card, no outline',
          st.hidden && st.hint === 'Point the camera at a painting' && g.green === 0, JSON.stringify({ st, green: g.green }));
    const hb = await page.locator('#hint').boundingBox();
    check('the hint is centred on one line', hb && Math.abs(hb.x + hb.width / 2 - PHONE.viewport.width / 2) < 2 && hb.height < 40,
          JSON.stringify(hb));
    await page.screenshot({ path: SCREENSHOT.replace(/(\.png)?$/, '-empty.png') });
  } catch (e) {
    check('no exhibit in view: frames are sent', false, JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'empty scene page');
  await page.context().close();

  await severalAtOnce(base, db);
}

// 5. Four exhibits in one frame (issue 20).
async function severalAtOnce(base, db) {
  const scene4 = JSON.parse(fs.readFileSync(path.join(tmp, 'scene4.json'), 'utf8'));
  const EXHIBITS = {  // sample name in scene4.json -> exhibit
    starry_night: { id: 'starry', title: TITLE },
    coffee: { id: 'coffee', title: 'Coffee' },
    building: { id: 'building', title: 'Building' },
    astronaut: { id: 'astronaut', title: 'Astronaut' },
  };
  for (const name of ['coffee', 'astronaut'])
    run(MVKP, ['db', 'add', db, '--id', EXHIBITS[name].id, '--image', path.join(SAMPLES, name + '.jpg'),
               '--title', EXHIBITS[name].title]);
  // The server reloads changed databases within --watch-db (2 s).
  let count = 0;
  for (let i = 0; i < 100 && count !== 4; i++) {
    await new Promise((ok) => setTimeout(ok, 100));
    count = (await (await fetch(base + '/healthz')).json()).exhibits;
  }
  if (count !== 4) return check('four exhibits: the server reloaded the database', false, 'exhibits ' + count);

  const names = Object.keys(scene4.quads);
  const browser = await launch(path.join(tmp, 'scene4.y4m'));
  // Every answer of /api/recognize as the page got it, with the prev it sent.
  const page = await newPage(browser, () => {
    window.__answers = [];
    const orig = window.fetch;
    window.fetch = async (...args) => {
      const r = await orig(...args);
      const url = String(args[0]);
      if (url.startsWith('/api/recognize') && r.ok) {
        const j = await r.clone().json();
        const prev = new URL(url, location.href).searchParams.get('prev');
        window.__answers.push({ t: performance.now(), prev: prev ? prev.split(',') : [],
                                found: j.found.map((f) => ({ id: f.id, outline: f.outline })) });
      }
      return r;
    };
  });
  const outlined = async () => {
    const r = {};
    for (const n of names) {
      const o = await outlineAt(page, scene4.quads[n], scene4.width, scene4.height);
      r[n] = o.edgeHits >= 0.9 * o.samples && o.corners === 4 && !o.centreGreen;
    }
    return r;
  };
  const all = (r) => names.every((n) => r[n]);
  const t0 = Date.now();
  await page.goto(base + '/');
  let first = -1, last = {};
  while (Date.now() - t0 < 30000) {
    last = await outlined();
    if (all(last)) { first = Date.now() - t0; break; }
    await page.waitForTimeout(50);
  }
  console.log(`four exhibits: all four outlined ${first} ms after page.goto`);
  check(`four exhibits: all four outlined where they are within ${TITLE_BUDGET_MS} ms (${first} ms)`,
        first >= 0 && first <= TITLE_BUDGET_MS, JSON.stringify(last));

  // 10 s of camera: overlay samples, and the answers behind them.
  const since = await page.evaluate(() => performance.now());
  let samples = 0, good = 0;
  const missing = {};
  const end = Date.now() + 10000;
  while (Date.now() < end) {
    const r = await outlined();
    samples++;
    if (all(r)) good++;
    for (const n of names) if (!r[n]) missing[n] = (missing[n] || 0) + 1;
    await page.waitForTimeout(100);
  }
  const answers = (await page.evaluate(() => window.__answers)).filter((a) => a.t >= since);
  // An answer is right when it holds exactly the four, each within 6 frame px (mean
  // corner distance; the video shakes by up to 2 px around the quads).
  const err = (outline, quad) => outline.reduce((e, [x, y], k) => e + Math.hypot(x - quad[k][0], y - quad[k][1]), 0) / 4;
  let right = 0, worst = 0, wrong = 0;
  for (const a of answers) {
    let ok = a.found.length === 4;
    for (const n of names) {
      const f = a.found.find((x) => x.id === EXHIBITS[n].id);
      if (!f) { ok = false; continue; }
      const e = err(f.outline, scene4.quads[n]);
      worst = Math.max(worst, e);
      if (e > 6) ok = false;
    }
    wrong += a.found.some((f) => !names.some((n) => EXHIBITS[n].id === f.id));
    if (ok) right++;
  }
  const withPrev4 = answers.filter((a) => a.prev.length === 4).length;
  console.log(`four exhibits over 10 s: overlay ${good}/${samples} samples with all four outlined` +
              ` (misses by painting ${JSON.stringify(missing)}); answers ${right}/${answers.length} with all four` +
              ` within 6 px (worst corner error ${worst.toFixed(1)} px), ${withPrev4} sent prev with all four`);
  check(`four exhibits: all four outlined in >= 95 % of overlay samples over 10 s (${good}/${samples})`,
        samples >= 20 && good >= 0.95 * samples);
  check(`four exhibits: >= 95 % of the answers over 10 s hold all four, each within 6 px (${right}/${answers.length})`,
        answers.length >= 20 && right >= 0.95 * answers.length);
  check('four exhibits: no other exhibit reported', wrong === 0, String(wrong));
  check(`four exhibits: the client sends prev with all four (${withPrev4}/${answers.length})`,
        withPrev4 >= 0.9 * answers.length);

  // Tapping an outline shows that exhibit's card, which stays while it is in view.
  const vp = PHONE.viewport;
  const s = Math.min(vp.width / scene4.width, vp.height / scene4.height);
  const ox = (vp.width - scene4.width * s) / 2, oy = (vp.height - scene4.height * s) / 2;
  for (const n of ['astronaut', 'coffee', 'building', 'starry_night']) {
    const q = scene4.quads[n];
    const cx = q.reduce((v, p) => v + p[0], 0) / 4, cy = q.reduce((v, p) => v + p[1], 0) / 4;
    await page.touchscreen.tap(ox + cx * s, oy + cy * s);
    try {
      await waitTitle(page, EXHIBITS[n].title, 3000);
      await page.waitForTimeout(1000);
      const st = await cardState(page);
      check(`four exhibits: tapping ${n} shows its card, kept for 1 s`, !st.hidden && st.title === EXHIBITS[n].title,
            JSON.stringify(st));
    } catch (e) {
      check(`four exhibits: tapping ${n} shows its card`, false, JSON.stringify(await cardState(page)));
    }
  }
  await page.screenshot({ path: SCREENSHOT.replace(/(\.png)?$/, '-four.png') });
  noErrors(page, 'four exhibits page');
  await page.context().close();
}

let stopping = false;
try {
  await main();
} catch (e) {
  failures.push('exception: ' + (e && e.stack || e));
  console.log('FAIL: exception:', e && e.stack || e);
} finally {
  for (const b of browsers) await b.close().catch(() => {});
  stopping = true;
  await stopServer();
}
console.log(`${passed} passed, ${failures.length} failed`);
if (failures.length) {
  console.log('failed:\n  ' + failures.join('\n  '));
  if (serverLog.length) console.log('server log (last lines):\n' + serverLog.join('\n'));
  process.exit(1);
}
process.exit(0);
