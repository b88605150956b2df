// mvkp museum guide: the service worker that keeps the visitor page usable
// offline for what was already seen. The page, its scripts, the site's name
// and logo, the exhibit list, every exhibit's information and picture are
// fetched from the network first (so changes show at once) and copied into
// the Cache API; when the network fails the copy is answered, marked with
// "X-Mvkp-Offline: 1" so the page can say so. Recognition (POST) and the
// admin page are never cached.
'use strict';
const CACHE = 'mvkp-visitor-v1';
const SHELL = ['/', '/style.css', '/app.js', '/ui.js', '/api/site'];

// Paths kept for offline use.
function kept(url) {
  if (url.origin !== self.location.origin) return false;
  const p = url.pathname;
  return p === '/' || p === '/index.html' || p === '/style.css' || p === '/app.js' || p === '/ui.js' ||
         p === '/api/site' || p === '/api/site/logo' || p === '/api/exhibits' ||
         /^\/api\/exhibits\/[^/]+$/.test(p) || (/^\/api\/exhibits\/[^/]+\/image$/.test(p) && url.searchParams.has('thumb'));
}

self.addEventListener('install', (ev) => {
  ev.waitUntil(caches.open(CACHE).then((c) => c.addAll(SHELL)).catch(() => {}).then(() => self.skipWaiting()));
});

self.addEventListener('activate', (ev) => {
  ev.waitUntil(caches.keys()
    .then((names) => Promise.all(names.filter((n) => n.startsWith('mvkp-visitor-') && n !== CACHE).map((n) => caches.delete(n))))
    .then(() => self.clients.claim()));
});

async function fromCache(req) {
  const hit = await caches.match(req, { ignoreVary: true }) ||
              (new URL(req.url).pathname === '/index.html' ? await caches.match('/') : undefined);
  if (!hit) return undefined;
  const headers = new Headers(hit.headers);
  headers.set('X-Mvkp-Offline', '1');
  return new Response(await hit.blob(), { status: hit.status, statusText: hit.statusText, headers });
}

self.addEventListener('fetch', (ev) => {
  const req = ev.request;
  if (req.method !== 'GET') return;
  const url = new URL(req.url);
  if (!kept(url)) return;
  if (req.referrer && new URL(req.referrer).pathname.startsWith('/admin')) return;  // the admin page: always live
  ev.respondWith((async () => {
    try {
      const res = await fetch(req);
      // Only whole, good answers are kept (not 304s, errors or partial bodies).
      if (res.status === 200) {
        const copy = res.clone();
        ev.waitUntil(caches.open(CACHE).then((c) => c.put(req, copy)).catch(() => {}));
      }
      return res;
    } catch (e) {
      const hit = await fromCache(req);
      if (hit) return hit;
      throw e;
    }
  })());
});
