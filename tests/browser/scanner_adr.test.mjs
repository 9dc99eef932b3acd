// The console's events panel in a real browser: Debian's chromium driven by playwright-core.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/ ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node scanner_adr.test.mjs
//
// Opens the page (a console over the simulated bus where MAC 5 is replaced at 10 s, --sim-replace
// 5@10000, every node on ADR), waits until the events panel shows the replacement in I/O, and
// compares the panel with GET /api/events; a screenshot goes into ARTIFACTS_DIR. Run by
// tests/tests/scanner_adr_browser.rs.
import { check, launch, openPage, settings, Steps } from "./lib.mjs";
import { join } from "node:path";

const { url, artifacts, executablePath } = settings();
const steps = new Steps();
const { step } = steps;

const browser = await launch(executablePath);
try {
  const { page, errors } = await openPage(browser, url, { viewport: { width: 1280, height: 1200 } });

  await step("the events panel shows the replacement of MAC 5, step by step", async () => {
    await page.waitForSelector('#events tr[data-kind="replaced"]', { timeout: 60000 });
    const kinds = await page.$$eval("#events tr[data-kind]", (rows) => rows.map((r) => r.dataset.kind).reverse());
    for (const want of ["appeared_at_63", "node_lost", "moved", "duplicate_check", "replaced"]) {
      check(kinds.includes(want), `${want} missing: ${kinds.join(",")}`);
    }
    const replaced = await page.textContent('#events tr[data-kind="replaced"]');
    check(replaced.includes("MAC 5") && replaced.includes("is in I/O at MAC 5"), replaced);
    await page.screenshot({ path: join(artifacts, "console-events.png"), fullPage: true });
  });

  await step("the panel shows what GET /api/events says, newest first", async () => {
    const api = await page.evaluate(async () => (await (await fetch("/api/events")).json()).events.map((e) => e.kind));
    const shown = await page.$$eval("#events tr[data-kind]", (rows) => rows.map((r) => r.dataset.kind).reverse());
    check(JSON.stringify(shown) === JSON.stringify(api.slice(-shown.length)), `${shown} vs ${api}`);
    check(errors.length === 0, errors.join("; "));
  });
} finally {
  await browser.close();
}
process.exit(steps.failed ? 1 : 0);
