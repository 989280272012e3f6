// The live demo in a real browser (Debian's Chromium, headless, driven by puppeteer-core): the
// first frame arrives; a grasp and drag moves the surface and the grasper's force is non-zero;
// the release lets go; a cut stroke across the overhanging left lobe adds triangles and the
// piece cut off falls away under gravity while the supported side stays. Saves a screenshot
// (SHOT, default: the server's output folder) and prints the page's frame rate.
//
//   LIVE_BIN=build/examples/live/live node test/browser.mjs
import puppeteer from 'puppeteer-core';
import { startServer, check } from './server.mjs';

const chromium = process.env.CHROMIUM || '/usr/bin/chromium';
const server = await startServer(['--scene', 'organ']);
const shot = process.env.SHOT || `${server.out}/live_demo.png`;
let browser;
const sleep = ms => new Promise(r => setTimeout(r, ms));

try {
  browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    // Software WebGL: CI machines have no GPU.
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
           '--window-size=1280,800'],
    defaultViewport: { width: 1280, height: 800 },
  });
  const page = await browser.newPage();
  const pageErrors = [];
  page.on('pageerror', e => pageErrors.push(e.message));
  page.on('console', m => { if (m.type() === 'error') pageErrors.push(m.text()); });
  await page.goto(server.url, { waitUntil: 'load' });

  // 1. The first frames arrive and the surface is drawn.
  await page.waitForFunction(() => window.live && window.live.frames >= 5 && window.live.triangles > 0,
                             { timeout: 60000 });
  const first = await page.evaluate(() => ({ v: live.vertices, t: live.triangles }));
  check(first.v > 1000 && first.t > 1000, `first frames: ${first.v} vertices, ${first.t} triangles`);
  await sleep(1500);  // the organ settles on its table

  // 2. Grasp the top of the right lobe and drag it up and to the side.
  const grab = await page.evaluate(() => {
    const p = live.positions;
    let best = -1;
    for (let i = 0; i < live.vertices; i++) {
      if (Math.abs(p[3 * i] - 0.03) < 0.01 && Math.abs(p[3 * i + 1]) < 0.01 && (best < 0 || p[3 * i + 2] > p[3 * best + 2]))
        best = i;
    }
    return { i: best, screen: live.screenOf(p[3 * best], p[3 * best + 1], p[3 * best + 2]),
             before: Array.from(p) };
  });
  await page.mouse.move(grab.screen[0], grab.screen[1]);
  await page.mouse.down();
  for (let k = 1; k <= 20; k++) {
    await page.mouse.move(grab.screen[0] + 3 * k, grab.screen[1] - 6 * k);
    await sleep(50);
  }
  await sleep(1500);
  const held = await page.evaluate(() => ({ grasping: live.grasping, force: live.force, p: Array.from(live.positions) }));
  let moved = 0;
  for (let j = 0; j < held.p.length; j++) moved = Math.max(moved, Math.abs(held.p[j] - grab.before[j]));
  const force = Math.hypot(...held.force);
  check(held.grasping, 'the tissue is grasped');
  check(moved > 0.01, `the surface moved under the grasp (largest coordinate change ${(1e3 * moved).toFixed(1)} mm)`);
  check(force > 1e-3, `the grasper's reaction force is non-zero (${force.toFixed(3)} N)`);
  await page.screenshot({ path: shot });
  console.log(`  screenshot: ${shot}`);

  // 3. Release.
  await page.mouse.up();
  await page.waitForFunction(() => !window.live.grasping, { timeout: 10000 });
  check(true, 'released');
  await sleep(2000);  // it settles back

  // 4. Cut mode; a stroke across the overhanging left lobe (x = -0.065, the table ends at -0.04),
  //    from off the organ on one side to off it on the other.
  const plan = await page.evaluate(() => {
    const p = live.positions, left = [], right = [];
    const top = [];
    for (let s = -0.09; s <= 0.0901; s += 0.01) {
      let best = -1;
      for (let i = 0; i < live.vertices; i++)
        if (Math.abs(p[3 * i] + 0.065) < 0.004 && Math.abs(p[3 * i + 1] - s) < 0.004 &&
            (best < 0 || p[3 * i + 2] > p[3 * best + 2])) best = i;
      if (best >= 0) top.push(live.screenOf(p[3 * best], p[3 * best + 1], p[3 * best + 2]));
    }
    for (let i = 0; i < live.vertices; i++) {
      if (p[3 * i] < -0.08) left.push(i);
      else if (p[3 * i] > -0.03 && p[3 * i] < 0) right.push(i);
    }
    const meanZ = ids => ids.reduce((a, i) => a + p[3 * i + 2], 0) / ids.length;
    return { top, left, right, leftZ: meanZ(left), rightZ: meanZ(right), triangles: live.triangles };
  });
  check(plan.top.length >= 4, `the stroke crosses the lobe at ${plan.top.length} surface points`);
  await page.click('#cut');
  const a = plan.top[0], b = plan.top[plan.top.length - 1];
  const dir = [b[0] - a[0], b[1] - a[1]], len = Math.hypot(...dir);
  const start = [a[0] - 60 * dir[0] / len, a[1] - 60 * dir[1] / len], end = [b[0] + 60 * dir[0] / len, b[1] + 60 * dir[1] / len];
  await page.mouse.move(start[0], start[1]);
  await page.mouse.down();
  for (const q of [...plan.top, end]) {
    for (let k = 1; k <= 4; k++) await page.mouse.move(start[0] + (q[0] - start[0]) * k / 4, start[1] + (q[1] - start[1]) * k / 4);
    start[0] = q[0]; start[1] = q[1];
  }
  await page.mouse.up();
  await page.waitForFunction(t => window.live.lastReply && window.live.triangles > t, { timeout: 20000 }, plan.triangles);
  const cut = await page.evaluate(() => ({ reply: live.lastReply, triangles: live.triangles }));
  check(cut.reply.ok, `the cut was applied (${JSON.stringify(cut.reply)})`);
  check(cut.triangles > plan.triangles, `the triangle count grew: ${plan.triangles} -> ${cut.triangles}`);

  // 5. The piece cut off falls; the supported side stays.
  await sleep(2500);
  const after = await page.evaluate(ids => {
    const p = live.positions;
    const meanZ = s => s.reduce((a, i) => a + p[3 * i + 2], 0) / s.length;
    return { leftZ: meanZ(ids.left), rightZ: meanZ(ids.right), fps: live.fps, status: live.status };
  }, { left: plan.left, right: plan.right });
  const fell = plan.leftZ - after.leftZ, stayed = Math.abs(plan.rightZ - after.rightZ);
  check(fell > 0.02, `the piece cut off fell ${(1e3 * fell).toFixed(0)} mm under gravity`);
  check(stayed < 0.003, `the supported side moved ${(1e3 * stayed).toFixed(1)} mm`);
  // 6. A reload, then a second page beside it: each draws the same (cut) surface. (Only the
  //    page in front animates: a browser pauses the frames of one behind.)
  const drawsCut = p => p.waitForFunction(t => window.live && window.live.frames >= 3 && window.live.triangles === t,
                                          { timeout: 60000 }, cut.triangles);
  await page.reload({ waitUntil: 'load' });
  await drawsCut(page);
  check(true, `after a reload the page draws the cut surface (${cut.triangles} triangles)`);
  const second = await browser.newPage();
  second.on('pageerror', e => pageErrors.push(e.message));
  await second.goto(server.url, { waitUntil: 'load' });
  await drawsCut(second);
  check(true, 'a second page opened beside it draws it too');
  await second.close();
  check(pageErrors.length === 0, `no errors in the page (${pageErrors.join('; ')})`);
  console.log(`live demo in headless Chromium: ${after.fps.toFixed(1)} frames/s, server step median ` +
              `${after.status.median_ms.toFixed(1)} ms (${after.status.mode}, ${after.status.dofs} dofs), ` +
              `${(100 * after.status.speed).toFixed(0)}% of the wall clock`);
  console.log('browser test passed');
} catch (e) {
  console.error(e.message || e);
  process.exitCode = 1;
} finally {
  if (browser) await browser.close();
  server.stop();
}
