// Facetscan live page: status over Server-Sent Events (/api/events), the latest scan in 3D (view3d.js), its
// objects and pictures, and the history. A classic script; no build step. State for tests: window.facetApp.
(function () {
  'use strict';
  const $ = (id) => document.getElementById(id);
  const esc = FacetView.escape;
  const app = {
    viewer: null, status: null, scans: [], current: null, detail: null,
    // Per shown scan: {id, shownMs, lagMs (result -> 3D view shown), live (arrived while the page was open)}.
    metrics: [], events: 0,
  };
  window.facetApp = app;

  function setPill(el, cls, text) {
    el.className = 'pill ' + cls;
    el.textContent = text;
  }

  function showStatus(s) {
    app.status = s;
    const state = s.recognizing ? 'recognizing' : s.scanning ? 'scanning' : s.connected ? 'connected' : 'not connected';
    setPill($('scanner'), s.recognizing || s.scanning ? 'busy' : s.connected ? 'on' : 'off', 'scanner: ' + state);
    const pct = s.steps > 0 ? Math.min(100, 100 * s.stripes / s.steps) : 0;
    $('progress-bar').style.width = pct.toFixed(1) + '%';
    $('progress-text').textContent = 'stripe ' + s.stripes + ' / ' + s.steps + (s.scan_id ? '  (scan ' + s.scan_id + ')' : '');
    $('rate').textContent = s.stripes_per_s.toFixed(0) + ' stripes/s';
    $('lateness').textContent = s.loop
      ? 'loop: ' + s.loop.lateness_median_us.toFixed(0) + ' / ' + s.loop.lateness_p99_us.toFixed(0) + ' / ' +
        s.loop.lateness_max_us.toFixed(0) + ' µs' + (s.loop.overruns ? ', ' + s.loop.overruns + ' overruns' : '')
      : 'loop: -';
    $('faults').textContent = 'faults: ' + s.faults + (s.last_fault_code ? ' (last code ' + s.last_fault_code + ')' : '');
    $('faults').className = 'metric' + (s.faults ? ' bad' : '');
  }

  function timeText(ms) {
    return new Date(ms).toLocaleTimeString();
  }

  function renderHistory() {
    const tb = $('history').querySelector('tbody');
    tb.innerHTML = '';
    for (const s of app.scans) {
      const tr = document.createElement('tr');
      if (app.current === s.id) tr.className = 'current';
      const l = s.links || {};
      const files = [];
      if (l.report) files.push('<a href="' + esc(l.report) + '" target="_blank">report</a>');
      if (l.result) files.push('<a href="' + esc(l.result) + '" target="_blank">result.json</a>');
      if (l.fscan) files.push('<a href="' + esc(l.fscan) + '">.fscan</a>');
      tr.innerHTML = '<td>' + s.id + '</td><td>' + s.scan_id + '</td><td>' + timeText(s.result_unix_ms) + '</td><td>' +
        esc(s.status) + '</td><td>' + s.stripes + ' / ' + s.steps + '</td><td>' +
        s.objects.map((o) => '<span class="sw" style="background:' + esc(o.colour) + '"></span> ' + esc(o.model) +
          (o.instance > 0 ? ' #' + (o.instance + 1) : '')).join(', ') +
        '</td><td>' + s.recognition_ms.toFixed(0) + ' ms</td><td>' + files.join(' · ') + '</td>';
      tr.addEventListener('click', (e) => {
        if (e.target.tagName !== 'A') {
          $('follow').checked = false;
          showScan(s.id);
        }
      });
      tb.appendChild(tr);
    }
  }

  async function loadHistory() {
    const r = await fetch('/api/scans', { cache: 'no-store' });
    if (!r.ok) return;
    app.scans = (await r.json()).scans;
    renderHistory();
  }

  function renderObjects(d) {
    const ul = $('objects');
    ul.innerHTML = '';
    $('objects-count').textContent = '(' + d.objects.length + ')';
    d.objects.forEach((o, i) => {
      const li = document.createElement('li');
      li.dataset.index = i;
      li.innerHTML = '<span class="sw" style="background:' + esc(o.colour) + '"></span><span class="name">' +
        esc(FacetView.objectName(o)) + (o.ambiguous ? ' (ambiguous)' : '') + '</span><span class="conf">' +
        o.confidence.toFixed(2) + '</span>';
      li.addEventListener('click', () => app.viewer.select(i));
      ul.appendChild(li);
    });
    if (!d.objects.length) ul.innerHTML = '<li class="muted">no objects recognized' + (d.note ? ': ' + esc(d.note) : '') + '</li>';
  }

  function renderPictures(d) {
    const l = d.links || {};
    const pics = [['top_view', 'top view'], ['segmentation', 'segmentation'], ['pfrg', 'scene PFRG'], ['enm', 'extended needle map']];
    const have = pics.filter((p) => l[p[0]]);
    $('pictures').innerHTML = have.length
      ? have.map((p) => '<figure><a href="' + esc(l[p[0]]) + '" target="_blank"><img alt="' + p[1] + '" src="' + esc(l[p[0]]) +
        '"></a><figcaption>' + p[1] + '</figcaption></figure>').join('')
      : '<p class="muted">The 2D pictures come with the scan\'s report (serve with --out DIR).</p>';
    const links = [];
    if (l.report) links.push('<a href="' + esc(l.report) + '" target="_blank">report</a>');
    if (l.result) links.push('<a href="' + esc(l.result) + '" target="_blank">result.json</a>');
    if (l.fscan) links.push('<a href="' + esc(l.fscan) + '">recording (.fscan)</a>');
    if (l.ply) links.push('<a href="' + esc(l.ply) + '">objects.ply</a>');
    $('links').innerHTML = links.length ? '<h2>Files</h2>' + links.join(' · ') : '';
  }

  let loading = 0;
  async function showScan(id) {
    const token = ++loading;
    const [dr, pr] = await Promise.all([fetch('/api/scans/' + id, { cache: 'no-store' }), fetch('/api/scans/' + id + '/points', { cache: 'no-store' })]);
    if (!dr.ok) return;
    const d = await dr.json();
    const pts = pr.ok ? FacetView.decodePoints(await pr.arrayBuffer()) : null;
    if (token !== loading) return;  // a newer scan was asked for meanwhile
    app.current = id;
    app.detail = d;
    const empty = $('view-empty');
    if (empty) empty.remove();
    app.viewer.setScan(d, pts);
    $('scan-title').textContent = 'scan ' + d.scan.scan_id + ' (#' + id + ', ' + d.scan.status + ', ' + d.scan.stripes + '/' + d.scan.steps + ' stripes, ' + (pts ? pts.n : 0) + ' points shown)';
    renderObjects(d);
    $('details').textContent = 'Click an object (in the 3D view or in the list).';
    renderPictures(d);
    renderHistory();
    // The view is drawn (setScan renders synchronously); wait for the frame to be presented.
    requestAnimationFrame(() => {
      const now = Date.now();
      app.metrics.push({ id, shownMs: now, lagMs: now - d.scan.result_unix_ms, live: d.scan.result_unix_ms >= app.loadedAt });
    });
  }

  function connectEvents() {
    const es = new EventSource('/api/events');
    es.onopen = () => setPill($('link'), 'on', 'page: live');
    es.onerror = () => setPill($('link'), 'off', 'page: reconnecting');
    es.addEventListener('status', (e) => {
      ++app.events;
      showStatus(JSON.parse(e.data));
    });
    es.addEventListener('scan', (e) => {
      ++app.events;
      const s = JSON.parse(e.data);
      const known = app.scans.findIndex((x) => x.id === s.id);
      if (known >= 0) {
        // The same scan again, now with its report's links: update the links, keep the 3D view.
        app.scans[known] = s;
        renderHistory();
        if (app.current === s.id && app.detail) {
          app.detail.links = s.links;
          renderPictures(app.detail);
        }
        return;
      }
      app.scans.unshift(s);
      renderHistory();
      if (app.current === null || $('follow').checked) {
        showScan(s.id);
      }
    });
    app.eventSource = es;
  }

  function init() {
    app.viewer = FacetView.create($('view'), { mode: $('colour-mode').value });
    app.viewer.onSelect((i, o) => {
      document.querySelectorAll('#objects li').forEach((li) => li.classList.toggle('selected', Number(li.dataset.index) === i));
      $('details').innerHTML = o ? FacetView.objectDetailsHTML(o, app.detail) : 'Click an object (in the 3D view or in the list).';
    });
    $('colour-mode').addEventListener('change', (e) => app.viewer.setMode(e.target.value));
    $('reset-view').addEventListener('click', () => app.viewer.resetView());
    app.loadedAt = Date.now();
    loadHistory().then(() => {
      if (app.current === null && app.scans.length) showScan(app.scans[0].id);
    });
    connectEvents();
  }
  init();
})();
