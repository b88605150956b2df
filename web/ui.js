// mvkp museum guide, the visitor page around the camera loop of app.js: the
// museum's name and colours (GET /api/site), the exhibit card (picture,
// title, artist, year, description from meta.description, link), the exhibit
// list with search, the camera-permission hint with the take/choose-a-photo
// fallback, offline cards (sw.js) and the mapping of frame pixels to the
// screen. app.js calls window.mvkpUi: showCard(exhibit), hideCard(),
// cameraProblem(error), fit(w, h, frameW, frameH). No framework.
'use strict';
(function () {
  const THUMB = 480;               // card picture: longest side in px (about 240 CSS px at 2x)
  const LIST_THUMB = 128;
  const $ = (id) => document.getElementById(id);
  const stage = $('stage');
  const card = $('card');
  const hint = $('hint');
  const announce = $('announce');
  const list = $('list');
  const listButton = $('list-open');
  const search = $('list-search');
  let exhibits = null;             // GET /api/exhibits, once per opening of the list
  let returnFocus = null;          // where focus goes when a card opened from the list closes
  let cardId = '';
  let unreachable = false;         // the last list came from the offline copy (sw.js)

  // Only http(s) links become links (the server refuses others; rows stored
  // before it did stay text).
  function safeUrl(u) {
    if (!u) return null;
    try {
      const url = new URL(u, location.href);
      return url.protocol === 'http:' || url.protocol === 'https:' ? url.href : null;
    } catch (e) {
      return null;
    }
  }

  function description(e) {
    const m = e && e.meta;
    return m && typeof m === 'object' && typeof m.description === 'string' ? m.description : '';
  }

  function thumbUrl(id, n) {
    return '/api/exhibits/' + encodeURIComponent(id) + '/image?thumb=' + n;
  }

  // --- the museum: name, colours, logo, intro ---------------------------------

  // WCAG relative luminance of "#rrggbb".
  function luminance(hex) {
    const c = [1, 3, 5].map((i) => parseInt(hex.substr(i, 2), 16) / 255)
      .map((v) => (v <= 0.03928 ? v / 12.92 : Math.pow((v + 0.055) / 1.055, 2.4)));
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
  }
  function contrast(a, b) {
    const la = luminance(a), lb = luminance(b);
    return (Math.max(la, lb) + 0.05) / (Math.min(la, lb) + 0.05);
  }

  function applySite(s) {
    const root = document.documentElement.style;
    const c = s.colors || {};
    if (c.background) root.setProperty('--bg', c.background);
    if (c.text) root.setProperty('--fg', c.text);
    if (c.accent) {
      root.setProperty('--accent', c.accent);
      // Text on accent buttons: black or white, whichever reads better (always >= 4.5:1).
      root.setProperty('--on-accent', contrast(c.accent, '#000000') >= contrast(c.accent, '#ffffff') ? '#000' : '#fff');
    }
    if (s.name) {
      $('site-name').textContent = s.name;
      document.title = s.name;
    }
    const logo = $('site-logo');
    logo.hidden = !s.logo;
    if (s.logo) logo.src = s.logo;
    for (const el of document.querySelectorAll('.site-intro')) {
      el.textContent = s.intro || '';
      el.hidden = !s.intro;
    }
  }

  fetch('/api/site').then((r) => (r.ok ? r.json() : null)).then((s) => { if (s) applySite(s); }).catch(() => {});

  // --- frame pixels to screen pixels ------------------------------------------

  // The video fills the screen (object-fit: cover: scaled to cover, centred,
  // the overflow cropped); a chosen photo is shown whole (contain). Returns
  // the scale and offset mapping a frameW x frameH frame onto a w x h box.
  function fit(w, h, frameW, frameH) {
    const cover = !stage.classList.contains('photo');
    const s = (cover ? Math.max : Math.min)(w / frameW, h / frameH);
    return { s: s, ox: (w - frameW * s) / 2, oy: (h - frameH * s) / 2 };
  }

  // --- the card -----------------------------------------------------------------

  // Exhibits shown on this page, and those asked again through the service
  // worker. A page the worker did not control from the start fetched their
  // information past it (app.js), so it is asked once more to be kept offline.
  const seen = new Set(), kept = new Set();
  const controlledAtStart = !!(navigator.serviceWorker && navigator.serviceWorker.controller);
  function keep(id) {
    if (controlledAtStart || kept.has(id) || !navigator.serviceWorker || !navigator.serviceWorker.controller) return;
    kept.add(id);
    fetch('/api/exhibits/' + encodeURIComponent(id)).catch(() => kept.delete(id));
  }

  function fillCard(e) {
    cardId = e.id;
    seen.add(e.id);
    keep(e.id);
    const title = e.title || e.id;
    $('card-title').textContent = title;
    $('card-artist').textContent = e.artist || '';
    $('card-artist').hidden = !e.artist;
    $('card-year').textContent = e.year || '';
    $('card-year').hidden = !e.year;
    const d = description(e);
    $('card-desc').textContent = d;
    $('card-desc').hidden = !d;
    const link = $('card-link');
    const href = safeUrl(e.url);
    link.hidden = !href;
    if (href) {
      link.href = href;
      link.setAttribute('aria-label', 'More about ' + title + ' (opens a new tab)');
    } else {
      link.removeAttribute('href');
    }
    const img = $('card-img');
    img.alt = 'Picture of ' + title + (e.artist ? ' by ' + e.artist : '');
    img.hidden = false;
    img.onerror = () => { img.hidden = true; };  // offline and never seen, or no stored image
    img.src = thumbUrl(e.id, THUMB);
    card.hidden = false;
  }

  // From the camera loop: shown and announced, focus stays where it is.
  function showCard(e) {
    if (!card.hidden && card.classList.contains('detail')) return;  // the visitor is reading another
    fillCard(e);
    announce.textContent = [e.title || e.id, e.artist, e.year].filter(Boolean).join(', ');
  }

  function hideCard() {
    if (card.classList.contains('detail')) return;  // opened from the list: closed by the visitor
    card.hidden = true;
    cardId = '';
  }

  // From the list: a dialog-like card that takes focus and gives it back.
  function openCard(e, from) {
    returnFocus = from || null;
    closeList(false);
    fillCard(e);
    card.classList.add('detail');
    card.focus();
  }

  function closeCard() {
    card.hidden = true;
    card.classList.remove('detail');
    cardId = '';
    if (returnFocus && document.contains(returnFocus)) {
      openList(false);
      returnFocus.focus();
    }
    returnFocus = null;
  }
  $('card-close').addEventListener('click', closeCard);

  // --- the exhibit list -----------------------------------------------------------

  // Lower case, accents removed: "Musée" matches "musee".
  const fold = (s) => String(s || '').normalize('NFD').replace(/[\u0300-\u036f]/g, '').toLowerCase();

  async function cachedIds() {
    if (!('caches' in window)) return null;
    try {
      const ids = new Set();
      for (const name of await caches.keys()) {
        for (const req of await (await caches.open(name)).keys()) {
          const m = /\/api\/exhibits\/([^/?]+)$/.exec(new URL(req.url).pathname);
          if (m) ids.add(decodeURIComponent(m[1]));
        }
      }
      return ids;
    } catch (e) {
      return null;
    }
  }

  async function loadList() {
    const status = $('list-count');
    try {
      const r = await fetch('/api/exhibits');
      if (!r.ok) throw new Error('HTTP ' + r.status);
      unreachable = r.headers.get('X-Mvkp-Offline') === '1';
      exhibits = (await r.json()).exhibits || [];
      onlineState();
    } catch (e) {
      exhibits = null;
      status.textContent = navigator.onLine === false || e instanceof TypeError
        ? 'Offline: the list needs a connection.' : 'The list cannot be loaded now.';
      $('list-items').replaceChildren();
      return;
    }
    renderList();
  }

  async function renderList() {
    if (!exhibits) return;
    const q = fold(search.value.trim());
    const seen = isOffline() ? await cachedIds() : null;
    const items = exhibits.filter((e) => !q || fold([e.title, e.artist, e.year, e.id, description(e)].join(' ')).includes(q));
    const ul = $('list-items');
    ul.replaceChildren(...items.map((e) => {
      const li = document.createElement('li');
      const b = document.createElement('button');
      b.type = 'button';
      b.className = 'item';
      b.dataset.id = e.id;
      const img = document.createElement('img');
      img.alt = '';
      img.loading = 'lazy';
      img.width = img.height = 56;
      img.src = thumbUrl(e.id, LIST_THUMB);
      img.onerror = () => { img.style.visibility = 'hidden'; };
      const text = document.createElement('span');
      const t = document.createElement('strong');
      t.textContent = e.title || e.id;
      const sub = document.createElement('span');
      sub.textContent = [e.artist, e.year].filter(Boolean).join(', ');
      text.append(t, sub);
      b.append(img, text);
      if (seen && !seen.has(e.id)) {
        b.disabled = true;
        b.title = 'Not available offline';
      }
      b.addEventListener('click', () => openCard(e, b));
      li.append(b);
      return li;
    }));
    $('list-count').textContent = items.length === exhibits.length
      ? exhibits.length + ' exhibit' + (exhibits.length === 1 ? '' : 's')
      : items.length + ' of ' + exhibits.length + ' match "' + search.value.trim() + '"';
  }

  function openList(reload) {
    list.hidden = false;
    listButton.setAttribute('aria-expanded', 'true');
    if (reload !== false) {
      search.focus();
      loadList();
    }
  }

  function closeList(focusButton) {
    list.hidden = true;
    listButton.setAttribute('aria-expanded', 'false');
    if (focusButton !== false) listButton.focus();
  }

  listButton.addEventListener('click', () => (list.hidden ? openList() : closeList()));
  $('list-close').addEventListener('click', () => closeList());
  search.addEventListener('input', renderList);
  document.addEventListener('keydown', (ev) => {
    if (ev.key !== 'Escape') return;
    if (!card.hidden && card.classList.contains('detail')) closeCard();
    else if (!list.hidden) closeList();
  });

  // --- no camera: why, how to allow it, and photos instead -------------------------

  function cameraProblem(err) {
    const name = err && err.name;
    const secure = window.isSecureContext;
    let why;
    if (!secure) {
      why = 'This page was opened without HTTPS, and phones only give the camera to secure (https://) pages. ' +
            'Ask the museum staff for the https address.';
    } else if (name === 'NotAllowedError' || name === 'SecurityError') {
      why = 'Camera access was refused. To allow it, tap the camera or lock icon beside the address, ' +
            'choose Allow for the camera, then try again. On an iPhone: Settings, Safari, Camera, Allow.';
    } else if (name === 'NotFoundError' || name === 'OverconstrainedError' || !navigator.mediaDevices) {
      why = 'No camera was found on this device.';
    } else if (name === 'NotReadableError' || name === 'AbortError') {
      why = 'The camera is in use by another app. Close it, then try again.';
    } else {
      why = 'The camera could not be started.';
    }
    $('permission-text').textContent = why;
    $('permission-https').hidden = !secure;  // else the text above says it already
    $('permission').hidden = false;
    $('upload').hidden = false;
    stage.classList.add('no-camera');
    hint.textContent = 'No camera: use a photo instead';
    return hint.textContent;
  }

  $('retry-camera').addEventListener('click', () => location.reload());
  $('file').addEventListener('change', (ev) => {
    if (!ev.target.files[0]) return;
    $('permission').hidden = true;
    stage.classList.add('photo');
    $('upload-label').textContent = 'Take or choose another photo';
  });

  // --- offline ------------------------------------------------------------------------

  const isOffline = () => navigator.onLine === false || unreachable;
  function onlineState() {
    $('offline').hidden = !isOffline();
  }
  window.addEventListener('online', () => { unreachable = false; onlineState(); if (!list.hidden) renderList(); });
  window.addEventListener('offline', () => { onlineState(); if (!list.hidden) renderList(); });
  onlineState();

  // The service worker keeps the page, the site and every exhibit and picture
  // seen, for when the connection goes. Browsers allow it on https:// and
  // localhost only; without it the page works as before.
  if ('serviceWorker' in navigator && window.isSecureContext) {
    navigator.serviceWorker.register('/sw.js').catch((e) => console.info('no offline copy:', e.message));
    // On the first visit the worker takes over while the page runs: what was
    // fetched before (or in flight) is asked again, through it, to be kept.
    navigator.serviceWorker.addEventListener('controllerchange', () => {
      for (const id of seen) {
        keep(id);
        fetch(thumbUrl(id, THUMB)).catch(() => {});
      }
    });
  }

  window.mvkpUi = { showCard, hideCard, cameraProblem, fit, openList, closeList, get cardId() { return cardId; } };
})();
