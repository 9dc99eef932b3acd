// The console's logins in a real browser: Debian's chromium driven by playwright-core.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/ ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node console_auth.test.mjs
//
// The console runs with `--users` holding vera (viewer, password "veravera") and otto (operator,
// "ottootto"). The page shows the login form; a wrong password is refused in the page; vera logs
// in, opens MAC 5, clicks Close, confirms, and the page shows the refusal by role; vera logs out
// and the login form is back; otto logs in, Close asks "Close the breaker at MAC 5 ...?", Cancel
// sends nothing, Confirm closes the breaker; the Audit view lists otto's close (ok) and vera's
// (refused). Screenshots go into ARTIFACTS_DIR. Run by tests/tests/console_auth_browser.rs.
import { launch, settings, Steps } from "./lib.mjs";
import { join } from "node:path";

const { url, artifacts, executablePath } = settings();
const steps = new Steps();
const { step } = steps;

const pageErrors = [];
const browser = await launch(executablePath);
try {
  const context = await browser.newContext({ viewport: { width: 1280, height: 900 } });
  const page = await context.newPage();
  page.on("pageerror", (e) => pageErrors.push(String(e)));
  const sw = () => page.locator('[data-field="switch"] .val').textContent();

  const logIn = async (user, password) => {
    await page.waitForSelector("#view-login:not([hidden])", { timeout: 10000 });
    await page.fill("#login-user", user);
    await page.fill("#login-password", password);
    await page.click("#btn-login");
  };

  await step("the login form first; a wrong password refused in the page", async () => {
    await page.goto(url);
    await logIn("otto", "wrong");
    await page.waitForFunction(() => document.querySelector("#login-error")?.textContent === "wrong user name or password");
    await page.screenshot({ path: join(artifacts, "login.png"), fullPage: true });
  });

  await step("the viewer sees MAC 5, and Close is refused by role in the page", async () => {
    await logIn("vera", "veravera");
    await page.waitForFunction(() => document.querySelector("#who-name")?.textContent === "vera (viewer)");
    await page.waitForFunction(() => document.querySelector("#cell-5")?.classList.contains("st-ok"), null, { timeout: 30000 });
    await page.click("#cell-5");
    await page.waitForSelector('[data-field="switch"] .val');
    const before = await sw();
    await page.click("#btn-close");
    const asked = await page.locator("#confirm-text").textContent();
    if (!asked.startsWith("Close the breaker at MAC 5")) throw new Error(`confirmation: ${asked}`);
    await page.click("#confirm-yes");
    await page.waitForFunction(() => /may not operate/.test(document.querySelector("#cmd-outcome")?.textContent || ""));
    console.log(`     ${await page.locator("#cmd-outcome").textContent()}`);
    await page.screenshot({ path: join(artifacts, "refused-by-role.png"), fullPage: true });
    await page.waitForTimeout(600);
    if ((await sw()) !== before) throw new Error(`the switch changed after a refusal: ${before} -> ${await sw()}`);
  });

  await step("logout: the login form is back, the API refuses", async () => {
    await page.click("#btn-logout");
    await page.waitForSelector("#view-login:not([hidden])");
    const status = await page.evaluate(async () => (await fetch("/api/state")).status);
    if (status !== 401) throw new Error(`/api/state after logout: ${status}`);
  });

  await step("the operator: Cancel sends nothing, Confirm closes the breaker", async () => {
    await logIn("otto", "ottootto");
    await page.waitForFunction(() => document.querySelector("#who-name")?.textContent === "otto (operator)");
    await page.goto(url + "#/node/5");
    await page.waitForFunction(() => document.querySelector("#who-name")?.textContent === "otto (operator)");
    await page.waitForSelector('[data-field="switch"] .val');
    if ((await sw()) === "closed") {
      await page.click("#btn-open");
      await page.click("#confirm-yes");
      await page.waitForFunction(() => document.querySelector('[data-field="switch"] .val')?.textContent === "open", null, { timeout: 10000 });
    }
    await page.click("#btn-close");
    await page.click("#confirm-no");
    await page.waitForFunction(() => document.querySelector("#cmd-outcome")?.textContent === "close: cancelled");
    await page.waitForTimeout(600);
    if ((await sw()) !== "open") throw new Error(`Cancel closed the breaker`);
    await page.click("#btn-close");
    await page.click("#confirm-yes");
    await page.waitForFunction(() => document.querySelector('[data-field="switch"] .val')?.textContent === "closed", null, { timeout: 10000 });
  });

  await step("the Audit view: otto's close ok, vera's refused", async () => {
    await page.click("#nav-audit");
    await page.waitForFunction(() => {
      const rows = [...document.querySelectorAll("#audit-table tbody tr")].map((r) => r.textContent);
      return rows.some((t) => t.includes("otto") && t.includes("breaker close") && t.endsWith("ok"))
        && rows.some((t) => t.includes("vera") && t.includes("breaker close") && t.includes("refused"));
    }, null, { timeout: 5000 });
    await page.screenshot({ path: join(artifacts, "audit.png"), fullPage: true });
  });

  await step("no script error", async () => {
    if (pageErrors.length) throw new Error(`page errors: ${pageErrors.join("; ")}`);
  });
} catch (_) {
  // The failing step said why.
} finally {
  await steps.finish(browser, artifacts);
}
