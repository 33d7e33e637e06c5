// The review page: the drop list (sorted, filtered, a page at a time), one
// drop's frames with what was fitted there, its plots, and the decisions,
// each saved at once by the server into review.csv.
'use strict';
(function () {
  const token = new URLSearchParams(location.search).get('token') || '';
  const $ = (id) => document.getElementById(id);
  const PAGE_ROWS = 50;
  const list = { drops: [], key: 'n', up: true, page: 0 };
  let drop = null; // the open drop: { run, data, frames, at: index, byFrame: Map }
  let frameRequest = 0;
  let shown = null; // { x0, z0, zoom, height } of the picture shown

  function url(path, params) {
    const q = new URLSearchParams(params || {});
    q.set('token', token);
    return path + '?' + q.toString();
  }
  async function answer(r) {
    let j = null;
    try { j = await r.json(); } catch (e) { j = null; }
    if (!r.ok) throw new Error((j && j.error) || (r.status + ' ' + r.statusText));
    return j;
  }
  async function getJSON(path, params) { return answer(await fetch(url(path, params))); }
  async function post(path, body) {
    return answer(await fetch(url(path), {
      method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body),
    }));
  }
  function say(text, bad) {
    const s = $('said');
    s.textContent = text;
    s.className = bad ? 'bad' : 'good';
  }
  function el(tag, attrs, text) {
    const e = document.createElement(tag);
    for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  // A value with its one-sigma error, the error to two significant digits.
  function pm(pair) {
    const v = pair && pair[0], e = pair && pair[1];
    if (v === null || v === undefined) return '—';
    if (e === null || e === undefined || !(e > 0)) return String(+v.toPrecision(6));
    const d = Math.max(0, Math.min(12, 1 - Math.floor(Math.log10(e))));
    return v.toFixed(d) + ' ± ' + e.toFixed(d);
  }

  // ---------------------------------------------------------------- list
  async function loadList() {
    const j = await getJSON('/api/drops');
    list.drops = j.drops;
    $('where').textContent = 'output folder ' + j.out + ' · decisions saved at once in ' +
      j.review_file + ' · `dropscope run` (or `process`) applies them';
    drawList();
  }
  function sortValue(d, key) {
    const v = d[key];
    if (Array.isArray(v)) return v[0];
    return v;
  }
  function shownDrops() {
    const text = $('filter').value.trim().toLowerCase();
    const status = $('status-filter').value;
    let rows = list.drops.filter((d) =>
      (!status || d.status === status) &&
      (!text || (d.run + ' ' + d.flags + ' ' + d.reason + ' ' + d.review).toLowerCase().includes(text)));
    const k = list.key, sign = list.up ? 1 : -1;
    rows = rows.slice().sort((a, b) => {
      const x = sortValue(a, k), y = sortValue(b, k);
      if (x === y) return a.n - b.n;
      if (x === null || x === undefined) return 1;
      if (y === null || y === undefined) return -1;
      return (x < y ? -1 : 1) * sign;
    });
    return rows;
  }
  function drawList() {
    const rows = shownDrops();
    const pages = Math.max(1, Math.ceil(rows.length / PAGE_ROWS));
    list.page = Math.min(list.page, pages - 1);
    const body = document.querySelector('#drops tbody');
    body.textContent = '';
    for (const d of rows.slice(list.page * PAGE_ROWS, (list.page + 1) * PAGE_ROWS)) {
      const tr = el('tr', { 'data-run': d.run, id: 'row-' + d.n });
      tr.appendChild(el('td', { class: 'num' }, String(d.n)));
      tr.appendChild(el('td', { class: 'run' }, d.run));
      tr.appendChild(el('td', { class: 'num' }, String(d.radius_mm)));
      const st = el('td');
      st.appendChild(el('span', { class: 'badge ' + d.status }, d.status));
      tr.appendChild(st);
      for (const k of ['v', 'delta', 'a', 'tau', 'e']) tr.appendChild(el('td', { class: 'num' }, pm(d[k])));
      const notes = el('td', { class: 'notes' });
      const parts = [d.flags, d.reason].filter((s) => s);
      notes.appendChild(document.createTextNode(parts.join(' · ')));
      if (d.decided.length) {
        notes.appendChild(el('div', { class: 'decided' }, 'in review.csv: ' + d.decided.join(', ')));
      }
      tr.appendChild(notes);
      tr.addEventListener('click', () => openDrop(d.run));
      body.appendChild(tr);
    }
    $('count').textContent = rows.length + ' of ' + list.drops.length + ' drops';
    $('page-no').textContent = 'page ' + (list.page + 1) + ' of ' + pages;
    $('prev-page').disabled = list.page === 0;
    $('next-page').disabled = list.page >= pages - 1;
    document.querySelectorAll('#drops th[data-sort]').forEach((th) => {
      th.classList.toggle('sorted', th.dataset.sort === list.key);
      th.classList.toggle('up', th.dataset.sort === list.key && list.up);
    });
  }
  document.querySelectorAll('#drops th[data-sort]').forEach((th) => th.addEventListener('click', () => {
    const k = th.dataset.sort;
    list.up = list.key === k ? !list.up : true;
    list.key = k;
    drawList();
  }));
  $('filter').addEventListener('input', () => { list.page = 0; drawList(); });
  $('status-filter').addEventListener('change', () => { list.page = 0; drawList(); });
  $('prev-page').addEventListener('click', () => { list.page -= 1; drawList(); });
  $('next-page').addEventListener('click', () => { list.page += 1; drawList(); });

  // ---------------------------------------------------------------- one drop
  async function openDrop(run) {
    try {
      say('opening ' + run + '…');
      const data = await getJSON('/api/run', { run: run });
      const t = data.track;
      const byFrame = new Map();
      t.frame.forEach((f, i) => byFrame.set(f, i));
      drop = { run: run, data: data, frames: data.frames, at: 0, byFrame: byFrame };
      $('list').hidden = true;
      $('drop').hidden = false;
      history.replaceState(null, '', '#run=' + encodeURIComponent(run));
      $('drop-title').textContent = run;
      const rec = data.record;
      $('drop-status').textContent = '';
      $('drop-status').appendChild(el('span', { class: 'badge ' + rec.status }, rec.status));
      $('drop-reason').textContent = [rec.flags && rec.flags !== '-' ? rec.flags : '', rec.reason && rec.reason !== '-' ? rec.reason : '',
        data.problem ? 'frames shown without edge points: ' + data.problem : ''].filter((s) => s).join(' · ');
      const s = data.surface;
      $('surf-row').value = s.row_at_impact_px === null ? '' : s.row_at_impact_px.toFixed(2);
      drawDecisions(data.decisions);
      const start = data.events.max !== null ? data.events.max : (data.frames.length ? data.frames[0] : null);
      drop.at = Math.max(0, data.frames.indexOf(start));
      $('ex-first').value = $('ex-last').value = data.frames.length ? data.frames[drop.at] : '';
      drawPlots();
      say(run + ': ' + data.frames.length + ' frames');
      await showFrame();
    } catch (e) {
      say(e.message, true);
    }
  }
  // Back to the list, read again first (it shows the decisions just made),
  // so that the rows shown are never replaced under the pointer.
  $('back').addEventListener('click', async () => {
    try { await loadList(); } catch (e) { say(e.message, true); }
    drop = null;
    history.replaceState(null, '', location.pathname + location.search);
    $('drop').hidden = true;
    $('list').hidden = false;
  });

  function currentFrame() { return drop.frames[drop.at]; }
  async function showFrame() {
    if (!drop || !drop.frames.length) return;
    const frame = currentFrame();
    $('frame-no').value = frame;
    drawCursor();
    const mine = ++frameRequest;
    const view = $('view').value;
    const r = await fetch(url('/api/frame', { run: drop.run, frame: frame, view: view }));
    if (mine !== frameRequest) return;
    if (!r.ok) {
      let j = null;
      try { j = await r.json(); } catch (e) { j = null; }
      say((j && j.error) || r.statusText, true);
      return;
    }
    const v = (r.headers.get('X-Dropscope-View') || '0 0 1').split(' ').map(Number);
    const blob = await r.blob();
    if (mine !== frameRequest) return;
    const img = $('frame');
    const old = img.src;
    img.onload = () => {
      shown = { x0: v[0], z0: v[1], zoom: v[2] };
      img.dataset.frame = String(frame);
      if (old && old.startsWith('blob:')) URL.revokeObjectURL(old);
    };
    img.src = URL.createObjectURL(blob);
    const i = drop.byFrame.get(frame);
    const t = drop.data.track;
    const bits = ['frame ' + frame];
    if (i !== undefined) {
      bits.push('t = ' + (t.t_s[i] * 1e3).toFixed(3) + ' ms');
      if (t.z_px[i] !== null) bits.push('z = ' + t.z_px[i].toFixed(3) + ' px');
      if (t.delta_mm[i] !== null) bits.push('δ = ' + t.delta_mm[i].toFixed(4) + ' mm');
      if (t.residual_px[i] !== null) bits.push('residual ' + t.residual_px[i].toFixed(3) + ' px, ' + t.edge_points[i] + ' points');
      if (t.flags[i]) bits.push(t.flags[i]);
    }
    if (excludedFrame(frame)) bits.push('EXCLUDED');
    $('frame-info').textContent = bits.join(' · ');
  }
  function step(k) {
    if (!drop) return;
    drop.at = Math.max(0, Math.min(drop.frames.length - 1, drop.at + k));
    showFrame();
  }
  function goFrame(frame) {
    if (!drop || frame === null || frame === undefined) return;
    let best = 0;
    drop.frames.forEach((f, i) => { if (Math.abs(f - frame) < Math.abs(drop.frames[best] - frame)) best = i; });
    drop.at = best;
    showFrame();
  }
  $('first').addEventListener('click', () => step(-1e9));
  $('prev').addEventListener('click', () => step(-1));
  $('next').addEventListener('click', () => step(1));
  $('last').addEventListener('click', () => step(1e9));
  $('go-onset').addEventListener('click', () => goFrame(drop && drop.data.events.onset));
  $('go-max').addEventListener('click', () => goFrame(drop && drop.data.events.max));
  $('go-rebound').addEventListener('click', () => goFrame(drop && drop.data.events.rebound));
  $('frame-no').addEventListener('change', () => goFrame(Number($('frame-no').value)));
  $('view').addEventListener('change', () => showFrame());
  document.addEventListener('keydown', (e) => {
    if (!drop) return;
    const tag = e.target && e.target.tagName;
    if (tag === 'INPUT' || tag === 'SELECT' || tag === 'TEXTAREA') return;
    if (e.key === 'ArrowLeft') { step(-1); e.preventDefault(); }
    else if (e.key === 'ArrowRight') { step(1); e.preventDefault(); }
    else if (e.key === 'Home') { step(-1e9); e.preventDefault(); }
    else if (e.key === 'End') { step(1e9); e.preventDefault(); }
  });

  // The surface row placed by a click on the frame: the clicked row moved
  // along the image's tilt to the impact column.
  $('frame').addEventListener('click', (e) => {
    if (!$('surf-pick').checked || !shown || !drop) return;
    const img = $('frame');
    const k = img.naturalWidth / img.clientWidth;
    const u = e.offsetX * k, v = e.offsetY * k;
    const x = shown.x0 + u / shown.zoom - 0.5, z = shown.z0 + v / shown.zoom - 0.5;
    const s = drop.data.surface;
    const slope = s.slope || 0, xi = s.impact_column_px === null ? x : s.impact_column_px;
    $('surf-row').value = (z + slope * (xi - x)).toFixed(2);
  });
  $('surf-pick').addEventListener('change', () => $('frame').classList.toggle('picking', $('surf-pick').checked));

  // ---------------------------------------------------------------- plots
  const SVG = 'http://www.w3.org/2000/svg';
  function svgEl(tag, attrs) {
    const e = document.createElementNS(SVG, tag);
    for (const k in attrs) e.setAttribute(k, attrs[k]);
    return e;
  }
  const W = 460, H = 150, L = 48, R = 8, T = 8, B = 22;
  function excludedFrame(frame) {
    return drop.data.decisions.some((d) => d.decision === 'exclude' && d.frames && frame >= d.frames.first && frame <= d.frames.last);
  }
  function plot(id, values, down) {
    const svg = $(id);
    svg.textContent = '';
    const t = drop.data.track.t_s;
    const pts = [];
    const [a, b] = t.length ? plotRange(t) : [0, 0];
    values.forEach((v, i) => {
      if (v !== null && v !== undefined && isFinite(v) && t[i] >= a && t[i] <= b) pts.push([t[i], v, i]);
    });
    if (!t.length) return;
    const [t0, t1] = plotRange(t);
    let lo = Infinity, hi = -Infinity;
    pts.forEach((p) => { lo = Math.min(lo, p[1]); hi = Math.max(hi, p[1]); });
    if (!pts.length) { lo = 0; hi = 1; }
    if (hi <= lo) { hi = lo + 1; }
    const X = (tt) => L + (tt - t0) / (t1 - t0) * (W - L - R);
    const Y = (v) => down ? T + (v - lo) / (hi - lo) * (H - T - B) : H - B - (v - lo) / (hi - lo) * (H - T - B);
    svg.appendChild(svgEl('rect', { x: L, y: T, width: W - L - R, height: H - T - B, fill: '#fff', stroke: '#999' }));
    for (const [label, v] of [[hi, hi], [lo, lo]]) {
      const tx = svgEl('text', { x: L - 4, y: Y(v) + 3, 'text-anchor': 'end' });
      tx.textContent = +label.toPrecision(4);
      svg.appendChild(tx);
    }
    for (const [tt, anchor] of [[t0, 'start'], [t1, 'end']]) {
      const tx = svgEl('text', { x: X(tt), y: H - 6, 'text-anchor': anchor });
      tx.textContent = (tt * 1e3).toFixed(2) + ' ms';
      svg.appendChild(tx);
    }
    const ev = drop.data.events;
    for (const f of [ev.onset, ev.max, ev.rebound]) {
      const i = drop.byFrame.get(f);
      if (i === undefined) continue;
      svg.appendChild(svgEl('line', { x1: X(t[i]), x2: X(t[i]), y1: T, y2: H - B, stroke: '#1f4e79', 'stroke-dasharray': '3 3' }));
    }
    const frames = drop.data.track.frame;
    for (const [tt, v, i] of pts) {
      const ex = excludedFrame(frames[i]);
      svg.appendChild(svgEl('circle', { cx: X(tt), cy: Y(v), r: ex ? 2.6 : 1.6, fill: ex ? '#e600e6' : '#1b1b1b' }));
    }
    svg.appendChild(svgEl('line', { class: 'cursor', x1: 0, x2: 0, y1: T, y2: H - B, stroke: '#d00', 'stroke-width': 1.5 }));
    svg.onclick = (e) => {
      const box = svg.getBoundingClientRect();
      const sx = (e.clientX - box.left) / box.width * W;
      const tt = t0 + (sx - L) / (W - L - R) * (t1 - t0);
      let best = 0;
      t.forEach((v, i) => { if (Math.abs(v - tt) < Math.abs(t[best] - tt)) best = i; });
      goFrame(frames[best]);
    };
    svg.dataset.t0 = t0;
    svg.dataset.t1 = t1;
  }
  // The plots' time span: every frame, or the contact with a third of its
  // length each side (every frame when the events are not known).
  function plotRange(t) {
    let t0 = t[0], t1 = t[t.length - 1];
    const ev = drop.data.events, i0 = drop.byFrame.get(ev.onset), i1 = drop.byFrame.get(ev.rebound);
    if ($('plot-range').value === 'contact' && i0 !== undefined && i1 !== undefined && t[i1] > t[i0]) {
      const m = Math.max((t[i1] - t[i0]) / 3, 3 / (drop.data.fps || 1e4));
      t0 = Math.max(t0, t[i0] - m);
      t1 = Math.min(t1, t[i1] + m);
    }
    return [t0, t1 > t0 ? t1 : t0 + 1e-6];
  }
  $('plot-range').addEventListener('change', () => { if (drop) { drawPlots(); drawCursor(); } });
  function drawPlots() {
    const t = drop.data.track;
    plot('plot-z', t.z_px, true);
    plot('plot-delta', t.delta_mm, false);
    plot('plot-res', t.residual_px, false);
  }
  function drawCursor() {
    const i = drop.byFrame.get(currentFrame());
    for (const id of ['plot-z', 'plot-delta', 'plot-res']) {
      const svg = $(id), c = svg.querySelector('line.cursor');
      if (!c) continue;
      if (i === undefined) { c.setAttribute('visibility', 'hidden'); continue; }
      const t0 = Number(svg.dataset.t0), t1 = Number(svg.dataset.t1);
      const tt = drop.data.track.t_s[i];
      const x = L + (tt - t0) / (t1 - t0) * (W - L - R);
      c.setAttribute('x1', x);
      c.setAttribute('x2', x);
      c.setAttribute('visibility', tt >= t0 && tt <= t1 ? 'visible' : 'hidden');
    }
  }

  // ---------------------------------------------------------------- decisions
  function frameText(f) { return f.first === f.last ? String(f.first) : f.first + ':' + f.last; }
  function drawDecisions(rows) {
    drop.data.decisions = rows;
    const ul = $('decisions');
    ul.textContent = '';
    if (!rows.length) ul.appendChild(el('li', { class: 'hint' }, 'none yet'));
    for (const d of rows) {
      let what = d.decision;
      if (d.frames) what += ' frames ' + frameText(d.frames);
      if (d.value !== undefined && d.value !== null) what += ' row ' + d.value + ' px';
      const li = el('li', {}, what + ': ' + d.reason + ' (' + d.time + ') ');
      const b = el('button', { type: 'button', class: 'withdraw' }, 'withdraw');
      b.addEventListener('click', () => decide('/api/withdraw', {
        run: drop.run, decision: d.decision, frames: d.frames ? frameText(d.frames) : null,
      }, 'withdrawn'));
      li.appendChild(b);
      ul.appendChild(li);
    }
  }
  async function decide(path, body, done) {
    try {
      const j = await post(path, body);
      drawDecisions(j.decisions);
      drawPlots();
      say(done + ' — saved in review.csv at ' + new Date().toLocaleTimeString());
      await showFrame();
    } catch (e) {
      say(e.message, true);
    }
  }
  $('ex-from-here').addEventListener('click', () => { $('ex-first').value = currentFrame(); });
  $('ex-to-here').addEventListener('click', () => { $('ex-last').value = currentFrame(); });
  $('ex-save').addEventListener('click', () => {
    const a = $('ex-first').value.trim(), b = $('ex-last').value.trim() || a;
    decide('/api/decide', {
      run: drop.run, decision: 'exclude', frames: a === b ? a : a + ':' + b, reason: $('ex-reason').value,
    }, 'frames ' + (a === b ? a : a + ' to ' + b) + ' excluded');
  });
  $('surf-save').addEventListener('click', () => {
    const v = $('surf-row').value.trim();
    decide('/api/decide', {
      run: drop.run, decision: 'surface', value: v === '' ? null : Number(v), reason: $('surf-reason').value,
    }, 'surface row set to ' + v + ' px');
  });
  $('reject').addEventListener('click', () => decide('/api/decide', {
    run: drop.run, decision: 'reject', reason: $('verdict-reason').value,
  }, drop.run + ' rejected'));
  $('accept').addEventListener('click', () => decide('/api/decide', {
    run: drop.run, decision: 'accept', reason: $('verdict-reason').value,
  }, drop.run + ': flags accepted'));

  // `#run=NAME` in the address opens that drop (a link to it, kept
  // across reloads); going back to the list clears it.
  function hashRun() {
    const m = /^#run=(.*)$/.exec(location.hash);
    return m ? decodeURIComponent(m[1]) : null;
  }
  loadList()
    .then(() => { const r = hashRun(); if (r) return openDrop(r); return null; })
    .catch((e) => say(e.message, true));
})();
