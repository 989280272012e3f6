// Starts the live server for a test: LIVE_BIN (the built `live`), on a free port, output into a
// temporary folder; resolves when it listens.
import { spawn } from 'node:child_process';
import { mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import net from 'node:net';

async function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.listen(0, '127.0.0.1', () => { const { port } = s.address(); s.close(() => resolve(port)); });
    s.on('error', reject);
  });
}

export async function startServer(extra = []) {
  const bin = process.env.LIVE_BIN;
  if (!bin) throw new Error('set LIVE_BIN to the built live server');
  const port = await freePort();
  const out = mkdtempSync(join(tmpdir(), 'plastifem-live-'));
  const child = spawn(bin, ['--port', String(port), '--out', out, '--seconds', '600', ...extra],
                      { stdio: ['ignore', 'pipe', 'pipe'] });
  let log = '';
  child.stdout.on('data', d => { log += d; process.stdout.write(`  [server] ${d}`); });
  child.stderr.on('data', d => { log += d; process.stderr.write(`  [server] ${d}`); });
  await new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`server did not start:\n${log}`)), 30000);
    child.stdout.on('data', () => { if (log.includes('live: open')) { clearTimeout(timer); resolve(); } });
    child.on('exit', code => { clearTimeout(timer); reject(new Error(`server exited (${code}):\n${log}`)); });
  });
  return { url: `http://127.0.0.1:${port}`, port, out, child, alive: () => child.exitCode === null,
           stop: () => child.kill('SIGTERM') };
}

export function check(cond, what) {
  if (!cond) throw new Error(`FAILED: ${what}`);
  console.log(`  ok: ${what}`);
}
