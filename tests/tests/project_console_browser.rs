//! The console's Project panel in a real browser: Debian's `chromium` driven by `playwright-core`
//! (`tests/browser/project_console.test.mjs`) against `dnet-master --bus sim --slave-mac 5,6 ui
//! --project FILE`, the project uploaded from the same network with MAC 6's product code and stale
//! timeout changed: the verdict, a row per difference, the same counts and rows as
//! `GET /api/project/compare`, the Compare button.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check`'s project-console stage after `cargo
//! build -p master-harness` and `npm ci --prefix tests/browser`. A missing chromium, node or
//! `node_modules` is a failure, never a skip. The screenshot goes to
//! `$UI_ARTIFACTS_DIR/project/` (default: a scratch folder).

use pty_rig::browser::{artifacts, Browser};
use pty_rig::console::spawn_ui;
use std::time::Duration;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check's project-console stage"]
fn project_panel_in_chromium() {
    let browser = Browser::require();
    let out = artifacts("project", "project-browser");

    let file = out.join("plant.toml");
    let mut upload = pty_rig::Proc::spawn(
        pty_rig::bin("dnet-master"),
        &["--bus", "sim", "--slave-mac", "5,6", "project", "upload", file.to_str().unwrap()],
    );
    let status = upload.wait(Duration::from_secs(120)).expect("project upload ends");
    assert!(status.success(), "project upload\n{}", upload.dump());
    let text = std::fs::read_to_string(&file).unwrap();
    let at = text.find("[[node]]\nmac = 6\n").expect("MAC 6 uploaded");
    let node = text[at..]
        .replacen(
            "[node.identity]\nvendor_id = 0x1234\ndevice_type = 0x000C\nproduct_code = 1\n",
            "[node.identity]\nvendor_id = 0x1234\ndevice_type = 0x000C\nproduct_code = 2\n",
            1,
        )
        .replacen("name = \"Stale timeout\"\nvalue = 3000\n", "name = \"Stale timeout\"\nvalue = 4000\n", 1);
    assert!(node.contains("product_code = 2\n") && node.contains("value = 4000\n"), "{node}");
    let other = out.join("other.toml");
    std::fs::write(&other, format!("{}{node}", &text[..at])).unwrap();

    let (mut ui, addr) = spawn_ui(
        &["--bus", "sim", "--slave-mac", "5,6"],
        &["--no-history", "--project", other.to_str().unwrap()],
        Duration::from_secs(20),
        String::new,
    );
    let run = browser.run("project_console.test.mjs", &format!("http://{addr}/"), &out);
    ui.terminate();
    assert!(run.success, "the browser test failed:\n{}\n{}", run.text, ui.dump());
    assert_eq!(run.steps_passed(), 3, "three steps passed:\n{}", run.text);
    assert!(out.join("console-project.png").is_file(), "no screenshot");
}
