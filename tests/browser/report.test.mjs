// The hardware study's page (`lucent report --html`) in a real browser, looked at as a
// person would: it is written for the built-in demo scene, opened in Debian's Chromium
// (driven by playwright-core), and checked by what the browser lays out: the tables and
// headings are there, the three charts are drawn with no label running into another or
// out of its chart, every image loads. A full-page screenshot is kept in target/browser/.
//
// Run: node tests/browser/report.test.mjs   (needs target/release/lucent and /usr/bin/chromium)

import { launchChromium } from "./chromium.mjs";
import { spawnSync } from "node:child_process";
import { mkdirSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";

const root = join(dirname(fileURLToPath(import.meta.url)), "..", "..");
const lucent = process.env.LUCENT_BIN || join(root, "target", "release", "lucent");
const artifacts = join(root, "target", "browser");
const dir = join(artifacts, "report");
mkdirSync(dir, { recursive: true });

let failures = 0;
function check(cond, what) {
  if (cond) console.log(`ok   ${what}`);
  else { console.log(`FAIL ${what}`); failures += 1; }
}

const html = join(dir, "report.html");
const run = spawnSync(lucent, ["report", "--size", "256x192", "--precision-size", "96x72", "--html", html], { encoding: "utf8" });
check(run.status === 0, `lucent report --html ran (${run.status}) ${run.status === 0 ? "" : run.stderr}`);

const browser = await launchChromium();
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 900 } });
  await page.goto(pathToFileURL(html).href);
  await page.waitForLoadState("load");

  const heads = await page.evaluate(() => Array.from(document.querySelectorAll("h2, h3")).map(h => h.textContent));
  for (const want of ["SaarCOR DynRTP model", "Table 3", "Table 4", "Threads per pipeline", "Table 1", "Table 2",
    "The paper's scenes", "Hit rate against cache size", "Unit usage", "Frame rate against threads"]) {
    check(heads.some(h => h.includes(want)), `heading "${want}"`);
  }
  const cells = await page.evaluate(() => Array.from(document.querySelectorAll("td")).map(td => td.textContent));
  check(cells.includes("kd") && cells.includes("bvh"), "Table 3/4 rows of both indices");
  check(cells.includes("RTDyn1 / RTstatic") && cells.includes("66"), "Table 1 with the paper's 66%");

  // The charts: three SVGs of real size; in each, no two labels overlap and none leaves
  // the chart (boxes as Chromium laid them out, 0.5 px of slack).
  const charts = await page.evaluate(() => Array.from(document.querySelectorAll("svg")).map(svg => {
    const r = svg.getBoundingClientRect();
    const texts = Array.from(svg.querySelectorAll("text")).filter(t => t.textContent.trim().length > 0)
      .map(t => { const b = t.getBoundingClientRect(); return { s: t.textContent.trim(), x0: b.left, y0: b.top, x1: b.right, y1: b.bottom }; });
    const overlaps = [];
    for (let i = 0; i < texts.length; i++) {
      for (let j = i + 1; j < texts.length; j++) {
        const a = texts[i], b = texts[j];
        if (a.x0 < b.x1 - 0.5 && b.x0 < a.x1 - 0.5 && a.y0 < b.y1 - 0.5 && b.y0 < a.y1 - 0.5) overlaps.push(`"${a.s}" over "${b.s}"`);
      }
    }
    const outside = texts.filter(t => t.x0 < r.left - 0.5 || t.x1 > r.right + 0.5 || t.y0 < r.top - 0.5 || t.y1 > r.bottom + 0.5).map(t => t.s);
    // Labels over data: a data point (circle) or a bar (a rect smaller than the chart).
    const data = Array.from(svg.querySelectorAll("circle, rect")).map(e => e.getBoundingClientRect())
      .filter(b => b.width > 0 && b.height > 0 && b.width * b.height < 0.5 * r.width * r.height);
    const covered = [];
    for (const t of texts) {
      for (const b of data) {
        if (t.x0 < b.right - 0.5 && b.left < t.x1 - 0.5 && t.y0 < b.bottom - 0.5 && b.top < t.y1 - 0.5) { covered.push(`"${t.s}"`); break; }
      }
    }
    const marks = svg.querySelectorAll("rect, polyline, circle, path, line").length;
    return { w: r.width, h: r.height, labels: texts.length, overlaps, outside, covered, marks, words: texts.map(t => t.s) };
  }));
  check(charts.length === 3, `three charts (${charts.length})`);
  charts.forEach((c, i) => {
    check(c.w > 300 && c.h > 200 && c.marks > 10 && c.labels > 5, `chart ${i}: ${c.w}x${c.h} px, ${c.marks} marks, ${c.labels} labels`);
    check(c.overlaps.length === 0, `chart ${i}: no label runs into another ${c.overlaps.slice(0, 3).join("; ")}`);
    check(c.outside.length === 0, `chart ${i}: every label inside the chart ${c.outside.slice(0, 3).join("; ")}`);
    check(c.covered.length === 0, `chart ${i}: no label over a data point or bar ${c.covered.slice(0, 3).join("; ")}`);
  });
  if (charts.length === 3) {
    check(charts[0].words.includes("traversal") && charts[0].words.includes("cache size, KB"), "hit-rate chart: legend and axis named");
    check(charts[1].words.some(w => w.startsWith("kd ")) && charts[1].words.includes("intersection"), "usage chart: groups and units named");
    check(charts[2].words.includes("linear in threads") && charts[2].words.includes("64"), "threads chart: up to 64 threads, the linear line named");
  }

  const images = await page.evaluate(() => Array.from(document.images).map(im => ({ src: im.getAttribute("src"), ok: im.complete && im.naturalWidth > 0 })));
  check(images.length >= 8 && images.every(im => im.ok), `${images.length} images load: ${images.filter(im => !im.ok).map(im => im.src).join(", ") || "all"}`);
  await page.screenshot({ path: join(artifacts, "report-page.png"), fullPage: true });
} finally {
  await browser.close();
}
if (failures > 0) { console.log(`${failures} report page check(s) failed`); process.exit(1); }
console.log("report page test passed");
