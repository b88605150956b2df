// The museum guide's admin page (/admin): log in with the admin token, list,
// add, edit and delete exhibits, replace an exhibit's photo (retrained), import
// many from a CSV with photos or a ZIP, and show each exhibit's target quality.
// Plain JS; every piece of exhibit data goes into the page as text
// (textContent, attribute values), never as HTML.
'use strict';

(() => {
  const TOKEN_KEY = 'mvkp-admin-token';
  const THUMB = 160;  // px, longest side of the list's thumbnails (shown at half size: sharp on phones)
  const $ = (id) => document.getElementById(id);

  let token = sessionStorage.getItem(TOKEN_KEY) || '';
  let exhibits = [];        // from GET /api/exhibits
  const quality = new Map(); // id -> report, or {error}
  let generation = 0;       // a new list cancels the previous one's quality queue

  // ---- helpers -----------------------------------------------------------

  // An element with attributes and children (strings become text nodes).
  function el(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === undefined || v === null || v === false) continue;
      if (k === 'class') e.className = v;
      else if (k === 'text') e.textContent = v;
      else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
      else e.setAttribute(k, v === true ? '' : String(v));
    }
    for (const c of children) {
      if (c === null || c === undefined || c === false) continue;
      e.append(typeof c === 'string' ? document.createTextNode(c) : c);
    }
    return e;
  }

  const exhibitPath = (id) => '/api/exhibits/' + encodeURIComponent(id);

  // Only http(s) links become links (a stored "javascript:" URL stays text).
  function safeUrl(u) {
    try {
      const url = new URL(u);
      return url.protocol === 'http:' || url.protocol === 'https:' ? url.href : null;
    } catch (e) {
      return null;
    }
  }

  class ApiError extends Error {
    constructor(status, message) {
      super(message);
      this.status = status;
    }
  }

  // fetch with the token; JSON errors ({"error": "..."}) become ApiError.
  // A 503 (the server's connection bound, e.g. while the browser still holds
  // connections from loading thumbnails) is answered before any work is
  // done, so the request is sent again after Retry-After, a few times.
  async function api(method, path, body, headers) {
    let r;
    for (let attempt = 0; ; attempt++) {
      try {
        r = await fetch(path, {
          method,
          body,
          headers: Object.assign({ Authorization: 'Bearer ' + token }, headers || {}),
          cache: 'no-store',
        });
      } catch (e) {
        throw new ApiError(0, 'The server cannot be reached (' + e.message + ')');
      }
      if (r.status !== 503 || attempt >= 4) break;
      const wait = Math.min(5, Number(r.headers.get('Retry-After')) || 1);
      await new Promise((ok) => setTimeout(ok, wait * 1000));
    }
    if (r.status === 204) return null;
    const type = r.headers.get('Content-Type') || '';
    const data = type.startsWith('application/json') ? await r.json().catch(() => null) : null;
    if (!r.ok) {
      const why = data && typeof data.error === 'string' ? data.error : 'HTTP ' + r.status;
      if (r.status === 401 && path !== '/api/admin/check') {
        logout('The token was refused: log in again.');
      }
      const err = new ApiError(r.status, why);
      err.data = data;
      throw err;
    }
    return data;
  }

  // Phone photos (12-48 MP) are shrunk in the browser before upload: training
  // uses far fewer pixels, and the upload is a fraction of the size. Images
  // already small, and anything the browser cannot decode, go as they are
  // (the server then names the problem).
  const UPLOAD_MAX_SIDE = 2048;
  async function downscaled(file) {
    if (!file || typeof createImageBitmap !== 'function') return file;
    let bmp;
    try {
      bmp = await createImageBitmap(file);
    } catch (e) {
      return file;
    }
    const side = Math.max(bmp.width, bmp.height);
    if (side <= UPLOAD_MAX_SIDE) {
      bmp.close();
      return file;
    }
    const k = UPLOAD_MAX_SIDE / side;
    const c = document.createElement('canvas');
    c.width = Math.round(bmp.width * k);
    c.height = Math.round(bmp.height * k);
    const g = c.getContext('2d');
    g.imageSmoothingQuality = 'high';
    g.drawImage(bmp, 0, 0, c.width, c.height);
    bmp.close();
    const blob = await new Promise((ok) => c.toBlob(ok, 'image/jpeg', 0.92));
    if (!blob) return file;
    return new File([blob], file.name.replace(/\.[^.]*$/, '') + '.jpg', { type: 'image/jpeg' });
  }

  // POST/PUT of an exhibit's photo; when the server answers 409 because the
  // photo shows another exhibit, the curator decides (adding it anyway makes
  // both unrecognisable, so the default is no).
  async function sendPhoto(method, path, fd) {
    try {
      return await api(method, path, fd);
    } catch (e) {
      if (e.status !== 409 || !e.data || !Array.isArray(e.data.duplicates)) throw e;
      const names = e.data.duplicates.map((d) => '“' + d.id + '”').join(', ');
      if (!window.confirm('This photo looks like ' + names + ', already an exhibit. Two copies of one picture ' +
                          'make both unrecognisable. Add it anyway?')) throw e;
      fd.append('allow_duplicate', '1');
      return api(method, path, fd);
    }
  }

  let messageTimer = 0;
  function say(text, kind) {
    const m = $('message');
    clearTimeout(messageTimer);
    m.textContent = text;
    m.className = 'message ' + (kind || 'info');
    m.setAttribute('role', kind === 'error' ? 'alert' : 'status');
    m.hidden = !text;
    if (text && kind !== 'error') messageTimer = setTimeout(() => { m.hidden = true; }, 6000);
  }

  function busy(button, on, label) {
    if (on) {
      button.dataset.label = button.textContent;
      button.textContent = label;
      button.classList.add('busy');
    } else if (button.dataset.label) {
      button.textContent = button.dataset.label;
      button.classList.remove('busy');
    }
    button.disabled = on;
    button.setAttribute('aria-busy', on ? 'true' : 'false');
  }

  // ---- login -------------------------------------------------------------

  function showLogin(why) {
    $('main').hidden = true;
    $('logout').hidden = true;
    $('count').textContent = '';
    $('login').hidden = false;
    if (why) say(why, 'error');
    $('token').focus();
  }

  function logout(why) {
    token = '';
    sessionStorage.removeItem(TOKEN_KEY);
    generation++;
    showLogin(why);
  }

  async function login(candidate) {
    token = candidate;
    try {
      await api('GET', '/api/admin/check');
    } catch (e) {
      token = '';
      sessionStorage.removeItem(TOKEN_KEY);
      if (e.status === 401) return showLogin('Wrong token.');
      if (e.status === 403) return showLogin('The admin API is off: start `mvkp serve` with --admin-token-file.');
      return showLogin(e.message);
    }
    sessionStorage.setItem(TOKEN_KEY, token);
    $('login').hidden = true;
    $('main').hidden = false;
    $('logout').hidden = false;
    say('');
    await loadList();
  }

  $('login-form').addEventListener('submit', async (ev) => {
    ev.preventDefault();
    const b = $('login-button');
    busy(b, true, 'Checking…');
    await login($('token').value.trim());
    busy(b, false);
    $('token').value = '';
  });
  $('logout').addEventListener('click', () => logout(''));

  // ---- quality -----------------------------------------------------------

  const VERDICTS = { excellent: 'excellent', good: 'good', fair: 'fair', poor: 'poor' };

  // The quality badge and its details for one report (or state).
  function qualityView(q) {
    if (!q) return el('span', { class: 'badge pending', text: 'quality: queued' });
    if (q.state === 'running') {
      return el('span', { class: 'badge pending busy', text: 'assessing quality…' });
    }
    if (q.error) return el('span', { class: 'badge poor', title: q.error, text: 'quality: ' + q.error });
    const verdict = VERDICTS[q.verdict] || 'poor';
    const box = el('div', { class: 'quality' });
    box.append(el('span', { class: 'badge ' + verdict, title: 'target quality, 0-100' },
      'quality ' + q.score + '/100 · ' + q.verdict));
    const rate = typeof q.expected_detection_rate === 'number'
      ? Math.round(100 * q.expected_detection_rate) + '% expected detection' : '';
    if (rate) box.append(el('span', { class: 'muted small', text: ' ' + rate }));
    if (Array.isArray(q.reasons) && q.reasons.length) {
      const ul = el('ul', { class: 'reasons' });
      for (const r of q.reasons) {
        const lost = typeof r.lost === 'number' && r.lost >= 0.5 ? ' (−' + Math.round(r.lost) + ')' : '';
        ul.append(el('li', { text: String(r.message) + lost }));
      }
      // Open for a weak target: the reasons say what to fix (a flatter, sharper, fuller photo).
      box.append(el('details', { open: q.score < 60 }, el('summary', { text: 'Why ' + q.score + '?' }), ul));
    }
    return box;
  }

  function setQuality(id, q) {
    if (q) quality.set(id, q);
    const slot = document.querySelector('[data-quality-for="' + CSS.escape(id) + '"]');
    if (slot) slot.replaceChildren(qualityView(quality.get(id)));
  }

  // Fetches the reports one at a time (the server computes missing ones,
  // about 2 s each, one at a time anyway).
  async function fetchQualities(gen) {
    for (const x of exhibits) {
      if (gen !== generation) return;
      const id = x.id;
      const known = quality.get(id);
      if (known && known.added_at === x.added_at && !known.error) continue;
      setQuality(id, { state: 'running' });
      try {
        const q = await api('GET', exhibitPath(id) + '/quality');
        q.added_at = x.added_at;
        setQuality(id, q);
      } catch (e) {
        if (gen !== generation) return;
        setQuality(id, { error: e.message });
        if (e.status === 401) return;
      }
    }
  }

  // ---- list --------------------------------------------------------------

  function field(label, value, name, type) {
    const id = 'f-' + Math.random().toString(36).slice(2);
    const input = name === 'meta'
      ? el('textarea', { id, name, rows: 3, spellcheck: 'false' })
      : el('input', { id, name, type: type || 'text' });
    input.value = value === undefined || value === null ? '' : value;
    return [el('label', { for: id, text: label }), input];
  }

  function card(x) {
    const li = el('li', { class: 'item', 'data-id': x.id });
    const thumb = el('img', {
      class: 'thumb',
      // added_at changes with the photo: a replaced one is not taken from the browser's cache.
      src: exhibitPath(x.id) + '/image?thumb=' + THUMB + '&v=' + encodeURIComponent(x.added_at || ''),
      alt: x.title || x.id,
      loading: 'lazy',
      width: THUMB / 2,
      height: THUMB / 2,
    });
    thumb.addEventListener('error', () => thumb.classList.add('missing'), { once: true });

    const info = el('div', { class: 'info' });
    const view = el('div', { class: 'view' });
    view.append(el('h3', { text: x.title || '(untitled)' }));
    view.append(el('p', { class: 'muted small' }, el('code', { text: x.id }),
      ' · ' + x.width + '×' + x.height + ' px · added ' + String(x.added_at || '').replace('T', ' ')));
    const who = [x.artist, x.year].filter(Boolean).join(', ');
    if (who) view.append(el('p', { text: who }));
    if (x.url) {
      const href = safeUrl(x.url);
      view.append(el('p', { class: 'small' }, href
        ? el('a', { href, target: '_blank', rel: 'noopener noreferrer', text: x.url })
        : el('span', { class: 'muted', text: x.url })));
    }
    const meta = x.meta && typeof x.meta === 'object' && Object.keys(x.meta).length ? JSON.stringify(x.meta) : '';
    if (meta) view.append(el('p', { class: 'muted small' }, 'meta ', el('code', { text: meta })));
    view.append(el('div', { class: 'slot', 'data-quality-for': x.id }, qualityView(quality.get(x.id))));
    const actions = el('div', { class: 'actions' },
      el('button', { type: 'button', class: 'secondary', onclick: () => edit(li, x), text: 'Edit' }),
      el('button', { type: 'button', class: 'secondary', onclick: (ev) => replacePhoto(li, x, ev.currentTarget), text: 'Replace photo' }),
      el('button', { type: 'button', class: 'danger', onclick: (ev) => remove(x, ev.currentTarget), text: 'Delete' }));
    view.append(actions);
    info.append(view);
    li.append(thumb, info);
    return li;
  }

  function render() {
    const q = $('filter').value.trim().toLowerCase();
    const shown = exhibits.filter((x) => !q ||
      [x.id, x.title, x.artist, x.year].some((v) => String(v || '').toLowerCase().includes(q)));
    $('list').replaceChildren(...shown.map(card));
    $('empty').hidden = exhibits.length > 0;
    $('count').textContent = exhibits.length === 1 ? '1 exhibit' : exhibits.length + ' exhibits';
  }

  async function loadList() {
    const gen = ++generation;
    const b = $('refresh');
    busy(b, true, 'Loading…');
    try {
      const data = await api('GET', '/api/exhibits');
      if (gen !== generation) return;
      exhibits = data.exhibits || [];
      render();
    } catch (e) {
      if (e.status !== 401) say('Cannot list the exhibits: ' + e.message, 'error');
      return;
    } finally {
      busy(b, false);
    }
    fetchQualities(gen);
  }

  $('refresh').addEventListener('click', () => loadList());
  $('filter').addEventListener('input', () => render());

  // ---- edit / delete -----------------------------------------------------

  function edit(li, x) {
    const info = li.querySelector('.info');
    const form = el('form', { class: 'edit' });
    form.append(
      ...field('Title', x.title, 'title'),
      ...field('Artist', x.artist, 'artist'),
      ...field('Year', x.year, 'year'),
      ...field('Link', x.url, 'url', 'url'),
      ...field('Meta (JSON object)', JSON.stringify(x.meta || {}), 'meta'));
    const save = el('button', { type: 'submit', text: 'Save' });
    const cancel = el('button', { type: 'button', class: 'secondary', text: 'Cancel' });
    form.append(el('div', { class: 'actions' }, save, cancel));
    const view = info.querySelector('.view');
    view.hidden = true;
    info.append(form);
    form.elements.title.focus();
    cancel.addEventListener('click', () => { form.remove(); view.hidden = false; });
    form.addEventListener('submit', async (ev) => {
      ev.preventDefault();
      let meta;
      try {
        meta = JSON.parse(form.elements.meta.value.trim() || '{}');
      } catch (e) {
        return say('Meta is not valid JSON: ' + e.message, 'error');
      }
      if (!meta || typeof meta !== 'object' || Array.isArray(meta)) {
        return say('Meta must be a JSON object, e.g. {"width_m": 0.74}', 'error');
      }
      const body = {
        title: form.elements.title.value,
        artist: form.elements.artist.value,
        year: form.elements.year.value,
        url: form.elements.url.value,
        meta,
      };
      busy(save, true, 'Saving…');
      try {
        const updated = await api('PUT', exhibitPath(x.id), JSON.stringify(body), { 'Content-Type': 'application/json' });
        const i = exhibits.findIndex((e) => e.id === x.id);
        if (i >= 0) exhibits[i] = updated;
        li.replaceWith(card(updated));
        say('Saved “' + (updated.title || updated.id) + '”.', 'ok');
      } catch (e) {
        busy(save, false);
        say('Cannot save: ' + e.message, 'error');
      }
    });
  }

  async function remove(x, button) {
    if (!confirm('Delete “' + (x.title || x.id) + '” (' + x.id + ')? Visitors will no longer be able to recognise it. This cannot be undone.')) return;
    busy(button, true, 'Deleting…');
    try {
      await api('DELETE', exhibitPath(x.id));
      exhibits = exhibits.filter((e) => e.id !== x.id);
      quality.delete(x.id);
      render();
      say('Deleted “' + (x.title || x.id) + '”.', 'ok');
    } catch (e) {
      busy(button, false);
      say('Cannot delete: ' + e.message, 'error');
      if (e.status === 404) loadList();
    }
  }

  // A new photo for an exhibit: PUT .../image trains it like an add; if the
  // server refuses it, the old photo and model stay.
  function replacePhoto(li, x, button) {
    const input = el('input', { type: 'file', accept: 'image/jpeg,image/png', hidden: true });
    li.append(input);
    input.addEventListener('change', async () => {
      const f = input.files[0];
      input.remove();
      if (!f) return;
      busy(button, true, 'Training…');
      try {
        const fd = new FormData();
        const small = await downscaled(f);
        fd.append('image', small, small.name);
        const updated = await sendPhoto('PUT', exhibitPath(x.id) + '/image', fd);
        if (updated.quality) {
          updated.quality.added_at = updated.added_at;
          quality.set(updated.id, updated.quality);
        }
        const i = exhibits.findIndex((e) => e.id === x.id);
        if (i >= 0) exhibits[i] = updated;
        li.replaceWith(card(updated));
        say('Replaced the photo of “' + (updated.title || updated.id) + '” and retrained it.', 'ok');
      } catch (e) {
        busy(button, false);
        say('Cannot replace the photo (the old one stays): ' + e.message, 'error');
        if (e.status === 404) loadList();
      }
    });
    input.click();
  }

  // ---- bulk import -------------------------------------------------------
  // A loop over POST /api/exhibits, one row at a time: each row is checked and
  // trained exactly as a single add, its answer is its progress and its
  // error, and the server keeps no import state.

  // CSV as `mvkp db import` reads it: a header naming the columns, fields in
  // double quotes may hold commas and "" for a quote, no line breaks inside.
  function parseCsv(text) {
    const rows = [];
    const lines = text.replace(/^\uFEFF/, '').split('\n');
    let header = null;
    lines.forEach((raw, i) => {
      const line = raw.replace(/\r$/, '');
      const f = [];
      let cur = '', quoted = false;
      for (let k = 0; k < line.length; k++) {
        const c = line[k];
        if (quoted) {
          if (c === '"' && line[k + 1] === '"') { cur += '"'; k++; }
          else if (c === '"') quoted = false;
          else cur += c;
        } else if (c === '"') quoted = true;
        else if (c === ',') { f.push(cur); cur = ''; }
        else cur += c;
      }
      f.push(cur);
      if (!header) {
        header = f.map((h) => h.trim());
        if (!header.includes('id') || !header.includes('image')) throw new Error('the CSV header needs id and image columns');
        return;
      }
      if (!line.trim()) return;
      const row = { line: i + 1, unterminated: quoted };
      header.forEach((h, k) => { row[h] = f[k] === undefined ? '' : f[k]; });
      rows.push(row);
    });
    if (!header) throw new Error('the CSV is empty');
    return rows;
  }

  // The entries of a ZIP file (stored or deflated) as name -> Blob.
  async function unzip(file) {
    const buf = new DataView(await file.arrayBuffer());
    let eocd = -1;
    for (let i = buf.byteLength - 22; i >= Math.max(0, buf.byteLength - 65557); i--) {
      if (buf.getUint32(i, true) === 0x06054b50) { eocd = i; break; }
    }
    if (eocd < 0) throw new Error(file.name + ' is not a ZIP file');
    const count = buf.getUint16(eocd + 10, true);
    let p = buf.getUint32(eocd + 16, true);
    const out = new Map();
    const dec = new TextDecoder();
    for (let n = 0; n < count; n++) {
      if (p + 46 > buf.byteLength || buf.getUint32(p, true) !== 0x02014b50) throw new Error(file.name + ': damaged ZIP directory');
      const method = buf.getUint16(p + 10, true), size = buf.getUint32(p + 20, true);
      const nameLen = buf.getUint16(p + 28, true), extra = buf.getUint16(p + 30, true), comment = buf.getUint16(p + 32, true);
      const local = buf.getUint32(p + 42, true);
      const name = dec.decode(new Uint8Array(buf.buffer, p + 46, nameLen));
      p += 46 + nameLen + extra + comment;
      if (name.endsWith('/')) continue;
      if (local + 30 > buf.byteLength || buf.getUint32(local, true) !== 0x04034b50) throw new Error(file.name + ': damaged entry ' + name);
      const start = local + 30 + buf.getUint16(local + 26, true) + buf.getUint16(local + 28, true);
      if (start + size > buf.byteLength) throw new Error(file.name + ': truncated at ' + name);
      const data = new Blob([new Uint8Array(buf.buffer, start, size)]);
      if (method === 0) out.set(name, data);
      else if (method === 8) out.set(name, await new Response(data.stream().pipeThrough(new DecompressionStream('deflate-raw'))).blob());
      else throw new Error(file.name + ': ' + name + ' uses an unsupported compression');
    }
    return out;
  }

  let bulkStop = false;
  $('bulk-stop').addEventListener('click', () => { bulkStop = true; $('bulk-stop').disabled = true; });

  $('bulk-form').addEventListener('submit', async (ev) => {
    ev.preventDefault();
    const chosen = [...$('bulk-files').files];
    const files = new Map();  // name (and base name) -> Blob
    const put = (name, blob) => { files.set(name, blob); files.set(name.split('/').pop(), blob); };
    let csv = null, csvName = '';
    let rows;
    try {
      for (const f of chosen) {
        if (/\.zip$/i.test(f.name)) {
          for (const [name, blob] of await unzip(f)) {
            if (/\.csv$/i.test(name) && !csv) { csv = blob; csvName = f.name + ': ' + name; } else put(name, blob);
          }
        } else if (/\.csv$/i.test(f.name)) { csv = f; csvName = f.name; } else put(f.name, f);
      }
      if (!csv) throw new Error('choose a CSV list (with its photos) or a ZIP holding one');
      rows = parseCsv(await csv.text());
    } catch (e) {
      return say('Cannot import: ' + e.message, 'error');
    }
    const list = $('bulk-rows');
    const items = rows.map((r) => {
      const li = el('li', { class: 'waiting' }, el('span', { class: 'state', text: 'waiting' }),
        ' line ' + r.line + ' · ', el('code', { text: r.id || '(no id)' }), el('span', { class: 'why' }));
      return li;
    });
    list.replaceChildren(...items);
    $('bulk-result').hidden = false;
    const bar = $('bulk-progress');
    bar.max = Math.max(rows.length, 1);
    bar.value = 0;
    const b = $('bulk-button');
    busy(b, true, 'Importing…');
    bulkStop = false;
    $('bulk-stop').hidden = false;
    $('bulk-stop').disabled = false;
    let added = 0, failed = 0;
    const mark = (i, kind, text, why) => {
      items[i].className = kind;
      items[i].querySelector('.state').textContent = text;
      items[i].querySelector('.why').textContent = why ? ' — ' + why : '';
    };
    for (let i = 0; i < rows.length && !bulkStop; i++) {
      const r = rows[i];
      $('bulk-summary').textContent = csvName + ': row ' + (i + 1) + ' of ' + rows.length + ' (line ' + r.line + ')…';
      mark(i, 'running', 'training');
      items[i].scrollIntoView({ block: 'nearest' });
      const image = files.get(r.image) || files.get(String(r.image).split('/').pop());
      try {
        if (r.unterminated) throw new Error('unterminated quoted field (fields cannot span lines)');
        if (!r.id || !r.image) throw new Error('needs an id and an image');
        if (!image) throw new Error('photo “' + r.image + '” was not chosen (or is not in the ZIP)');
        const fd = new FormData();
        const small = await downscaled(image);
        fd.append('image', small, small === image ? String(r.image).split('/').pop() : small.name);
        for (const k of ['id', 'title', 'artist', 'year', 'url']) fd.append(k, (r[k] || '').trim());
        fd.append('meta', (r.meta || '').trim() || '{}');
        const x = await api('POST', '/api/exhibits', fd);
        if (x.quality) {
          x.quality.added_at = x.added_at;
          quality.set(x.id, x.quality);
        }
        added++;
        mark(i, 'ok', 'added', x.quality ? 'quality ' + x.quality.score + '/100, ' + x.quality.verdict : '');
      } catch (e) {
        failed++;
        mark(i, 'error', 'failed', e.message);
        if (e.status === 401) break;
      }
      bar.value = i + 1;
    }
    const left = rows.length - added - failed;
    $('bulk-summary').textContent = csvName + ': ' + added + ' added, ' + failed + ' failed' +
      (left ? ', ' + left + ' not tried (stopped)' : '') + ' of ' + rows.length + ' rows.';
    $('bulk-stop').hidden = true;
    busy(b, false);
    say('Import: ' + added + ' added, ' + failed + ' failed.', failed ? 'error' : 'ok');
    if (added) loadList();
  });

  // ---- add ---------------------------------------------------------------

  let previewUrl = '';
  $('add-image').addEventListener('change', () => {
    const f = $('add-image').files[0];
    const img = $('add-preview');
    if (previewUrl) URL.revokeObjectURL(previewUrl);
    previewUrl = f ? URL.createObjectURL(f) : '';
    img.hidden = !f;
    if (f) img.src = previewUrl;
    else img.removeAttribute('src');
    // Suggest an id from the file name.
    if (f && !$('add-id').value) {
      $('add-id').value = f.name.replace(/\.[^.]*$/, '').toLowerCase().replace(/[^a-z0-9_-]+/g, '-').replace(/^-+|-+$/g, '');
    }
  });

  $('add-form').addEventListener('submit', async (ev) => {
    ev.preventDefault();
    const form = ev.currentTarget;
    const file = $('add-image').files[0];
    if (!file) return say('Choose a photo first.', 'error');
    const metaText = $('add-meta').value.trim() || '{}';
    try {
      const m = JSON.parse(metaText);
      if (!m || typeof m !== 'object' || Array.isArray(m)) throw new Error('not an object');
    } catch (e) {
      return say('Meta must be a JSON object, e.g. {"width_m": 0.74}', 'error');
    }
    const fd = new FormData();
    const small = await downscaled(file);
    fd.append('image', small, small.name);
    for (const k of ['id', 'title', 'artist', 'year', 'url']) fd.append(k, $('add-' + k).value.trim());
    fd.append('meta', metaText);
    const b = $('add-button');
    const result = $('add-result');
    result.hidden = true;
    busy(b, true, 'Training and assessing…');
    form.querySelectorAll('input, textarea').forEach((i) => { i.disabled = true; });
    try {
      const x = await sendPhoto('POST', '/api/exhibits', fd);
      if (x.quality) {
        x.quality.added_at = x.added_at;
        quality.set(x.id, x.quality);
      }
      const secs = x.time_ms && x.time_ms.total ? ' in ' + (x.time_ms.total / 1000).toFixed(1) + ' s' : '';
      result.replaceChildren(
        el('p', {}, 'Added ', el('strong', { text: x.title || x.id }), secs + '.'),
        x.quality ? qualityView(x.quality) : '');
      result.hidden = false;
      say('Added “' + (x.title || x.id) + '”.', 'ok');
      form.reset();
      $('add-meta').value = '{}';
      $('add-preview').hidden = true;
      if (previewUrl) URL.revokeObjectURL(previewUrl);
      previewUrl = '';
      await loadList();
    } catch (e) {
      say('Cannot add: ' + e.message, 'error');
    } finally {
      form.querySelectorAll('input, textarea').forEach((i) => { i.disabled = false; });
      busy(b, false);
    }
  });

  // ---- database quality ------------------------------------------------------

  // GET /api/admin/quality: every exhibit's score (cached on the server by
  // the exhibit's added_at) and the look-alike pairs; weakest exhibits first.
  $('dbq-button').addEventListener('click', async () => {
    const b = $('dbq-button');
    busy(b, true, 'Checking…');
    try {
      const r = await api('GET', '/api/admin/quality');
      const n = r.exhibits.length;
      const pairs = r.lookalikes || [];
      $('dbq-summary').textContent = n + (n === 1 ? ' exhibit' : ' exhibits') + ', ' +
        (pairs.length ? pairs.length + (pairs.length === 1 ? ' look-alike' : ' look-alikes')
          : 'no exhibits that look alike') + ' (' + (r.time_ms / 1000).toFixed(1) + ' s, ' +
        r.assessed_now + ' assessed now).';
      $('dbq-pairs').replaceChildren(...pairs.map((p) => el('li', { class: 'poor' },
        el('strong', { text: p.a }), ' is recognised as ', el('strong', { text: p.b }),
        ' in ' + p.found_in + ' of ' + p.probes + ' tries (up to ' + p.inliers + ' matching points)')));
      const rows = r.exhibits.slice().sort((x, y) =>
        (x.quality ? x.quality.score : -1) - (y.quality ? y.quality.score : -1));
      $('dbq-scores').replaceChildren(...rows.map((x) => {
        if (x.quality) setQuality(x.id, Object.assign({ added_at: x.added_at }, x.quality));
        return el('li', {}, el('strong', { text: x.title || x.id }), ' ',
          x.quality ? qualityView(x.quality) : el('span', { class: 'badge poor', text: x.error || 'not assessed' }));
      }));
      $('dbq-result').hidden = false;
    } catch (e) {
      say('Cannot check the database: ' + e.message, 'error');
    } finally {
      busy(b, false);
    }
  });

  // ---- start -------------------------------------------------------------

  if (token) login(token);
  else showLogin('');
})();
