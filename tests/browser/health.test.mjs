// The console's health panel in a real browser: Debian's chromium driven by playwright-core.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/ ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node health.test.mjs
//
// Opens the page (a console over the simulated bus with MAC 5 and MAC 6), waits until the health
// panel shows the controller's state and a row per node with response times, compares the panel
// with GET /api/health, downloads the CSV, clicks Clear and sees the frame count start again; a
// screenshot goes into ARTIFACTS_DIR. Run by tests/tests/health_browser.rs.
import { check, launch, openPage, settings, Steps } from "./lib.mjs";
import { readFileSync } from "node:fs";
import { join } from "node:path";

const { url, artifacts, executablePath } = settings();
const steps = new Steps();
const { step } = steps;

const browser = await launch(executablePath);
try {
  const { page, errors } = await openPage(browser, url, {
    viewport: { width: 1280, height: 1000 },
    acceptDownloads: true,
  });

  await step("the panel shows the controller and both nodes with response times", async () => {
    await page.waitForFunction(() => {
      const rows = document.querySelectorAll("#health-nodes tr[data-mac]");
      return rows.length === 2 && [...rows].every((r) => r.children[1].textContent.endsWith(" ms"));
    }, null, { timeout: 20000 });
    const bus = await page.textContent("#health-bus");
    check(bus.startsWith("controller active · TEC 0 · REC 0 · 0 error frames · 0 bus-offs · load "), bus);
    const macs = await page.$$eval("#health-nodes tr[data-mac]", (rows) => rows.map((r) => r.dataset.mac));
    check(macs.join(",") === "5,6", macs.join(","));
    await page.screenshot({ path: join(artifacts, "console-health.png"), fullPage: true });
  });

  await step("the panel shows what GET /api/health says", async () => {
    // One report, drawn and read back at once (the periodic refresh draws a newer one).
    const { h, score, findings, rows } = await page.evaluate(async () => {
      const h = await (await fetch("/api/health")).json();
      showHealth(h);
      return {
        h,
        score: document.querySelector("#health-score").textContent,
        findings: [...document.querySelectorAll("#health-findings li")].map((l) => l.textContent),
        rows: [...document.querySelectorAll("#health-nodes tr[data-mac]")].map((r) => [...r.children].map((c) => c.textContent)),
      };
    });
    check(score === `score ${h.score}`, `${score} vs ${h.score}`);
    const want = h.findings.length ? h.findings : ["no findings"];
    check(JSON.stringify(findings) === JSON.stringify(want), `${JSON.stringify(findings)} vs ${JSON.stringify(want)}`);
    h.nodes.forEach((n, i) => {
      const r = n.response_ms;
      check(rows[i][0] === String(n.mac), `row ${i}: ${rows[i]}`);
      check(rows[i][1] === `${r.min.toFixed(2)} / ${r.avg.toFixed(2)} / ${r.max.toFixed(2)} ms`, `row ${i}: ${rows[i]}`);
      check(rows[i][2] === `${n.traffic_pct.toFixed(1)} %` && rows[i][3] === String(n.dropouts), `row ${i}: ${rows[i]}`);
    });
  });

  await step("Export CSV downloads a row per node", async () => {
    const [download] = await Promise.all([page.waitForEvent("download"), page.click("#health-csv")]);
    const path = join(artifacts, "health.csv");
    await download.saveAs(path);
    const rows = readFileSync(path, "utf8").trim().split("\n");
    check(rows[0].startsWith("mac,frames,traffic_pct,response_min_ms"), rows[0]);
    check(rows.length === 3 && rows[1].startsWith("5,") && rows[2].startsWith("6,"), rows.join(" | "));
  });

  await step("Clear starts the statistics again", async () => {
    const frames = async () => Number((await page.textContent("#health-bus")).match(/ (\d+) frames in/)[1]);
    await page.waitForFunction(() => / (\d{3,}) frames in/.test(document.querySelector("#health-bus").textContent), null, { timeout: 20000 });
    const before = await frames();
    await page.click("#btn-health-clear");
    await page.waitForFunction((b) => {
      const m = document.querySelector("#health-bus").textContent.match(/ (\d+) frames in/);
      return m && Number(m[1]) < b / 2;
    }, before, { timeout: 5000 });
    const after = await frames();
    check(after < before, `${after} after ${before}`);
  });

  check(errors.length === 0, `page errors: ${errors.join("; ")}`);
} catch (_) {
  steps.failed = steps.failed || 1;
} finally {
  await browser.close();
  process.exit(steps.failed ? 1 : 0);
}
