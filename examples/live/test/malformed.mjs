// The live server against malformed and hostile input: each bad command gets an error reply
// (400 for a malformed one, 409 for one the scene refuses) and changes nothing; a client that
// drops its connection mid-request and two clients at once leave the server running; static
// paths outside the page's folder are not served.
//
//   LIVE_BIN=build/examples/live/live node test/malformed.mjs
import net from 'node:net';
import { startServer, check } from './server.mjs';

const server = await startServer(['--scene', 'organ']);
const post = async (body, type = 'application/json') => {
  const r = await fetch(`${server.url}/command`, { method: 'POST', body, headers: { 'Content-Type': type } });
  let json = null;
  try { json = await r.json(); } catch { /* an error page */ }
  return { status: r.status, json };
};
const status = async () => (await fetch(`${server.url}/status`)).json();

try {
  const before = await status();
  const cases = [
    ['not JSON', 'grasp the liver', 400],
    ['JSON that is not an object', '[1, 2, 3]', 400],
    ['no cmd', '{"point": [0, 0, 0]}', 400],
    ['cmd not a string', '{"cmd": 42}', 400],
    ['unknown command', '{"cmd": "explode"}', 400],
    ['NaN (not JSON)', '{"cmd": "grasp", "point": [NaN, 0, 0]}', 400],
    ['a number beyond double', '{"cmd": "grasp", "point": [1e400, 0, 0]}', 400],
    ['a huge coordinate', '{"cmd": "move", "target": [1e300, 0, 0]}', 400],
    ['a point of 2 numbers', '{"cmd": "grasp", "point": [0, 0]}', 400],
    ['a point of strings', '{"cmd": "grasp", "point": ["a", "b", "c"]}', 400],
    ['move with nothing grasped', '{"cmd": "move", "target": [0, 0, 0.1]}', 409],
    ['grasp far from the tissue', '{"cmd": "grasp", "point": [5, 5, 5]}', 409],
    ['unknown scene', '{"cmd": "scene", "name": "../../etc/passwd"}', 400],
    ['bad mode', '{"cmd": "mode", "mode": "ludicrous"}', 400],
    ['cut without a stroke', '{"cmd": "cut", "direction": [0, 0, 1], "topology": 1}', 400],
    ['cut with an empty stroke', '{"cmd": "cut", "stroke": [], "direction": [0, 0, 1], "topology": 1}', 409],
    ['cut of zero length', '{"cmd": "cut", "stroke": [{"triangle": 5, "bary": [1, 0, 0]}, {"triangle": 5, "bary": [1, 0, 0]}], "direction": [0, 0, 1], "topology": 1}', 409],
    ['cut along a zero direction', '{"cmd": "cut", "stroke": [{"triangle": 5, "bary": [1, 0, 0]}, {"triangle": 9, "bary": [1, 0, 0]}], "direction": [0, 0, 0], "topology": 1}', 400],
    ['cut on a triangle that does not exist', '{"cmd": "cut", "stroke": [{"triangle": 99999999, "bary": [1, 0, 0]}, {"triangle": 5, "bary": [1, 0, 0]}], "direction": [0, 0, 1], "topology": 1}', 409],
    ['cut with bad barycentric coordinates', '{"cmd": "cut", "stroke": [{"triangle": 5, "bary": [7, -3, 0]}, {"triangle": 6, "bary": [1, 0, 0]}], "direction": [0, 0, 1], "topology": 1}', 400],
    ['cut drawn on old triangles', '{"cmd": "cut", "stroke": [{"triangle": 5, "bary": [1, 0, 0]}, {"triangle": 900, "bary": [1, 0, 0]}], "direction": [0, 0, 1], "topology": 77}', 409],
    ['open_start not a boolean', '{"cmd": "cut", "stroke": [], "direction": [0, 0, 1], "topology": 1, "open_start": "yes"}', 400],
    ['a stroke of 5000 points', JSON.stringify({ cmd: 'cut', direction: [0, 0, 1], topology: 1,
                                                 stroke: Array(5000).fill({ triangle: 1, bary: [1, 0, 0] }) }), 400],
    ['a 2 MB body', '{"cmd": "release", "pad": "' + 'x'.repeat(2 << 20) + '"}', 413],
  ];
  const plain = await post('{"cmd": "release"}', 'text/plain');
  check(plain.status === 415, `a command sent as text/plain is refused (415: another site's page could send it)`);
  for (const [what, body, want] of cases) {
    const r = await post(body);
    const said = r.json && r.json.error ? r.json.error : '';
    check(r.status === want && (want === 413 || (r.json && r.json.ok === false && said.length > 0)),
          `${what}: ${r.status} ${said.slice(0, 90)}`);
  }

  // A client that sends half a request and goes away, and one that drops the frame mid-read.
  await new Promise((resolve) => {
    const s = net.connect(server.port, '127.0.0.1', () => { s.write('POST /command HTTP/1.1\r\nContent-Length: 100\r\n\r\n{"cm'); s.destroy(); resolve(); });
  });
  await new Promise((resolve) => {
    const s = net.connect(server.port, '127.0.0.1', () => s.write('GET /frame HTTP/1.1\r\nHost: x\r\n\r\n'));
    s.once('data', () => { s.destroy(); resolve(); });
  });
  // Two clients at once, each pulling frames.
  const pulls = await Promise.all(Array.from({ length: 8 }, () => fetch(`${server.url}/frame`).then(r => r.arrayBuffer())));
  check(pulls.every(b => b.byteLength > 64), `8 concurrent frame requests answered (${pulls[0].byteLength} bytes each)`);

  // Paths outside the page's folders, sent as written (fetch would normalise them away).
  const rawStatus = (path, host = `127.0.0.1:${server.port}`) => new Promise((resolve, reject) => {
    let data = '';
    const s = net.connect(server.port, '127.0.0.1',
                          () => s.write(`GET ${path} HTTP/1.1\r\nHost: ${host}\r\nConnection: close\r\n\r\n`));
    s.on('data', d => { data += d; });
    s.on('end', () => resolve(Number(data.split(' ')[1])));
    s.on('error', reject);
  });
  check(await rawStatus('/live.js') === 200, 'the page itself is served (raw request)');
  check(await rawStatus('/live.js', 'evil.example:80') === 403, 'a request for another Host is refused (403: DNS rebinding)');
  for (const path of ['/../live.cpp', '/three/../../live.cpp', '/%2e%2e/live.cpp', '/three/%2e%2e/%2e%2e/live.cpp',
                      '/../../../../etc/passwd']) {
    const code = await rawStatus(path);
    check(code === 404 || code === 400 || code === 403, `${path} is not served (${code})`);
  }

  // Still running, still stepping, the scene as it was.
  await new Promise(r => setTimeout(r, 500));
  const after = await status();
  check(server.alive(), 'the server is still running');
  check(after.frame > before.frame && after.time > before.time, `it still steps (t = ${before.time.toFixed(2)} -> ${after.time.toFixed(2)} s)`);
  check(after.scene === 'organ' && after.triangles === before.triangles && after.dofs === before.dofs && !after.grasping,
        'nothing changed: same scene, surface and dofs, nothing grasped');
  const saved = await post('{"cmd": "save", "file": "/tmp/evil.vtu"}');
  check(saved.status === 200 && saved.json.file.startsWith(server.out + '/'),
        `save writes into the output folder only (${saved.json.file})`);
  const ok = await post('{"cmd": "mode", "mode": "accurate"}');
  check(ok.status === 200 && ok.json.ok && (await status()).mode === 'accurate', 'a good command after all that works');
  console.log('malformed-input test passed');
} catch (e) {
  console.error(e.message || e);
  process.exitCode = 1;
} finally {
  server.stop();
}
