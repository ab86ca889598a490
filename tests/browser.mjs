/* SPDX-License-Identifier: MIT */
// browser.mjs - what the page's browser test (tests/test_ui.mjs) and its
// measurement on a large scan (bench/bench_ui.mjs) share: Debian's chromium
// as the team runs it here, and an mcfd on a free loopback port.
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import readline from 'node:readline';
import puppeteer from 'puppeteer-core';

export const CHROMIUM = process.env.MCF_CHROMIUM || '/usr/lib/chromium/chromium';
// The binary itself (the /usr/bin/chromium wrapper misbehaves here): no
// sandbox (root), SwiftShader's software WebGL, nothing from the network.
const ARGS = ['--no-sandbox', '--enable-unsafe-swiftshader', '--disable-gpu-sandbox',
              '--disable-background-networking', '--disable-component-update',
              '--disable-sync', '--no-first-run', '--disable-quic', '--window-size=1400,1300'];

// A headless chromium with a fresh profile under tmp; throws when it
// cannot start.
export function launch(tmp) {
  return puppeteer.launch({ executablePath: CHROMIUM, headless: true, args: ARGS,
                            timeout: 60000, userDataDir: path.join(tmp, 'profile') });
}

// mcfd (build/mcfd) on 127.0.0.1 with a free port, its spool and log under
// tmp, in a process group of its own; resolves to {url, proc, stop()}.
export function startDaemon(build, tmp, flags = []) {
  const log = path.join(tmp, 'mcfd.log');
  const proc = spawn(path.join(build, 'mcfd'),
                     ['--bind', '127.0.0.1', '--port', '0', '--grpc-port', '0',
                      '--spool', path.join(tmp, 'spool'), ...flags],
                     { stdio: ['ignore', 'pipe', fs.openSync(log, 'a')], detached: true });
  const kill = () => {
    if (proc.exitCode === null && proc.signalCode === null) {
      try { process.kill(-proc.pid, 'SIGKILL'); } catch (e) { /* gone */ }
    }
  };
  process.on('exit', kill);
  // SIGTERM drains; resolves to the exit code ('timeout' after 40 s)
  const stop = () => {
    const exited = new Promise(resolve => proc.on('exit', code => resolve(code)));
    process.kill(proc.pid, 'SIGTERM');
    return Promise.race([exited, new Promise(r => setTimeout(() => { kill(); r('timeout'); }, 40000))]);
  };
  return new Promise((resolve, reject) => {
    const t = setTimeout(() => { kill(); reject(new Error('mcfd did not start in 20 s')); }, 20000);
    proc.on('exit', code => reject(new Error(`mcfd exited (${code}): ` +
      fs.readFileSync(log, 'utf8').slice(-2000))));
    readline.createInterface({ input: proc.stdout }).on('line', line => {
      const m = /^mcfd listening on (http:\/\/127\.0\.0\.1:\d+)/.exec(line);
      if (m) { clearTimeout(t); resolve({ url: m[1], proc, stop }); }
    });
  });
}
