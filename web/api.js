/* SPDX-License-Identifier: MIT */
// api.js - the page's client of the mcfd REST API: JSON calls with the
// bearer token the user typed, job submission, the job's Server-Sent Events
// read through fetch (EventSource cannot send an Authorization header), and
// the binary fields document (GET /v1/jobs/{id}/fields) as typed arrays.

let token = '';

export function setToken(t) {
  token = t.trim();
}

function auth(extra = {}) {
  return token ? { ...extra, Authorization: `Bearer ${token}` } : extra;
}

// A refusal of the API: the HTTP status and its problem document (RFC 9457).
export class ApiError extends Error {
  constructor(status, problem) {
    super(problem && problem.detail ? `${problem.detail} (${status} ${problem.code || ''})`
                                    : `HTTP ${status}`);
    this.status = status;
    this.problem = problem;
  }
}

async function checked(resp) {
  if (resp.ok) return resp;
  let problem = null;
  try { problem = await resp.json(); } catch (e) { /* not JSON */ }
  throw new ApiError(resp.status, problem);
}

async function call(path, init = {}) {
  return checked(await fetch(path, { ...init, headers: auth(init.headers) }));
}

export async function getJSON(path) {
  return (await call(path)).json();
}

// POST /v1/jobs: the mesh, a params object and optionally a target (a
// clean mesh of the same connectivity: the metrics then compare with it);
// fields: the daemon keeps the per-vertex fields (GET .../fields). The
// page shows the metrics' measures (mesh info, curvature): it asks for them
// (measures=true). Resolves to the Job.
export async function submit(file, params, target = null, fields = false) {
  const body = new FormData();
  body.append('params', JSON.stringify(params));
  body.append('mesh', file, file.name);
  if (target) body.append('target', target, target.name);
  return (await call(fields ? '/v1/jobs?measures=true&fields=true' : '/v1/jobs?measures=true',
                     { method: 'POST', body })).json();
}

export async function cancel(id) {
  await call(`/v1/jobs/${id}`, { method: 'DELETE' });
}

export async function result(id) {
  const resp = await call(`/v1/jobs/${id}/result`);
  const cd = resp.headers.get('Content-Disposition') || '';
  const m = /filename="([^"]+)"/.exec(cd);
  return { blob: await resp.blob(), name: m ? m[1] : 'result' };
}

// Calls onEvent(type, data) for each event of the job's stream (status,
// progress, work: the core's phases between steps, done) until the daemon
// ends it.
export async function follow(id, onEvent) {
  const resp = await call(`/v1/jobs/${id}/events`, { headers: { Accept: 'text/event-stream' } });
  const reader = resp.body.pipeThrough(new TextDecoderStream()).getReader();
  let buf = '';
  for (;;) {
    const { value, done } = await reader.read();
    if (done) return;
    buf += value.replace(/\r\n?/g, '\n');
    let end;
    while ((end = buf.indexOf('\n\n')) >= 0) {
      const block = buf.slice(0, end);
      buf = buf.slice(end + 2);
      let type = 'message';
      const data = [];
      for (const line of block.split('\n')) {
        if (line.startsWith('event:')) type = line.slice(6).trim();
        else if (line.startsWith('data:')) data.push(line.slice(5).replace(/^ /, ''));
      }
      if (data.length) onEvent(type, JSON.parse(data.join('\n')));
    }
  }
}

// The fields document: {vertices, faces, arrays: {name: TypedArray},
// stats: {name: {min, max, p02, p98}}}. The arrays view the response's
// own bytes (4-byte aligned, little-endian like every browser's host).
export async function fields(id) {
  const buf = await (await call(`/v1/jobs/${id}/fields`)).arrayBuffer();
  const dv = new DataView(buf);
  const magic = new TextDecoder().decode(new Uint8Array(buf, 0, 4));
  if (magic !== 'MCFF' || dv.getUint32(4, true) !== 1)
    throw new Error('not an mcfd fields document (version 1)');
  const hlen = dv.getUint32(8, true);
  const head = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 12, hlen)));
  const base = 12 + hlen;
  const out = { vertices: head.vertices, faces: head.faces, arrays: {}, stats: {} };
  for (const a of head.arrays) {
    const Type = a.type === 'uint32' ? Uint32Array : Float32Array;
    out.arrays[a.name] = new Type(buf, base + a.offset, a.count * a.components);
    if (a.stats) out.stats[a.name] = a.stats;
  }
  return out;
}
