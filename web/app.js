/* SPDX-License-Identifier: MIT */
// app.js - the page's controller: the parameter form (from GET /v1/schemes),
// the job (submit, progress from its events, cancel), the before/after
// views coloured by the job's per-vertex fields, the metrics table and the
// downloads. Everything goes through the REST API (api.js).
//
// The input is shown as soon as it is chosen, as the daemon reads it: the
// page sends it as a one-step explicit job with fields (PREVIEW), shows that
// document's input arrays (the same positions, faces and curvature the
// smoothing job starts from, for every format the daemon reads: the page
// parses no mesh format) and deletes the job. Over PREVIEW_MAX_BYTES the
// page does not read it twice: the input shows with the job's result.
import * as api from './api.js';
import { Compare, defaultScale } from './view.js';

const $ = id => document.getElementById(id);
const FORMATS = [['obj', 'OBJ', '.obj'], ['draco', 'Draco', '.drc'], ['ply', 'PLY', '.ply'],
                 ['stl', 'STL', '.stl'], ['off', 'OFF', '.off'], ['glb', 'glTF binary', '.glb'],
                 ['gltf', 'glTF', '.gltf']];
const DEFAULT_ITERATIONS = 10; // Params.iterations' default (api/openapi.yaml)
// The input view's job: about the cheapest the daemon runs (one explicit
// step of 0.01 mean edges, written as binary STL) so that its fields carry
// the input as read. Its result is never shown; the job is deleted.
const PREVIEW = { scheme: 'euler', iterations: 1, strength: 0.01, format: 'stl' };
// Above this the page does not preview: the input is read once, by the
// smoothing job, and shows with its result. A preview costs the daemon a
// decode, the curvature and the metrics again; 32 MiB of OBJ is some 500k
// vertices, the size of dragon_vrip.drc (435k vertices in 1.3 MB of Draco,
// whose preview is measured by lab/bench/bench_ui.mjs).
const PREVIEW_MAX_BYTES = 32 << 20;

// file: the chosen mesh; preview: its input-view job's fields (null until
// read); fields: what the views show (a preview's or a finished job's).
const state = { file: null, job: null, fields: null, preview: null, busy: false };
// What the browser test and the dragon measurement read.
const perf = { succeededAt: 0, fieldsMs: 0, firstFrameMs: 0, chosenAt: 0, inputShownMs: 0 };
const compare = new Compare([$('before'), $('after')], [$('legend-before'), $('legend-after')]);
window.mcfd = { state, perf, compare };

function status(text, error = false) {
  $('status').textContent = text;
  $('status').classList.toggle('error', error);
}

function fail(e) {
  console.warn(e);
  if (e instanceof api.ApiError && e.status === 401) showToken('The token was refused.');
  status(e.message || String(e), true);
}

// ------------------------------------------------------------ token

function showToken(why) {
  $('token-box').hidden = false;
  $('token').focus();
  status(why, true);
}

$('token-apply').addEventListener('click', () => {
  api.setToken($('token').value);
  sessionStorage.setItem('mcfd-token', $('token').value);
  loadSchemes();
});
$('token').addEventListener('keydown', e => {
  if (e.key === 'Enter') { e.preventDefault(); $('token-apply').click(); }
});

// ------------------------------------------------------------ form

function schemeText(s) {
  const stab = s.stability === 'unconditional' ? 'unconditionally stable'
                                                : `stable for dt·λmax ≤ ${s.stability}`;
  return `${s.name} - order ${s.order}, ${s.explicit ? 'explicit' : 'implicit'}, ${stab}`;
}

async function loadSchemes() {
  let doc;
  try {
    doc = await api.getJSON('/v1/schemes');
  } catch (e) {
    if (e instanceof api.ApiError && e.status === 401)
      return showToken('This daemon needs its bearer token: type it above.');
    return fail(e);
  }
  const sel = $('scheme');
  sel.length = 1;
  state.schemes = doc.schemes;
  for (const s of doc.schemes) sel.add(new Option(schemeText(s), s.name));
  status('Choose a mesh.');
  updateRun();
}

$('scheme').addEventListener('change', () => {
  const s = (state.schemes || []).find(x => x.name === $('scheme').value);
  $('scheme-info').textContent = s ? `${s.title}. Best for: ${s.best_use}.` : '';
});
$('strength-auto').addEventListener('change', () => {
  $('strength').disabled = $('strength-auto').checked;
});

for (const [value, label] of FORMATS) $('format').add(new Option(label, value));

function params() {
  const p = {};
  const num = id => $(id).value.trim() === '' ? undefined : Number($(id).value);
  if ($('scheme').value) p.scheme = $('scheme').value;
  if ($('strength-auto').checked) p.strength = 'auto';
  else if (num('strength') !== undefined) p.strength = num('strength');
  if (num('iterations') !== undefined) p.iterations = num('iterations');
  if ($('boundary').value) p.boundary = $('boundary').value;
  if ($('rescale').value) p.rescale = $('rescale').value;
  if ($('adaptive').checked) p.adaptive = true;
  if ($('format').value) p.format = $('format').value;
  return p;
}

function counts(f) {
  return `${f.vertices.toLocaleString()} vertices, ${f.faces.toLocaleString()} faces`;
}

// A new mesh: what was shown of the last one goes, and the input is read
// by the daemon (preview) unless it is larger than PREVIEW_MAX_BYTES.
function chooseFile(f) {
  if (!f) return;
  if (state.busy) return status(`A job is running: cancel it before choosing ${f.name}.`, true);
  state.file = f;
  state.fields = state.preview = null;
  perf.chosenAt = performance.now();
  perf.inputShownMs = 0;
  $('mesh-name').textContent = `${f.name} (${(f.size / 1024).toFixed(0)} KiB)`;
  compare.setMeshes([null, null], new Uint32Array(0));
  for (const id of ['before-info', 'after-info', 'scale-before', 'scale-after', 'unit-before', 'unit-after'])
    $(id).replaceChildren();
  $('metrics').tBodies[0].replaceChildren();
  $('downloads').replaceChildren();
  $('progress').value = 0;
  $('scale-min').value = $('scale-max').value = '';
  updateRun();
  if (f.size > PREVIEW_MAX_BYTES) {
    status(`${f.name}: ${(f.size / 2 ** 20).toFixed(0)} MiB, more than the preview reads ` +
           `(${PREVIEW_MAX_BYTES >> 20} MiB): the input shows with the result. Press Smooth.`);
    return;
  }
  status(`Reading ${f.name} (the daemon decodes it)...`);
  preview(f).catch(e => {
    if (state.file !== f) return;
    if (e instanceof api.ApiError && e.status === 401) return fail(e);
    console.warn(e);
    if (e instanceof api.ApiError && e.status >= 500) // busy, draining: not the file's fault
      return status(`${f.name}: no input view (${e.message}); it shows with the result. Press Smooth.`);
    // the daemon's detail names the part that failed ("mesh: ply: ..."); a
    // step that failed would say so too (a preview's failure is not always
    // the file's)
    status(`${f.name}: no input view: ${e.message || e}`, true);
  });
}

// The PREVIEW job's fields document (null: another file was chosen
// meanwhile); the job is deleted once read. Throws what the daemon said
// when it cannot read the file.
async function previewFields(file) {
  const job = await api.submit(file, PREVIEW, null, true);
  try {
    let end = job;
    await api.follow(job.id, (type, data) => { if (type === 'status' || type === 'done') end = data; });
    if (!['succeeded', 'failed', 'canceled'].includes(end.status))
      end = await api.getJSON(`/v1/jobs/${job.id}`);
    if (end.status !== 'succeeded') throw new Error(end.error ? end.error.detail : `job ${end.status}`);
    return state.file === file ? await api.fields(job.id) : null;
  } finally {
    api.cancel(job.id).catch(e => console.warn(e)); // DELETE: the preview's job is not kept
  }
}

// The input view: the preview's input arrays, unless the smoothing job's
// own fields came first.
async function preview(file) {
  const f = await previewFields(file);
  if (!f || state.file !== file || state.fields) return;
  state.preview = state.fields = f;
  compare.setMeshes([f.arrays['input.positions'], null], f.arrays.faces);
  $('before-info').textContent = counts(f);
  $('after-info').textContent = 'shows when a job is done';
  resetScale();
  await compare.frame();
  perf.inputShownMs = performance.now() - perf.chosenAt;
  if (!state.busy) status(`${file.name}: ${counts(f)}, as the daemon reads it. Press Smooth.`);
}

function updateRun() {
  $('run').disabled = state.busy || !state.file || !state.schemes;
  $('cancel').disabled = !state.busy;
}

$('mesh').addEventListener('change', () => chooseFile($('mesh').files[0]));
const drop = $('drop');
drop.addEventListener('dragover', e => { e.preventDefault(); drop.classList.add('over'); });
drop.addEventListener('dragleave', () => drop.classList.remove('over'));
drop.addEventListener('drop', e => {
  e.preventDefault();
  drop.classList.remove('over');
  chooseFile(e.dataTransfer.files[0]);
});

// ------------------------------------------------------------ the job

// Submits the mesh with p and follows the job until it ends; resolves to
// the final Job document. With a target (a clean mesh of the same
// connectivity), the metrics measure the error before and after against it.
// onProgress(fraction or null when unknown, step, status, the core's phase
// when known: the default request reports phases, not steps).
async function runJob(file, target, p, onProgress, fields = false) {
  let job = await api.submit(file, p, target, fields);
  state.job = job;
  const planned = j => j.progress.steps ||
    (p.adaptive || p.time ? null : p.iterations || DEFAULT_ITERATIONS);
  await api.follow(job.id, (type, data) => {
    if (type === 'status' || type === 'done') {
      job = data;
      onProgress(data.status === 'succeeded' ? 1 : data.progress.fraction,
                 data.progress.step, data.status);
    } else if (type === 'progress') {
      const n = planned(job);
      onProgress(n ? Math.min(1, data.step / n) : null, data.step, 'running');
    } else if (type === 'work') {
      onProgress(data.fraction, data.step, 'running', data.phase);
    }
  });
  if (!['succeeded', 'failed', 'canceled'].includes(job.status))
    job = await api.getJSON(`/v1/jobs/${job.id}`);
  return job;
}

function showProgress(fraction, step, st, phase) {
  const bar = $('progress');
  if (fraction === null) bar.removeAttribute('value');
  else bar.value = fraction;
  status(st === 'queued' ? 'Queued...'
    : phase ? `${st}: ${phase} (${Math.round(100 * fraction)}%)` : `${st}: step ${step}`);
}

$('job-form').addEventListener('submit', async e => {
  e.preventDefault();
  if ($('run').disabled) return;
  state.busy = true;
  updateRun();
  $('progress').value = 0;
  status('Uploading...');
  try {
    state.jobFile = state.file;
    const job = await runJob(state.file, $('target').files[0] || null, params(), showProgress, true);
    if (job.status === 'canceled') {
      status(`Job canceled at step ${job.progress.step}: nothing was kept.`);
    } else if (job.status !== 'succeeded') {
      status(`Job ${job.status}: ${job.error ? job.error.detail : ''}`, true);
    } else {
      perf.succeededAt = performance.now();
      status('Done: loading the fields...');
      await showJob(job);
      status(`Done: job ${job.id}: ${summary(job.metrics)}.`);
    }
  } catch (err) {
    fail(err);
  } finally {
    state.busy = false;
    updateRun();
  }
});

$('cancel').addEventListener('click', async () => {
  if (!state.job) return;
  status('Canceling...'); // the job's last event says when it has stopped
  try {
    await api.cancel(state.job.id);
  } catch (e) {
    fail(e);
  }
});

// ------------------------------------------------------------ results

async function showJob(job) {
  const t0 = performance.now();
  const f = await api.fields(job.id);
  perf.fieldsMs = performance.now() - t0;
  state.fields = f;
  compare.setMeshes([f.arrays['input.positions'], f.arrays['result.positions']],
                    f.arrays.faces);
  $('before-info').textContent = $('after-info').textContent = counts(f);
  resetScale();
  await compare.frame();
  perf.firstFrameMs = performance.now() - perf.succeededAt;
  metricsTable(job.metrics);
  downloads(job);
}

// What the job did, as mcf's summary line says it; a filter that took no
// step says why nothing changed (the noise it read off the mesh).
function summary(m) {
  const f = m.flow, s = n => (n === 1 ? '' : 's');
  if (f.steps === 0)
    return `nothing to remove: the noise read is ${fmt(f.noise)} mean edges, so ${f.filter || m.scheme} ` +
           'took no step and the mesh is unchanged';
  if (/^fairing/.test(f.filter))
    return `${f.filter}, ${f.steps} step${s(f.steps)} for noise ${fmt(f.noise)} mean edges`;
  return `${m.scheme}, ${f.steps} step${s(f.steps)} to t = ${fmt(f.t_final)}`;
}

// The values view i shows for the chosen colour mode (null: plain). A
// preview has the input only (its job's result and displacement are not
// this smoothing's).
function values(i) {
  const f = state.fields, mode = $('colour').value;
  if (!f || mode === 'none') return null;
  if (f === state.preview && (i || mode === 'displacement')) return null;
  if (mode === 'displacement') return f.arrays.displacement;
  return f.arrays[`${i ? 'result' : 'input'}.${mode}`];
}

function stats(i) {
  const f = state.fields, mode = $('colour').value;
  if (f === state.preview && (i || mode === 'displacement')) return null;
  if (mode === 'displacement') return f.stats.displacement;
  return f.stats[`${i ? 'result' : 'input'}.${mode}`];
}

function fmt(x) {
  if (x === null || x === undefined || Number.isNaN(x)) return '-';
  if (typeof x !== 'number') return String(x);
  if (x === 0) return '0';
  const a = Math.abs(x);
  return a >= 1e4 || a < 1e-3 ? x.toExponential(3) : x.toPrecision(4);
}

// The scale of each view: shared (the inputs edit it) or each its own.
function scales() {
  const mode = $('colour').value;
  if ($('shared-scale').checked) {
    const lo = Number($('scale-min').value), hi = Number($('scale-max').value);
    return [[lo, hi], [lo, hi]];
  }
  return [0, 1].map(i => defaultScale(mode, stats(i)));
}

// What the legend's numbers measure: the mesh's length unit is its own.
const UNITS = { mean_curvature: 'mean curvature H, 1/length',
                gaussian_curvature: 'Gaussian curvature K, 1/length²',
                displacement: 'displacement, length' };

function recolour() {
  if (!state.fields) return;
  const mode = $('colour').value;
  const map = mode === 'displacement' ? 'sequential' : 'diverging';
  scales().forEach(([lo, hi], i) => {
    const v = values(i), shown = mode !== 'none' && compare.has(i);
    compare.colour(i, v, lo, hi, map);
    // the middle label: zero when a diverging scale spans it (view.js position)
    const mid = map === 'diverging' && lo < 0 && hi > 0 ? 0 : (lo + hi) / 2;
    $(i ? 'scale-after' : 'scale-before').replaceChildren(...(shown && v ?
      [lo, mid, hi].map(x => Object.assign(document.createElement('span'), { textContent: fmt(x) })) : []));
    $(i ? 'unit-after' : 'unit-before').textContent = shown && v ? UNITS[mode] : '';
  });
}

// The default shared scale: the smoothed mesh's (the input's in a preview).
function resetScale() {
  if (!state.fields) return;
  const [lo, hi] = defaultScale($('colour').value, stats(1) || stats(0));
  $('scale-min').value = lo.toPrecision(4);
  $('scale-max').value = hi.toPrecision(4);
  recolour();
}

$('colour').addEventListener('change', resetScale);
$('shared-scale').addEventListener('change', () => {
  $('scale-min').disabled = $('scale-max').disabled = !$('shared-scale').checked;
  recolour();
});
$('scale-min').addEventListener('change', recolour);
$('scale-max').addEventListener('change', recolour);
$('scale-reset').addEventListener('click', resetScale);
$('view-reset').addEventListener('click', () => compare.resetView());

function metricsTable(m) {
  const rows = [];
  const row = (name, before, after, warn = false) => rows.push([name, before, after, warn]);
  const one = (name, value, warn = false) => rows.push([name, value, null, warn]);
  const b = m.input.info, a = m.output.info, cb = m.curvature.before, ca = m.curvature.after;
  row('vertices / faces', `${b.vertices} / ${b.faces}`, `${a.vertices} / ${a.faces}`);
  if (m.compare) {
    const x = m.compare.before, y = m.compare.after;
    row('error vs target: RMS (relative)', fmt(x.rms_rel), fmt(y.rms_rel));
    row('error vs target: max', fmt(x.max_err), fmt(y.max_err));
    row('error vs target: normal angle (deg)', fmt(x.normal_angle_deg), fmt(y.normal_angle_deg));
  }
  row('mean curvature H: RMS', fmt(cb.H.rms), fmt(ca.H.rms));
  row('H: 5% .. 95%', `${fmt(cb.H.p05)} .. ${fmt(cb.H.p95)}`, `${fmt(ca.H.p05)} .. ${fmt(ca.H.p95)}`);
  row('Gaussian curvature K: RMS', fmt(cb.K.rms), fmt(ca.K.rms));
  row('total K (Gauss-Bonnet)', fmt(cb.total_K), fmt(ca.total_K));
  row('area', fmt(b.area), fmt(a.area));
  row('volume', fmt(m.flow.volume0), fmt(m.flow.volume1));
  const drift = (m.flow.volume1 - m.flow.volume0) / Math.abs(m.flow.volume0);
  one('volume drift', Number.isFinite(drift) ? `${(100 * drift).toFixed(3)} %` : '-');
  one('area ratio after/before', fmt(m.flow.area_ratio));
  one('folded faces', fmt(m.flow.folded_faces), m.flow.folded_faces > 0);
  one('warnings', m.warnings.length ? m.warnings.join(', ') : 'none', m.warnings.length > 0);
  one('scheme, steps', `${m.scheme}, ${m.flow.steps} (${m.flow.rejected} rejected)`);
  for (const k of ['queue_s', 'decode_s', 'flow_s', 'encode_s', 'metrics_s', 'total_s'])
    one(`time: ${k.replace('_s', '')} (s)`, fmt(m.timings[k]));
  const body = $('metrics').tBodies[0];
  body.replaceChildren(...rows.map(([name, x, y, warn]) => {
    const tr = document.createElement('tr');
    const th = Object.assign(document.createElement('th'), { scope: 'row', textContent: name });
    tr.append(th);
    const td = Object.assign(document.createElement('td'), { textContent: x });
    if (y === null) td.colSpan = 2;
    if (warn) td.className = 'warn';
    tr.append(td);
    if (y !== null) tr.append(Object.assign(document.createElement('td'), { textContent: y }));
    return tr;
  }));
}

// ------------------------------------------------------------ downloads

function save(blob, name) {
  const a = Object.assign(document.createElement('a'),
                          { href: URL.createObjectURL(blob), download: name });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}

// The job's own format at once; another one by running the same job with
// that format (a new job, deleted once its result is fetched).
async function download(job, format) {
  try {
    if (format === job.metrics.params.format) {
      const r = await api.result(job.id);
      return save(r.blob, r.name);
    }
    state.busy = true;
    updateRun();
    const p = { ...job.params, format };
    const again = await runJob(state.jobFile, null, p, (f, step) => {
      $('progress').value = f ?? 0;
      status(`Writing ${format}: step ${step}`);
    });
    if (again.status !== 'succeeded') throw new Error(`the ${format} job ${again.status}`);
    const r = await api.result(again.id);
    await api.cancel(again.id);
    save(r.blob, r.name);
    status(`Downloaded ${r.name}.`);
  } catch (e) {
    fail(e);
  } finally {
    state.busy = false;
    updateRun();
  }
}

function downloads(job) {
  $('downloads').replaceChildren(...FORMATS.map(([value, label, ext]) => {
    const b = Object.assign(document.createElement('button'),
                            { type: 'button', textContent: `${label} (${ext})` });
    b.addEventListener('click', () => download(job, value));
    return b;
  }));
}

// ------------------------------------------------------------ start

// Asks for the token first when the daemon needs one (and none was typed
// in this tab), rather than provoking a 401.
async function start() {
  const saved = sessionStorage.getItem('mcfd-token');
  if (saved) {
    $('token').value = saved;
    api.setToken(saved);
  }
  const config = await api.getJSON('/ui/config.json');
  if (config.token_required && !saved)
    return showToken('This daemon needs its bearer token: type it above.');
  if (config.token_required) $('token-box').hidden = false;
  return loadSchemes();
}
start().catch(fail);
