//! The console's logins in a real browser: `dnet-master --bus sim ui --users FILE` with a viewer
//! and an operator (made by `dnet-master user add`), driven by Debian's `chromium` through
//! `playwright-core` (`tests/browser/console_auth.test.mjs`): the login form, a wrong password
//! refused, the viewer's Close refused by role in the page, logout, the operator's Close asked
//! for (Cancel sends nothing) and carried out, the Audit view.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check` with `-- --ignored` after chromium,
//! node and `npm ci --prefix tests/browser`. A missing chromium, node or `node_modules` is a
//! failure, never a skip. Screenshots go to `$UI_ARTIFACTS_DIR/console-auth/` (default: the
//! test's scratch folder).

use pty_rig::browser::{artifacts, Browser};
use pty_rig::console::{add_user, console_url};
use pty_rig::{bin, scratch, Proc};
use std::time::Duration;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check"]
fn login_refusal_by_role_and_logout_in_chromium() {
    let browser = Browser::require();
    let dir = scratch("console-auth-browser");
    let users = dir.join("users.toml");
    let _ = std::fs::remove_file(&users);
    add_user(&users, "vera", "viewer", "veravera");
    add_user(&users, "otto", "operator", "ottootto");
    let list = dir.join("list.toml");
    std::fs::write(&list, "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n").unwrap();
    let mut p = Proc::spawn(
        bin("dnet-master"),
        &[
            "--bus",
            "sim",
            "ui",
            "--listen",
            "127.0.0.1:0",
            "--no-history",
            "--scanlist",
            list.to_str().unwrap(),
            "--users",
            users.to_str().unwrap(),
        ],
    );
    let url = console_url(&p, Duration::from_secs(30));
    let out = artifacts("console-auth", "console-auth-browser-artifacts");
    let run = browser.run("console_auth.test.mjs", &url, &out);
    assert!(run.success, "the browser test failed:\n{}\n{}", run.text, p.dump());
    assert!(run.text.contains("6 passed, 0 failed"), "{}", run.text);
    for shot in ["login", "refused-by-role", "audit"] {
        assert!(out.join(format!("{shot}.png")).is_file(), "no screenshot {shot}.png");
    }
    p.signal("INT");
    assert_eq!(p.wait(Duration::from_secs(20)).and_then(|s| s.code()), Some(130), "{}", p.dump());
}
