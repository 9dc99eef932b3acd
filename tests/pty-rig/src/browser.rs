//! The console in a real browser: a script of `tests/browser/` (Node.js, `playwright-core`)
//! driving Debian's `chromium` headless against a running console.
//!
//! A missing chromium, node or `node_modules` is a failure, never a skip: these tests are run on
//! purpose (`-- --ignored`) where the browser is installed.

use crate::{scratch, workspace_dir};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The browser scripts' folder, checked: `tests/browser/` with `playwright-core` installed,
/// chromium (`CHROMIUM`, default `/usr/bin/chromium`) and `node` present.
#[derive(Debug, Clone)]
pub struct Browser {
    scripts: PathBuf,
    chromium: PathBuf,
}

/// What a browser script printed (standard output, then standard error) and whether it
/// succeeded.
#[derive(Debug, Clone)]
pub struct ScriptRun {
    /// The script's exit status was 0.
    pub success: bool,
    /// Standard output followed by standard error.
    pub text: String,
}

impl ScriptRun {
    /// How many steps the script reported passed: lines that start with `ok   `.
    pub fn steps_passed(&self) -> usize {
        self.text.lines().filter(|l| l.starts_with("ok   ")).count()
    }
}

impl Browser {
    /// Checks that chromium, node and `playwright-core` are there; panics naming the missing one
    /// and how to install it.
    pub fn require() -> Browser {
        let scripts = workspace_dir().join("tests/browser");
        let chromium =
            std::env::var_os("CHROMIUM").map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
        assert!(chromium.exists(), "{} is missing: apt-get install chromium", chromium.display());
        assert!(
            Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success()),
            "node is missing: install Node.js"
        );
        assert!(
            scripts.join("node_modules/playwright-core").is_dir(),
            "playwright-core is missing: npm ci --prefix tests/browser"
        );
        Browser { scripts, chromium }
    }

    /// Runs `node SCRIPT` in `tests/browser/` with `CONSOLE_URL=url`, `ARTIFACTS_DIR=artifacts`
    /// and `CHROMIUM`; prints what it said (shown when the test fails) and returns it.
    pub fn run(&self, script: &str, url: &str, artifacts: &Path) -> ScriptRun {
        let result = Command::new("node")
            .arg(script)
            .current_dir(&self.scripts)
            .env("CONSOLE_URL", url)
            .env("ARTIFACTS_DIR", artifacts)
            .env("CHROMIUM", &self.chromium)
            .output()
            .unwrap_or_else(|e| panic!("node {script}: {e}"));
        let text =
            format!("{}{}", String::from_utf8_lossy(&result.stdout), String::from_utf8_lossy(&result.stderr));
        println!("{text}");
        ScriptRun { success: result.status.success(), text }
    }
}

/// An empty folder for a browser test's screenshots and downloads: `$UI_ARTIFACTS_DIR/SUB` when
/// set (emptied first, so that no earlier run's screenshot passes for this one's), else a fresh
/// scratch folder named after `test`.
pub fn artifacts(sub: &str, test: &str) -> PathBuf {
    match std::env::var_os("UI_ARTIFACTS_DIR") {
        Some(dir) => {
            let out = Path::new(&dir).join(sub);
            let _ = std::fs::remove_dir_all(&out);
            std::fs::create_dir_all(&out).unwrap_or_else(|e| panic!("{}: {e}", out.display()));
            out
        }
        None => scratch(test),
    }
}
