// The museum guide's admin page (/admin): log in with the admin token, list,
// add, edit and delete exhibits, and show each exhibit's target quality.
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
      throw new ApiError(r.status, why);
    }
    return data;
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
      src: exhibitPath(x.id) + '/image?thumb=' + THUMB,
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
    fd.append('image', file, file.name);
    for (const k of ['id', 'title', 'artist', 'year', 'url']) fd.append(k, $('add-' + k).value.trim());
    fd.append('meta', metaText);
    const b = $('add-button');
    const result = $('add-result');
    result.hidden = true;
    busy(b, true, 'Training and assessing…');
    form.querySelectorAll('input, textarea').forEach((i) => { i.disabled = true; });
    try {
      const x = await api('POST', '/api/exhibits', fd);
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

  // ---- start -------------------------------------------------------------

  if (token) login(token);
  else showLogin('');
})();
