// The console's Serial line panel in a real browser: Debian's chromium driven by playwright-core.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/#/node/5 ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node serial-trace.test.mjs
//
// The console runs on the real SLCAN path with the soft slave (MAC 5) and dnet-sim-breaker on
// ptys. Opens MAC 5's view, opens the Serial line panel and waits for the breaker's status frames
// decoded; gives Close (confirmed) and waits for the command frame, its acknowledgement and a
// status frame with the switch closed; compares the panel's rows with GET
// /api/node/5/serial-trace. A screenshot of the panel goes into ARTIFACTS_DIR. Run by
// tests/tests/serial_trace_browser.rs.
import { check, runScript } from "./lib.mjs";
import { join } from "node:path";

const rows = (page) => page.$$eval("#serial-table tbody tr", (rs) => rs.map((r) => ({
  n: Number(r.dataset.n), kind: r.dataset.kind, decoded: r.children[3].textContent, hex: r.children[4].textContent,
})));

await runScript({ viewport: { width: 1280, height: 1400 } }, async ({ page, errors, step, artifacts }) => {

  await step("the panel shows the converter's status frames decoded", async () => {
    await page.waitForFunction(() => / ok \(0\)$/.test(document.querySelector("#dev-title").textContent), null, { timeout: 15000 });
    await page.click("#btn-serial");
    await page.waitForFunction(() => [...document.querySelectorAll("#serial-table tbody tr[data-kind=rx]")]
      .filter((r) => /^status: currents \d+ \d+ \d+ \d+, switch Open$/.test(r.children[3].textContent)).length >= 2,
      null, { timeout: 10000 });
    const profile = await page.textContent("#serial-profile");
    check(profile === "breaker (framed serial)", profile);
    const status = (await rows(page)).find((r) => r.kind === "rx" && r.decoded.startsWith("status:"));
    // A status frame on the wire: start 68, length 12 (18 data bytes), end 16; 22 bytes.
    check(status.hex.startsWith("68 12 ") && status.hex.endsWith(" 16") && status.hex.split(" ").length === 22, status.hex);
  });

  await step("Close shows the command, its acknowledgement and the switch closed", async () => {
    await page.click("#btn-close");
    await page.click("#confirm-yes");
    await page.waitForFunction(() => {
      const texts = [...document.querySelectorAll("#serial-table tbody tr")].map((r) => r.dataset.kind + " " + r.children[3].textContent);
      return texts.includes("tx command Close") && texts.includes("rx ack of command 0x02: ok")
        && texts.some((t) => /^rx status: currents .*, switch Closed$/.test(t));
    }, null, { timeout: 10000 });
    // Newest first: the closed status comes after (above) the command.
    const r = await rows(page);
    const command = r.findIndex((x) => x.decoded === "command Close");
    const closed = r.findIndex((x) => / switch Closed$/.test(x.decoded));
    check(closed < command, `closed at row ${closed}, command at ${command}`);
    check(r[command].hex === "68 01 02 02 16", r[command].hex);
    await page.locator("#serial-card").screenshot({ path: join(artifacts, "console-serial-line.png") });
  });

  await step("the panel shows what GET /api/node/5/serial-trace says", async () => {
    const shown = await rows(page);
    const api = await page.evaluate(async () => (await (await fetch("/api/node/5/serial-trace")).json()));
    check(api.ok && api.converter, JSON.stringify(api).slice(0, 300));
    const byN = new Map(api.lines.map((l) => [l.n, l]));
    const compared = shown.filter((r) => byN.has(r.n));
    check(compared.length >= 5, `${compared.length} rows compared`);
    for (const r of compared) {
      const l = byN.get(r.n);
      check(l.kind === r.kind && l.decoded === r.decoded && l.hex === r.hex, `row ${r.n}: ${JSON.stringify(r)} vs ${JSON.stringify(l)}`);
    }
    // Nothing new since the newest line: an empty answer.
    const after = await page.evaluate(async (n) => (await (await fetch(`/api/node/5/serial-trace?since=${n}`)).json()), api.next);
    check(after.lines.every((l) => l.n > api.next), JSON.stringify(after.lines));
    check(errors.length === 0, `page errors: ${errors.join("; ")}`);
  });
});
