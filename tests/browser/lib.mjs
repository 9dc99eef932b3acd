// What every browser script of this folder shares: its settings from the environment, chromium
// launched headless through playwright-core, and the steps it prints.
//
//   CONSOLE_URL=http://127.0.0.1:PORT/ ARTIFACTS_DIR=DIR [CHROMIUM=/usr/bin/chromium] node SCRIPT
//
// A step prints `ok   NAME (N ms)` or `FAIL NAME: WHY` (the Rust side counts the `ok   ` lines);
// a failed step throws, so the steps after it do not run.
import { chromium } from "playwright-core";
import { mkdirSync, writeFileSync } from "node:fs";
import { join } from "node:path";

/// The console's URL (CONSOLE_URL, required: exit 2 without), the folder for screenshots and
/// downloads (ARTIFACTS_DIR, made here; default browser-artifacts), chromium's path (CHROMIUM,
/// default /usr/bin/chromium).
export function settings() {
  const url = process.env.CONSOLE_URL;
  const artifacts = process.env.ARTIFACTS_DIR || "browser-artifacts";
  const executablePath = process.env.CHROMIUM || "/usr/bin/chromium";
  if (!url) {
    console.error("CONSOLE_URL is not set");
    process.exit(2);
  }
  mkdirSync(artifacts, { recursive: true });
  return { url, artifacts, executablePath };
}

/// Chromium, headless, without the sandbox (the tests run as root in CI).
export function launch(executablePath) {
  return chromium.launch({ executablePath, headless: true, args: ["--no-sandbox"] });
}

/// The steps of one script and how many passed and failed.
export class Steps {
  passed = 0;
  failed = 0;

  /// Runs `f`; prints ok with the time it took, or FAIL with the reason and throws it again.
  step = async (name, f) => {
    const t0 = Date.now();
    try {
      await f();
      this.passed++;
      console.log(`ok   ${name} (${Date.now() - t0} ms)`);
    } catch (e) {
      this.failed++;
      console.log(`FAIL ${name}: ${e && e.message ? e.message : e}`);
      throw e;
    }
  };

  /// Closes the browser, writes `N passed, M failed` to ARTIFACTS_DIR/result.txt and to standard
  /// output, and exits (1 when a step failed).
  async finish(browser, artifacts) {
    await browser.close();
    writeFileSync(join(artifacts, "result.txt"), `${this.passed} passed, ${this.failed} failed\n`);
    console.log(`${this.passed} passed, ${this.failed} failed`);
    process.exit(this.failed ? 1 : 0);
  }
}

/// A new page in a new browser context made with `options` (viewport, downloads), at `url`; the
/// page's script errors are collected in `errors`.
export async function openPage(browser, url, options) {
  const context = await browser.newContext(options);
  const page = await context.newPage();
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(url);
  return { context, page, errors };
}

/// Throws `what` unless `cond` holds.
export const check = (cond, what) => {
  if (!cond) throw new Error(what);
};

/// One whole script: its settings, chromium, a page at the console's URL in a context made with
/// `options`, and `body({ page, errors, context, step, artifacts })` run on it; then the browser
/// closed and the exit (1 when a step failed or `body` threw: a failed step has printed why).
export async function runScript(options, body) {
  const { url, artifacts, executablePath } = settings();
  const steps = new Steps();
  const browser = await launch(executablePath);
  try {
    const { context, page, errors } = await openPage(browser, url, options);
    await body({ page, errors, context, step: steps.step, artifacts });
  } catch (e) {
    if (!steps.failed) console.log(`FAIL ${e && e.message ? e.message : e}`);
    steps.failed = steps.failed || 1;
  } finally {
    await steps.finish(browser, artifacts);
  }
}
