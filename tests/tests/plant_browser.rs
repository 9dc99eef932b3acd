//! Several networks in one console in a real browser: Debian's `chromium` driven by
//! `playwright-core` (`tests/browser/plant.test.mjs`) against `dnet-master --slave-mac 5,6 ui
//! --plant FILE` with two simulated networks, `a` scanning MAC 5 and `b` MAC 6: a tab per
//! network, each network's grid, network b's node in the device view through `/api/net/b/`.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check`'s plant-networks stage after `cargo
//! build -p master-harness` and `npm ci --prefix tests/browser`. A missing chromium, node or
//! `node_modules` is a failure, never a skip. The screenshots go to `$UI_ARTIFACTS_DIR/plant/`
//! (default: a scratch folder).

use pty_rig::browser::{artifacts, Browser};
use pty_rig::console::spawn_ui;
use std::time::Duration;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check's plant-networks stage"]
fn a_tab_per_network_in_chromium() {
    let browser = Browser::require();
    let out = artifacts("plant", "plant-browser");
    let node = |mac: u8| format!("[[node]]\nmac = {mac}\ninput_size = 18\noutput_size = 8\n");
    std::fs::write(out.join("a.toml"), node(5)).unwrap();
    std::fs::write(out.join("b.toml"), node(6)).unwrap();
    let plant = out.join("plant.toml");
    std::fs::write(
        &plant,
        "[[network]]\nname = \"a\"\nbus = \"sim\"\nscanlist = \"a.toml\"\n\n\
         [[network]]\nname = \"b\"\nbus = \"sim\"\nscanlist = \"b.toml\"\n",
    )
    .unwrap();
    let (mut ui, addr) = spawn_ui(
        &["--slave-mac", "5,6"],
        &["--plant", plant.to_str().unwrap(), "--no-history"],
        Duration::from_secs(20),
        String::new,
    );
    let run = browser.run("plant.test.mjs", &format!("http://{addr}/"), &out);
    ui.terminate();
    assert!(run.success, "the browser test failed:\n{}\n{}", run.text, ui.dump());
    assert_eq!(run.steps_passed(), 3, "three steps passed:\n{}", run.text);
    for shot in ["plant-network-a.png", "plant-network-b.png"] {
        assert!(out.join(shot).is_file(), "no screenshot {shot}");
    }
}
