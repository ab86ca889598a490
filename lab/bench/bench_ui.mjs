/* SPDX-License-Identifier: MIT */
// bench_ui.mjs - the page on a large scan in headless chromium (software
// WebGL, SwiftShader, on the CPU): load to first frame and frame time.
//
//   make bench-ui [MESHES=...] [UI_MESH=dragon_vrip.drc] [UI_REPS=3]
//
// Each repetition starts a fresh page on one mcfd (2 workers), uploads the
// mesh with the page's default parameters and measures, in the page:
//   input_ms     choosing the file to the first frame of the input view
//                (the page's preview job: the daemon reads the mesh; none
//                over the page's PREVIEW_MAX_BYTES)
//   job_s        submit to the job's `succeeded` event (the daemon's work)
//   fields_ms    GET /v1/jobs/{id}/fields and its parsing into typed arrays
//   first_ms     `succeeded` to the first frame of both views (fields,
//                geometry, normals, colours, upload to WebGL, drawing)
//   frame_ms     one frame of both views while the camera orbits, each
//                waited for by a 1-pixel readback (mean of 20)
// and prints them with the median of each.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { launch, startDaemon } from '../../tests/browser.mjs';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..'); // the top level
const BUILD = path.resolve(ROOT, process.env.MCF_BUILD || 'build');
const MESH = path.resolve(process.env.MESHES || path.join(ROOT, '..', 'shared', 'meshes'),
                          process.env.UI_MESH || 'dragon_vrip.drc');
const REPS = Number(process.env.UI_REPS || 3);
const TMP = fs.mkdtempSync(path.join(os.tmpdir(), 'mcfd-ui-bench-'));
process.on('exit', () => fs.rmSync(TMP, { recursive: true, force: true }));

if (!fs.existsSync(MESH)) {
  console.log(`bench_ui: no ${MESH} (set MESHES or UI_MESH)`);
  process.exit(2);
}
const daemon = await startDaemon(BUILD, TMP, ['--workers', '2']);
const browser = await launch(TMP);
const rows = [];
try {
  for (let rep = 0; rep < REPS; rep++) {
    const page = await browser.newPage();
    await page.setViewport({ width: 1400, height: 1300 });
    const errors = [];
    page.on('console', m => { if (m.type() === 'error') errors.push(m.text()); });
    await page.goto(daemon.url + '/');
    await page.waitForFunction(() => document.getElementById('scheme').options.length > 3);
    await (await page.$('#mesh')).uploadFile(MESH);
    await page.waitForFunction(() => window.mcfd.perf.inputShownMs > 0 ||
                               /more than the preview reads/.test(document.getElementById('status').textContent),
                               { timeout: 600000, polling: 100 });
    const inputMs = await page.evaluate(() => window.mcfd.perf.inputShownMs);
    const t0 = Date.now();
    await page.click('#run');
    await page.waitForFunction(() => window.mcfd.perf.succeededAt > 0, { timeout: 600000, polling: 100 });
    const jobS = (Date.now() - t0) / 1000;
    await page.waitForFunction(() => window.mcfd.perf.firstFrameMs > 0, { timeout: 600000, polling: 100 });
    const r = await page.evaluate(() => ({
      vertices: window.mcfd.state.fields.vertices,
      bytes: window.mcfd.state.fields.arrays.faces.buffer.byteLength,
      fields_ms: window.mcfd.perf.fieldsMs,
      first_ms: window.mcfd.perf.firstFrameMs,
      frame_ms: window.mcfd.compare.benchFrames(20),
    }));
    if (rep === 0) await page.screenshot({ path: path.join(BUILD, 'bench-ui.png') });
    if (errors.length) throw new Error(`console errors: ${errors.join('; ')}`);
    rows.push({ job_s: jobS, input_ms: inputMs, ...r });
    console.log(`rep ${rep + 1}: ${r.vertices} vertices, fields ${(r.bytes / 1e6).toFixed(1)} MB, ` +
                `input view ${inputMs.toFixed(0)} ms, job ${jobS.toFixed(1)} s, fields ${r.fields_ms.toFixed(0)} ms, ` +
                `first frame ${r.first_ms.toFixed(0)} ms, frame ${r.frame_ms.toFixed(0)} ms`);
    await page.close();
  }
} finally {
  await browser.close();
  await daemon.stop();
}
const median = k => rows.map(r => r[k]).sort((a, b) => a - b)[Math.floor(rows.length / 2)];
console.log(`bench_ui: ${path.basename(MESH)}, median of ${rows.length}: input view ${median('input_ms').toFixed(0)} ms, job ${median('job_s').toFixed(1)} s, ` +
            `fields ${median('fields_ms').toFixed(0)} ms, load to first frame ${median('first_ms').toFixed(0)} ms, ` +
            `frame ${median('frame_ms').toFixed(0)} ms (both views, SwiftShader); screenshot ${BUILD}/bench-ui.png`);
