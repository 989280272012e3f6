// Starts the live server for a test: LIVE_BIN (the built `live`), on a free port the server
// chooses itself (--port 0: no race with another process between choosing and binding), output
// into a temporary folder; resolves when it listens, with the port it printed.
import { spawn } from 'node:child_process';
import { mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

export async function startServer(extra = []) {
  const bin = process.env.LIVE_BIN;
  if (!bin) throw new Error('set LIVE_BIN to the built live server');
  const out = mkdtempSync(join(tmpdir(), 'plastifem-live-'));
  const child = spawn(bin, ['--port', '0', '--out', out, '--seconds', '600', ...extra],
                      { stdio: ['ignore', 'pipe', 'pipe'] });
  let log = '';
  child.stdout.on('data', d => { log += d; process.stdout.write(`  [server] ${d}`); });
  child.stderr.on('data', d => { log += d; process.stderr.write(`  [server] ${d}`); });
  const port = await new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`server did not start:\n${log}`)), 30000);
    child.stdout.on('data', () => {
      const m = log.match(/live: open http:\/\/127\.0\.0\.1:(\d+)\//);
      if (m) { clearTimeout(timer); resolve(Number(m[1])); }
    });
    child.on('exit', code => { clearTimeout(timer); reject(new Error(`server exited (${code}):\n${log}`)); });
  });
  return { url: `http://127.0.0.1:${port}`, port, out, child, alive: () => child.exitCode === null,
           stop: () => child.kill('SIGTERM') };
}

export function check(cond, what) {
  if (!cond) throw new Error(`FAILED: ${what}`);
  console.log(`  ok: ${what}`);
}
