// The live page in a real browser: starts `lucent serve` on free loopback ports, opens
// its page in Debian's Chromium (driven by playwright-core; nothing is downloaded), runs
// example programs from the text box and checks the canvas with pixel probes. A
// screenshot is kept in target/browser/ as a test artifact.
//
// Run: node tests/browser/page.test.mjs   (needs target/release/lucent and /usr/bin/chromium)

import { launchChromium } from "./chromium.mjs";
import { spawn } from "node:child_process";
import { mkdirSync, existsSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const root = join(dirname(fileURLToPath(import.meta.url)), "..", "..");
const lucent = process.env.LUCENT_BIN || join(root, "target", "release", "lucent");
const artifacts = join(root, "target", "browser");
mkdirSync(artifacts, { recursive: true });

let failures = 0;
function check(cond, what) {
  if (cond) console.log(`ok   ${what}`);
  else { console.log(`FAIL ${what}`); failures += 1; }
}

function startServer() {
  return new Promise((resolve, reject) => {
    const examples = join(root, "..", "shared", "rend3r", "programs");
    const args = ["serve", "--listen", "127.0.0.1:0", "--no-udp", "--http", "127.0.0.1:0"];
    if (existsSync(examples)) args.push("--examples", examples);
    const p = spawn(lucent, args, { stdio: ["ignore", "pipe", "inherit"] });
    let out = "";
    const timer = setTimeout(() => reject(new Error("lucent serve did not start: " + out)), 15000);
    p.stdout.on("data", d => {
      out += d.toString();
      const m = out.match(/live page on (http:\/\/[0-9.:]+)\//);
      if (m) { clearTimeout(timer); resolve({ proc: p, url: m[1] }); }
    });
    p.on("exit", code => reject(new Error(`lucent serve exited (${code}): ${out}`)));
  });
}

async function runProgram(page, name) {
  await page.selectOption("#examples", name);
  await page.waitForFunction(n => document.getElementById("program").value.includes("nf"), name);
  const before = Number(await page.evaluate(() => document.getElementById("frame").dataset.frames || "0"));
  await page.click("#run");
  await page.waitForFunction(b => Number(document.getElementById("frame").dataset.frames || "0") > b, before, { timeout: 20000 });
}

async function probe(page, x, y) {
  return page.evaluate(([x, y]) => Array.from(document.getElementById("frame").getContext("2d").getImageData(x, y, 1, 1).data.slice(0, 3)), [x, y]);
}

const server = await startServer();
const browser = await launchChromium();
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
  const external = [];
  page.on("request", r => { if (!r.url().startsWith(server.url)) external.push(r.url()); });
  await page.goto(server.url + "/");
  await page.waitForFunction(() => document.getElementById("examples").options.length > 0);
  const names = await page.evaluate(() => Array.from(document.getElementById("examples").options).map(o => o.value));
  check(names[0] === "lucent/three-spheres.rdr", `examples listed (${names.length}): ${names.slice(0, 4).join(", ")} ...`);
  await page.waitForFunction(() => document.getElementById("status").textContent.startsWith("connected"));

  // lucent's own example: red sphere left, mirror middle, yellow right, green ground.
  await runProgram(page, "lucent/three-spheres.rdr");
  const red = await probe(page, 160, 235), yellow = await probe(page, 350, 235), ground = await probe(page, 256, 360), sky = await probe(page, 256, 40);
  check(red[0] > 150 && red[1] < 60 && red[2] < 60, `three-spheres: red sphere at (160,235) ${red}`);
  check(yellow[0] > 150 && yellow[1] > 150 && yellow[2] < 60, `three-spheres: yellow sphere at (350,235) ${yellow}`);
  check(ground[1] > ground[0] + 20 && ground[1] > ground[2] + 20, `three-spheres: green ground at (256,360) ${ground}`);
  check(sky[0] + sky[1] + sky[2] < 30, `three-spheres: black background at (256,40) ${sky}`);
  await page.screenshot({ path: join(artifacts, "page-three-spheres.png") });

  // One of REND3R's own programs, when the shared folder is there: rt_spheres.rdr shows a
  // blue sphere in the centre and a wider yellow one to the right.
  const rt = names.find(n => n.endsWith("raytracing/sw/rt_spheres.rdr"));
  if (rt) {
    await runProgram(page, rt);
    const blue = await probe(page, 256, 192);
    check(blue[2] > 100 && blue[0] < 40 && blue[1] < 40, `rt_spheres: blue sphere in the centre ${blue}`);
    const yellow = await page.evaluate(() => {
      const c = document.getElementById("frame");
      const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
      let n = 0, x0 = c.width, x1 = -1;
      for (let i = 0; i < d.length; i += 4) {
        if (d[i] > 60 && d[i + 1] > 60 && d[i] > 3 * d[i + 2] && d[i + 1] > 3 * d[i + 2]) {
          const x = (i / 4) % c.width;
          n += 1; x0 = Math.min(x0, x); x1 = Math.max(x1, x);
        }
      }
      return { n, x0, x1 };
    });
    check(yellow.n > 200 && yellow.x0 > 270, `rt_spheres: yellow sphere to the right of the centre (${yellow.n} px, x ${yellow.x0}..${yellow.x1})`);
    await page.screenshot({ path: join(artifacts, "page-rt_spheres.png") });
  } else {
    check(false, "rt_spheres.rdr is listed (needs ../shared/rend3r/programs)");
  }

  // Typed assembly with a mistake: the page shows the server's error with its line:column.
  await page.fill("#program", "nr\ncam xloc, 0\nsp 0, bogus, type, 1, 1\nnf\ner\ner\n");
  await page.click("#run");
  await page.waitForFunction(() => document.getElementById("error").textContent.length > 0, null, { timeout: 10000 });
  const err = await page.textContent("#error");
  check(/^3:\d+: /.test(err), `assembly error shown with line:column: "${err}"`);

  const status = await page.textContent("#status");
  check(/\d+ fps/.test(status), `status line shows fps: "${status}"`);
  check(external.length === 0, `no request leaves the server (${external.join(", ") || "none"})`);
} finally {
  await browser.close();
  server.proc.kill();
}
if (failures > 0) { console.log(`${failures} browser check(s) failed`); process.exit(1); }
console.log("browser test passed");
