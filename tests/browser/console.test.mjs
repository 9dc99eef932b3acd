// The dnet-master console in a real browser: Debian's chromium driven by playwright-core.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/ ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node console.test.mjs
//
// Opens the page, sees MAC 5 and MAC 6 with their product names (MAC 5 with its scan-list name
// "feeder 1"), opens MAC 5's device view, finds the plot's y-axis labels all different,
// clicks Close and sees the switch state turn to closed and the phase currents rise within two
// seconds, exports the CSV and finds the samples in it, records a trace; a screenshot of each
// view goes into ARTIFACTS_DIR. Any request to another host fails the test (the page must work
// offline). Run by master-harness/tests/ui_browser.rs.
import { launch, settings, Steps } from "./lib.mjs";
import { readFileSync } from "node:fs";
import { join } from "node:path";

const { url, artifacts, executablePath } = settings();
const steps = new Steps();
const { step } = steps;

const origin = new URL(url).origin;
const outside = [];
const pageErrors = [];
const browser = await launch(executablePath);
try {
  const context = await browser.newContext({ viewport: { width: 1280, height: 900 }, acceptDownloads: true });
  await context.route("**/*", (route) => {
    const u = route.request().url();
    if (u.startsWith(origin)) return route.continue();
    outside.push(u);
    return route.abort();
  });
  const page = await context.newPage();
  page.on("pageerror", (e) => pageErrors.push(String(e)));

  await step("network view: MAC 5 and MAC 6 with their product names", async () => {
    await page.goto(url);
    for (const mac of [5, 6]) {
      await page.waitForFunction(
        (m) => /Serial-DeviceNet Bridge|Modbus-DeviceNet Gateway/.test(document.querySelector(`#cell-${m} .name`)?.textContent || ""),
        mac, { timeout: 15000 });
    }
    await page.waitForFunction(() => document.querySelector("#cell-5")?.classList.contains("st-ok"), null, { timeout: 15000 });
    // The scan list's name beside the product name (MAC 5 is named, MAC 6 is not).
    const name5 = await page.locator("#cell-5 .name").textContent();
    if (!name5.startsWith("feeder 1 · ")) throw new Error(`MAC 5 without its scan-list name: ${name5}`);
    const name6 = await page.locator("#cell-6 .name").textContent();
    if (name6.includes("·")) throw new Error(`MAC 6 has no scan-list name, yet shows: ${name6}`);
    await page.screenshot({ path: join(artifacts, "console-network.png"), fullPage: true });
  });

  const sw = () => page.locator('[data-field="switch"] .val').textContent();
  const phaseA = async () => parseInt(await page.locator('[data-field="phase_a"] .val').textContent(), 10);

  await step("device view of MAC 5: the breaker decoded", async () => {
    await page.click("#cell-5");
    await page.waitForFunction(() => /^MAC 5 · feeder 1 · /.test(document.querySelector("#dev-title")?.textContent || ""));
    await page.waitForSelector('[data-field="switch"] .val');
    await page.waitForSelector('[data-field="phase_a"] .val');
    if ((await sw()) === "closed") {
      await page.click("#btn-open");
      await page.click("#confirm-yes");
      await page.waitForFunction(() => document.querySelector('[data-field="switch"] .val')?.textContent === "open",
        null, { timeout: 5000 });
    }
  });

  // Every y-axis label of the plot different (whole-number rounding once gave "2, 2, 1, 1, 0"),
  // with the breaker open (currents 0 or small) and, below, closed.
  const yLabels = async (when) => {
    await page.waitForFunction(() => (document.querySelector("#plot")?.dataset.yLabels || "").length > 0, null, { timeout: 5000 });
    const labels = (await page.locator("#plot").getAttribute("data-y-labels")).split(",");
    if (labels.length < 3 || new Set(labels).size !== labels.length) throw new Error(`y-axis labels ${when}: ${labels}`);
    return labels;
  };
  await step("plot: the y-axis labels are all different", async () => {
    console.log(`     y axis with the breaker open: ${await yLabels("with the breaker open")}`);
  });

  let before = 0;
  await step("Close: switch closed and phase currents rising within 2 s", async () => {
    before = await phaseA();
    const t0 = Date.now();
    await page.click("#btn-close");
    // Open and Close ask first, naming the node and the action.
    const asked = await page.locator("#confirm-text").textContent();
    if (!/^Close the breaker at MAC 5 \(feeder 1\)\?$|^Close the breaker at MAC 5/.test(asked)) throw new Error(`confirmation: ${asked}`);
    await page.click("#confirm-yes");
    await page.waitForFunction((b) => {
      const s = document.querySelector('[data-field="switch"] .val')?.textContent;
      const a = parseInt(document.querySelector('[data-field="phase_a"] .val')?.textContent || "0", 10);
      return s === "closed" && a > b;
    }, before, { timeout: 2000, polling: 50 });
    console.log(`     switch closed, phase A ${before} A -> ${await phaseA()} A after ${Date.now() - t0} ms; ` +
      `outcome: ${await page.locator("#cmd-outcome").textContent()}`);
  });

  await step("explicit Get and the parameter table", async () => {
    await page.click("#btn-get");
    await page.waitForFunction(() => /Serial-DeviceNet Bridge|Modbus-DeviceNet Gateway/.test(
      document.querySelector("#explicit-result")?.textContent || ""), null, { timeout: 10000 });
    await page.click("#btn-params");
    await page.waitForFunction(() => {
      const t = document.querySelector("#params")?.textContent || "";
      return document.querySelectorAll("#params table tbody tr").length > 0 || /^none/.test(t);
    }, null, { timeout: 20000 });
    console.log(`     get: ${await page.locator("#explicit-result").textContent()}; ` +
      `${await page.locator("#params tbody tr").count()} parameter(s)`);
  });

  await step("device view screenshot with the plot", async () => {
    // Let the plot show the currents rising.
    await page.waitForTimeout(2500);
    await page.waitForFunction(() => document.querySelectorAll("#plot-legend span").length > 0, null, { timeout: 5000 });
    console.log(`     y axis with the breaker closed: ${await yLabels("with the breaker closed")}`);
    await page.screenshot({ path: join(artifacts, "console-device.png"), fullPage: true });
  });

  await step("Export CSV: the samples of MAC 5, with the currents after Close", async () => {
    const [download] = await Promise.all([page.waitForEvent("download", { timeout: 10000 }), page.click("#export-csv")]);
    const file = join(artifacts, "export.csv");
    await download.saveAs(file);
    const lines = readFileSync(file, "utf8").trim().split("\n");
    const header = lines[0].split(",");
    const mac = header.indexOf("mac"), a = header.indexOf("phase_a");
    if (mac < 0 || a < 0) throw new Error(`CSV header without mac and phase_a: ${lines[0]}`);
    const rows = lines.slice(1).map((l) => l.split(","));
    if (!rows.length) throw new Error("no samples in the CSV");
    if (!rows.every((r) => r[mac] === "5")) throw new Error("rows of another MAC in MAC 5's export");
    // The switch as the page shows it (open / closed), not its byte.
    const swCol = header.indexOf("switch");
    const states = new Set(rows.map((r) => r[swCol]));
    if (swCol < 0 || ![...states].every((v) => v === "open" || v === "closed") || !states.has("closed")) {
      throw new Error(`the CSV's switch column is not the page's state: ${[...states]}`);
    }
    const high = rows.filter((r) => Number(r[a]) > before);
    if (!high.length) throw new Error(`no sample with phase A above ${before} A among ${rows.length}`);
    console.log(`     ${rows.length} samples, ${high.length} after Close`);
  });

  await step("trace view: live frames, recording to candump and pcap", async () => {
    await page.click("#nav-trace");
    await page.waitForFunction(() => document.querySelectorAll("#trace-table tbody tr").length > 10, null, { timeout: 5000 });
    await page.click("#rec-start");
    await page.waitForFunction(() => /\.log and .*\.pcap/.test(document.querySelector("#rec-files")?.textContent || ""));
    await page.waitForTimeout(1200);
    await page.screenshot({ path: join(artifacts, "console-trace.png"), fullPage: false });
    // The recording status the page polls answers late (1.5 s): one asked before Stop must not
    // overwrite Stop's outcome when its answer comes after it (a race the check run once showed).
    const slowStatus = async (route) => { await new Promise((r) => setTimeout(r, 1500)); await route.continue(); };
    await page.route("**/api/record", slowStatus);
    await page.waitForTimeout(1100);
    await page.click("#rec-stop");
    await page.waitForFunction(() => /^recorded: .* [1-9]\d* frames/.test(document.querySelector("#rec-files")?.textContent || ""));
    await page.waitForTimeout(2500);
    const after = await page.locator("#rec-files").textContent();
    if (!/^recorded: /.test(after)) throw new Error(`a late status overwrote Stop's outcome: ${after}`);
    await page.unroute("**/api/record", slowStatus);
    console.log(`     ${after}`);
    await page.fill("#tr-mac", "6");
    await page.waitForTimeout(800);
    const macs = await page.$$eval("#trace-table tbody tr td:nth-child(5)", (tds) => [...new Set(tds.map((t) => t.textContent))]);
    if (macs.length !== 1 || macs[0] !== "6") throw new Error(`filter MAC 6 shows ${macs}`);
  });

  await step("nothing from another host, no script error", async () => {
    if (outside.length) throw new Error(`requests to other hosts: ${outside.join(", ")}`);
    if (pageErrors.length) throw new Error(`page errors: ${pageErrors.join("; ")}`);
  });
} catch (_) {
  // The failing step said why.
} finally {
  await steps.finish(browser, artifacts);
}
