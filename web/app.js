// mvkp museum guide client: the rear camera's frames go to /api/recognize
// (a new one whenever the previous answer is back), the recognised
// painting's outline is drawn over the video and its information shown on a
// card (asked once per exhibit, then cached). No framework.
'use strict';
(function () {
  const MAX_SIDE = 640;            // frames are downscaled to this longest side
  const video = document.getElementById('video');
  const overlay = document.getElementById('overlay');
  const ctx = overlay.getContext('2d');
  const hint = document.getElementById('hint');
  const card = document.getElementById('card');
  const debug = document.getElementById('debug');
  const ui = window.mvkpUi;        // ui.js: card, list, site, camera hint, frame-to-screen fit
  const params = new URLSearchParams(location.search);
  const showDebug = params.get('debug') === '1';
  const info = new Map();          // exhibit id -> information (fetched once)
  const grab = document.createElement('canvas');
  let idleHint = hint.textContent; // shown while nothing is recognised
  let prev = '';                   // last exhibit seen: temporal focus on the server
  let shown = '';
  let lastMs = 0, frames = 0;

  debug.hidden = !showDebug;

  // The server is busy (503) or refusing (429, 5xx): not "nothing found".
  // The outline stays; the loop waits Retry-After or a growing back-off.
  class Busy extends Error {
    constructor(status, retryAfterS) {
      super('busy ' + status);
      this.status = status;
      this.waitMs = Math.max(0, retryAfterS || 0) * 1000;
    }
  }
  let backoffMs = 0;

  async function exhibit(id) {
    if (!info.has(id)) {
      const r = await fetch('/api/exhibits/' + encodeURIComponent(id));
      info.set(id, r.ok ? await r.json() : { id: id, title: id });
    }
    return info.get(id);
  }

  async function showCard(id) {
    if (id === shown) return;
    shown = id;
    if (!id) { ui.hideCard(); return; }
    const e = await exhibit(id);
    if (shown !== id) return;
    ui.showCard(e);
  }

  // Maps frame pixels to overlay pixels as the video (object-fit: cover) or photo (contain) is shown.
  function draw(found, fw, fh) {
    overlay.width = overlay.clientWidth * devicePixelRatio;
    overlay.height = overlay.clientHeight * devicePixelRatio;
    ctx.clearRect(0, 0, overlay.width, overlay.height);
    const { s, ox, oy } = ui.fit(overlay.width, overlay.height, fw, fh);
    ctx.lineWidth = 4 * devicePixelRatio;
    ctx.strokeStyle = '#3f3';
    ctx.fillStyle = '#3f3';
    ctx.font = (18 * devicePixelRatio) + 'px system-ui, sans-serif';
    for (const f of found) {
      ctx.beginPath();
      f.outline.forEach(([x, y], i) => (i ? ctx.lineTo : ctx.moveTo).call(ctx, ox + x * s, oy + y * s));
      ctx.closePath();
      ctx.stroke();
      const [x0, y0] = f.outline[0];
      ctx.fillText(f.title || f.id, ox + x0 * s + 6, oy + y0 * s - 8);
    }
  }

  async function recognise(source, w, h) {
    const scale = Math.min(1, MAX_SIDE / Math.max(w, h));
    grab.width = Math.round(w * scale);
    grab.height = Math.round(h * scale);
    grab.getContext('2d').drawImage(source, 0, 0, grab.width, grab.height);
    const blob = await new Promise((ok) => grab.toBlob(ok, 'image/jpeg', 0.85));
    const t0 = performance.now();
    const r = await fetch('/api/recognize' + (prev ? '?prev=' + encodeURIComponent(prev) : ''),
                          { method: 'POST', headers: { 'Content-Type': 'image/jpeg' }, body: blob });
    lastMs = performance.now() - t0;
    if (r.status === 503 || r.status === 429 || r.status >= 500)
      throw new Busy(r.status, parseFloat(r.headers.get('Retry-After')));
    backoffMs = 0;
    const j = r.ok ? await r.json() : { found: [] };
    const found = j.found || [];
    draw(found, grab.width, grab.height);
    if (!found.length) hint.textContent = idleHint;  // also after 'Connection problem'
    hint.hidden = found.length > 0;
    prev = found.length ? found[0].id : '';
    await showCard(prev);
    frames++;
    if (showDebug) {
      debug.textContent = 'round trip ' + lastMs.toFixed(0) + ' ms\nserver ' +
        (j.time_ms ? j.time_ms.total.toFixed(1) : '-') + ' ms\nframes ' + frames + (prev ? '\n' + prev : '');
    }
    return found;
  }

  async function loop() {
    try {
      if (video.readyState >= 2 && video.videoWidth) await recognise(video, video.videoWidth, video.videoHeight);
    } catch (e) {
      // Back off: 0.5 s, 1 s, 2 s ... 8 s, or what the server asks.
      backoffMs = Math.min(8000, backoffMs ? 2 * backoffMs : 500);
      const busy = e instanceof Busy;
      hint.textContent = busy ? 'Server busy, retrying' : 'Connection problem, retrying';
      hint.hidden = false;
      await new Promise((ok) => setTimeout(ok, Math.max(backoffMs, busy ? e.waitMs : 0)));
    }
    requestAnimationFrame(loop);   // the next frame once the answer is back
  }

  // No camera: recognise a chosen photo, shown under the outline; another can be chosen.
  function fallback(err) {
    const upload = document.getElementById('upload');
    const photo = document.getElementById('photo');
    upload.hidden = false;
    hint.textContent = ui.cameraProblem(err);
    idleHint = 'No painting recognised in this photo';
    photo.onload = async () => {
      video.hidden = true;
      photo.hidden = false;
      upload.classList.add('again');
      prev = '';
      try {
        await recognise(photo, photo.naturalWidth, photo.naturalHeight);
      } catch (e) {
        hint.textContent = 'Connection problem, try again';
        hint.hidden = false;
      }
    };
    photo.onerror = () => { hint.textContent = 'Cannot read this photo'; hint.hidden = false; };
    document.getElementById('file').addEventListener('change', (ev) => {
      const file = ev.target.files[0];
      if (!file) return;
      if (photo.src) URL.revokeObjectURL(photo.src);
      photo.src = URL.createObjectURL(file);
    });
  }

  if (!navigator.mediaDevices || !navigator.mediaDevices.getUserMedia) { fallback(); return; }
  navigator.mediaDevices.getUserMedia({ video: { facingMode: { ideal: 'environment' }, width: { ideal: 1280 } }, audio: false })
    .then((stream) => { video.srcObject = stream; return video.play(); })
    .then(loop)
    .catch(fallback);
})();
