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

use std::path::Path;
use std::process::Command;
use std::time::Duration;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check's project-console stage"]
fn project_panel_in_chromium() {
    let browser = Path::new(env!("CARGO_MANIFEST_DIR")).join("browser");
    assert!(browser.join("node_modules/playwright-core").is_dir(), "npm ci --prefix tests/browser");
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    assert!(Path::new(&chromium).exists(), "{chromium} is missing: apt-get install chromium");
    let out = std::env::var_os("UI_ARTIFACTS_DIR")
        .map_or_else(|| pty_rig::scratch("project-browser"), |d| Path::new(&d).join("project"));
    std::fs::create_dir_all(&out).unwrap();

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

    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let addr = format!("127.0.0.1:{port}");
    let mut ui = pty_rig::Proc::spawn(
        pty_rig::bin("dnet-master"),
        &[
            "--bus",
            "sim",
            "--slave-mac",
            "5,6",
            "ui",
            "--listen",
            &addr,
            "--no-history",
            "--project",
            other.to_str().unwrap(),
        ],
    );
    let end = std::time::Instant::now() + Duration::from_secs(20);
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(std::time::Instant::now() < end, "the console did not start\n{}", ui.dump());
        std::thread::sleep(Duration::from_millis(100));
    }
    let result = Command::new("node")
        .arg("project_console.test.mjs")
        .current_dir(&browser)
        .env("CONSOLE_URL", format!("http://{addr}/"))
        .env("ARTIFACTS_DIR", &out)
        .env("CHROMIUM", &chromium)
        .output()
        .expect("node runs (install Node.js)");
    let text =
        format!("{}{}", String::from_utf8_lossy(&result.stdout), String::from_utf8_lossy(&result.stderr));
    println!("{text}");
    ui.terminate();
    assert!(result.status.success(), "the browser test failed:\n{text}\n{}", ui.dump());
    assert!(
        text.matches("\nok   ").count() + usize::from(text.starts_with("ok   ")) == 3,
        "three steps passed:\n{text}"
    );
    assert!(out.join("console-project.png").is_file(), "no screenshot");
}
