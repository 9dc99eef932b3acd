// The console's Project panel in a real browser: Debian's chromium driven by playwright-core.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/ ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node project_console.test.mjs
//
// Opens the page (a console over the simulated bus with MAC 5 and MAC 6, started with a project in
// which MAC 6 has another product code and stale timeout), waits until the Project panel shows its
// verdict, compares the panel with GET /api/project/compare (the counts of what was compared, a row
// per difference), clicks Compare and sees a new comparison asked; a screenshot goes into
// ARTIFACTS_DIR. Run by tests/tests/project_console_browser.rs.
import { check, runScript } from "./lib.mjs";
import { join } from "node:path";

await runScript({ viewport: { width: 1280, height: 1000 } }, async ({ page, errors, step, artifacts }) => {

  await step("the Project panel shows the differences of MAC 6", async () => {
    // The first comparison may come before the scan list (503): the button asks again.
    await page.waitForFunction(() => {
      const card = document.querySelector("#project-card");
      const rows = document.querySelectorAll("#project-differences tr[data-mac]");
      if (card && !card.hidden && rows.length === 0) document.querySelector("#btn-project").click();
      return rows.length === 2;
    }, null, { timeout: 30000, polling: 1000 });
    const verdict = await page.textContent("#project-verdict");
    check(verdict === "2 difference(s)", verdict);
    const rows = await page.$$eval("#project-differences tr[data-mac]", (rs) => rs.map((r) => [...r.children].map((c) => c.textContent)));
    check(JSON.stringify(rows) === JSON.stringify([
      ["6", "identity product_code (keying exact)", "2", "1"],
      ["6", "parameter 4 (Stale timeout)", "4000", "3000"],
    ]), JSON.stringify(rows));
    await page.screenshot({ path: join(artifacts, "console-project.png"), fullPage: true });
  });

  await step("the panel shows what GET /api/project/compare says", async () => {
    const { r, compared, rows, notCompared } = await page.evaluate(async () => {
      const r = await (await fetch("/api/project/compare")).json();
      showProject(r);
      return {
        r,
        compared: document.querySelector("#project-compared").textContent,
        rows: [...document.querySelectorAll("#project-differences tr[data-mac]")].map((t) => [...t.children].map((c) => c.textContent)),
        notCompared: document.querySelectorAll("#project-not-compared li").length,
      };
    });
    const c = r.compared;
    check(r.ok === true && r.equal === false, JSON.stringify(r));
    check(c.nodes === 2 && c.identity === 2 && c.configuration === 2 && c.parameters === 18, JSON.stringify(c));
    check(compared === "compared: 2 node(s), 2 scan-list entries, 2 identities, 2 configuration(s) by CCV, 18 parameter(s)", compared);
    check(JSON.stringify(rows) === JSON.stringify(r.differences.map((d) => [String(d.mac), d.what, d.expected, d.found])), JSON.stringify(rows));
    check(notCompared === r.not_compared.length, `${notCompared} vs ${r.not_compared.length}`);
  });

  await step("Compare asks again", async () => {
    const [response] = await Promise.all([
      page.waitForResponse((res) => res.url().endsWith("/api/project/compare"), { timeout: 10000 }),
      page.click("#btn-project"),
    ]);
    check(response.status() === 200, `status ${response.status()}`);
  });

  check(errors.length === 0, `page errors: ${errors.join("; ")}`);
});
