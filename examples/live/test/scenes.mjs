// Every scene of the live demo through the server's commands, in both modes: the fat layer keeps
// a bump after a pull past yield and can be cut, the sheet tears from its nick when pulled, the organ is
// grasped with a non-zero force in accurate mode too; a reset brings a scene back to its start;
// after a stall real time keeps its pace.
//
//   LIVE_BIN=build/examples/live/live node test/scenes.mjs
import { startServer, check } from './server.mjs';

const server = await startServer(['--scene', 'organ']);
const sleep = ms => new Promise(r => setTimeout(r, ms));
const command = async (c) => {
  const r = await fetch(`${server.url}/command`, { method: 'POST', body: JSON.stringify(c),
                                                   headers: { 'Content-Type': 'application/json' } });
  return r.json();
};
const status = async () => (await fetch(`${server.url}/status`)).json();
const positions = async () => {
  const buf = await (await fetch(`${server.url}/frame`)).arrayBuffer();
  const nv = new Uint32Array(buf, 0, 4)[2];
  return new Float32Array(buf, 64, 3 * nv).slice();
};
const largestChange = (a, b) => a.reduce((m, x, i) => Math.max(m, Math.abs(x - b[i])), 0);

try {
  // The fat layer: grasp the middle of its top, lift 15 mm, let go: a permanent bump.
  check((await command({ cmd: 'scene', name: 'fat' })).ok, 'scene fat');
  await sleep(500);
  const rest = await positions();
  const reset0Dofs = (await status()).dofs;
  check((await command({ cmd: 'grasp', point: [0.04, 0.03, 0.018] })).ok, 'fat: grasped its top');
  check((await command({ cmd: 'move', target: [0.04, 0.03, 0.033] })).ok, 'fat: the grasper moves up 15 mm');
  await sleep(2000);
  const lifted = await status();
  check(lifted.grasping && Math.hypot(...lifted.force) > 1e-3, `fat: lifted, force ${Math.hypot(...lifted.force).toFixed(3)} N`);
  check((await command({ cmd: 'release' })).ok, 'fat: released');
  await sleep(3000);
  const bump = largestChange(await positions(), rest);
  check(bump > 1e-3, `fat: a permanent bump of ${(1e3 * bump).toFixed(1)} mm after the release (plastic flow)`);

  // ... and cut across its top, seen from above: the plastic layer opens (plasticity and X-FEM
  // in one Solver) and steps on.
  const topo = new Uint32Array(await (await fetch(`${server.url}/topology`)).arrayBuffer());
  const [version, ntri] = [topo[0], topo[1]];
  const x = await positions();
  const top = (px, py) => {  // the highest triangle whose centre lies within 3 mm of (px, py)
    let best = -1, bestZ = -Infinity;
    for (let t = 0; t < ntri; ++t) {
      const c = [0, 1, 2].map(d => (x[3 * topo[2 + 3 * t] + d] + x[3 * topo[3 + 3 * t] + d] + x[3 * topo[4 + 3 * t] + d]) / 3);
      if (Math.hypot(c[0] - px, c[1] - py) < 0.003 && c[2] > bestZ) [best, bestZ] = [t, c[2]];
    }
    return best;
  };
  const stroke = [top(0.02, 0.03), top(0.04, 0.03), top(0.06, 0.03)].map(t => ({ triangle: t, bary: [1 / 3, 1 / 3, 1 / 3] }));
  check(stroke.every(p => p.triangle >= 0), 'fat: a stroke across its top');
  const cut = await command({ cmd: 'cut', stroke, direction: [0, 0, -1], topology: version });
  check(cut.ok, `fat: cut (${cut.error || 'ok'})`);
  await sleep(1500);
  const afterCut = await status();
  check(afterCut.triangles > ntri && afterCut.dofs > reset0Dofs && !afterCut.error && afterCut.time > lifted.time,
        `fat: the cut opened the surface (${ntri} -> ${afterCut.triangles} triangles, ${afterCut.dofs} dofs) and it steps on`);

  // The sheet: pull the middle of its upper edge away from the fixed lower edge: it tears.
  check((await command({ cmd: 'scene', name: 'sheet' })).ok, 'scene sheet');
  await sleep(300);  // the first steps split the surface along the nick
  const sheet0 = await status();
  check((await command({ cmd: 'grasp', point: [0.05, 0.079, 0.001] })).ok, 'sheet: grasped its upper edge');
  check((await command({ cmd: 'move', target: [0.05, 0.12, 0.001] })).ok, 'sheet: pulled 4 cm');
  await sleep(3000);
  const torn = await status();
  check(torn.topology > sheet0.topology && torn.triangles > sheet0.triangles,
        `sheet: it tore (topology ${sheet0.topology} -> ${torn.topology}, ${sheet0.triangles} -> ${torn.triangles} triangles)`);
  check((await command({ cmd: 'reset' })).ok, 'sheet: reset');
  await sleep(300);
  const reset = await status();
  check(reset.triangles === sheet0.triangles && reset.time < 1 && !reset.grasping,
        `sheet: the reset brought it back (t = ${reset.time.toFixed(2)} s, ${reset.triangles} triangles)`);

  // The organ in accurate mode: grasp and pull; the step converges and the force is non-zero.
  check((await command({ cmd: 'scene', name: 'organ' })).ok, 'scene organ');
  check((await command({ cmd: 'mode', mode: 'accurate' })).ok && (await status()).mode === 'accurate', 'organ: accurate mode');
  await sleep(500);
  const organ0 = await positions();
  check((await command({ cmd: 'grasp', point: [0.03, 0.0, 0.045] })).ok || (await command({ cmd: 'grasp', point: [0.03, 0.0, 0.04] })).ok,
        'organ: grasped the top of its right lobe');
  check((await command({ cmd: 'move', target: [0.03, 0.0, 0.065] })).ok, 'organ: pulled up 2 cm');
  await sleep(3000);
  const pulled = await status();
  const moved = largestChange(await positions(), organ0);
  check(pulled.grasping && Math.hypot(...pulled.force) > 1e-3 && moved > 0.01 && !pulled.error,
        `organ, accurate: moved ${(1e3 * moved).toFixed(0)} mm, force ${Math.hypot(...pulled.force).toFixed(3)} N, ` +
        `step median ${pulled.median_ms.toFixed(1)} ms`);
  check((await command({ cmd: 'mode', mode: 'realtime' })).ok, 'organ: back to real time while grasped');
  await sleep(1000);
  const rt = await status();
  check(rt.mode === 'realtime' && rt.grasping && !rt.error, 'organ: real time steps on with the grasp');

  // After a stall (here the server stopped for 2 s; in use: slow accurate steps, a busy machine)
  // real time keeps its pace instead of running flat out to make the lost time up. The pace
  // allows a lag of 0.25 s and a lead of one step: at most (2 + 0.25 + 0.02) / 2 = 1.14 over 2 s.
  check((await command({ cmd: 'release' })).ok, 'organ: released');
  server.child.kill('SIGSTOP');
  await sleep(2000);
  server.child.kill('SIGCONT');
  const t0 = (await status()).time, w0 = performance.now();
  await sleep(2000);
  const ratio = ((await status()).time - t0) / ((performance.now() - w0) / 1000);
  check(ratio < 1.3, `organ: after a 2 s stall the simulation keeps real time (${ratio.toFixed(2)} of the wall clock)`);
  console.log('scenes test passed');
} catch (e) {
  console.error(e.message || e);
  process.exitCode = 1;
} finally {
  server.stop();
}
