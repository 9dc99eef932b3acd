// Several networks in one console (dnet-master ui --plant) in a real browser: Debian's chromium
// driven by playwright-core.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/ ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node plant.test.mjs
//
// The console runs a plant of two simulated networks: "a" scans MAC 5, "b" scans MAC 6. The page
// shows a tab per network; network a's grid has MAC 5 in I/O and not MAC 6; a click on b's tab
// shows MAC 6 in I/O and not MAC 5, asked through /api/net/b/; b's node opens in the device view.
// Screenshots go into ARTIFACTS_DIR. Run by tests/tests/plant_browser.rs.
import { check, runScript } from "./lib.mjs";
import { join } from "node:path";

await runScript({ viewport: { width: 1280, height: 1000 } }, async ({ page, errors, step, artifacts }) => {
  const asked = [];
  page.on("request", (r) => asked.push(new URL(r.url()).pathname));
  const inIo = (mac) => page.$eval(`#cell-${mac}`, (c) => c.classList.contains("in-list") && c.classList.contains("st-ok"));
  const listed = (mac) => page.$eval(`#cell-${mac}`, (c) => c.classList.contains("in-list"));

  await step("a tab per network, the first shown: MAC 5 in I/O, MAC 6 not in its list", async () => {
    await page.waitForSelector("#networks:not([hidden]) .net-tab.active", { timeout: 20000 });
    const tabs = await page.$$eval(".net-tab", (b) => b.map((x) => [x.textContent, x.classList.contains("active")]));
    check(JSON.stringify(tabs) === JSON.stringify([["a", true], ["b", false]]), JSON.stringify(tabs));
    await page.waitForFunction(() => document.querySelector("#cell-5").classList.contains("st-ok"), null, { timeout: 20000 });
    check(!(await listed(6)), "MAC 6 is in network a's grid");
    const line = await page.textContent("#scanner-line");
    check(line.startsWith("network a · "), line);
    await page.screenshot({ path: join(artifacts, "plant-network-a.png"), fullPage: true });
  });

  await step("network b's tab: MAC 6 in I/O, MAC 5 not in its list, asked through /api/net/b/", async () => {
    await page.click('.net-tab[data-network="b"]');
    await page.waitForFunction(() => {
      const c6 = document.querySelector("#cell-6"), c5 = document.querySelector("#cell-5");
      return c6.classList.contains("st-ok") && !c5.classList.contains("in-list");
    }, null, { timeout: 20000 });
    check(await inIo(6), "MAC 6 not in I/O");
    const active = await page.$$eval(".net-tab.active", (b) => b.map((x) => x.textContent));
    check(active.join() === "b", active.join());
    check(asked.includes("/api/net/b/state"), `no /api/net/b/state among ${[...new Set(asked)].join(" ")}`);
    const line = await page.textContent("#scanner-line");
    check(line.startsWith("network b · "), line);
    await page.screenshot({ path: join(artifacts, "plant-network-b.png"), fullPage: true });
  });

  await step("network b's node in the device view", async () => {
    await page.click("#cell-6");
    await page.waitForFunction(() => !document.querySelector("#view-device").hidden, null, { timeout: 10000 });
    await page.waitForFunction(() => /^MAC 6 · .*Serial-DeviceNet/.test(document.querySelector("#dev-title").textContent), null, { timeout: 20000 });
    check(asked.includes("/api/net/b/node/6"), `no /api/net/b/node/6 among ${[...new Set(asked)].join(" ")}`);
    check(!asked.includes("/api/node/6"), "the device view asked the first network for MAC 6");
    check(errors.length === 0, errors.join("\n"));
  });
});
