//! The network project in the web console (issue 28 item 4, guide: docs/src/plant/projects.md):
//! `dnet-master ui --project FILE` and `GET /api/project/compare`, as programs talking HTTP, on the
//! simulated bus and on the real SLCAN path (the soft slave and the simulated breaker on socat
//! ptys). A project uploaded from the network is equal, with every compared part counted; a
//! project with another product code, parameter value or configuration shows those differences;
//! a project file with an unknown key is refused with file and line (exit 2) before the bus; with
//! logins, a viewer may compare (it only reads).
//!
//! Needs the dnet-master program (and socat for the SLCAN test): ignored in the plain host-test
//! run, run by scripts/check's project-console stage.

use pty_rig::console::{add_user, free_addr, get, request, spawn_ui, wait_listening};
use pty_rig::{require_socat, Proc, PtyRig};
use serde_json::Value;
use std::path::Path;
use std::time::{Duration, Instant};

/// Waits until the console listens and every node of `macs` is ok in the console's state.
fn wait_ok(addr: &str, macs: &[u64], ui: &Proc) {
    let end = Instant::now() + Duration::from_secs(60);
    wait_listening(addr, Duration::from_secs(60), || ui.dump());
    loop {
        let (status, body) = get(addr, "/api/state");
        let v: Value = serde_json::from_str(&body).unwrap_or_default();
        let ok = |m: &u64| {
            v["nodes"].as_array().is_some_and(|n| n.iter().any(|n| n["mac"] == *m && n["status"] == "ok"))
        };
        if status == 200 && macs.iter().all(ok) {
            return;
        }
        assert!(Instant::now() < end, "nodes {macs:?} never ok: {body}\n{}", ui.dump());
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Starts `dnet-master ARGS ui --listen ADDR --no-history --project FILE EXTRA`, waits for the
/// nodes `macs` ok, asks `GET /api/project/compare`; the status and the answer.
fn compare(global: &[&str], project: &Path, extra: &[&str], macs: &[u64]) -> (u16, Value) {
    let addr = free_addr();
    let mut args: Vec<&str> = global.to_vec();
    args.extend(["ui", "--listen", &addr, "--no-history", "--project", project.to_str().unwrap()]);
    args.extend_from_slice(extra);
    let mut ui = Proc::spawn(pty_rig::bin("dnet-master"), &args);
    wait_ok(&addr, macs, &ui);
    let (status, body) = get(&addr, "/api/project/compare");
    let v: Value = serde_json::from_str(&body).unwrap_or_else(|e| panic!("{e}: {body}\n{}", ui.dump()));
    ui.terminate();
    (status, v)
}

/// `dnet-master ARGS` as a program: exit status, standard output and error.
fn dnet(args: &[&str]) -> (i32, String, String) {
    let mut p = Proc::spawn(pty_rig::bin("dnet-master"), args);
    let status = p
        .wait(Duration::from_secs(120))
        .unwrap_or_else(|| panic!("dnet-master {args:?} hangs\n{}", p.dump()));
    (status.code().unwrap_or(-1), p.stdout.text(), p.stderr.text())
}

/// The differences as `(mac, what, expected, found)`.
fn differences(v: &Value) -> Vec<(u64, String, String, String)> {
    let text = |d: &Value, k: &str| d[k].as_str().unwrap_or_default().to_string();
    v["differences"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| (d["mac"].as_u64().unwrap(), text(d, "what"), text(d, "expected"), text(d, "found")))
        .collect()
}

/// The uploaded project with MAC `mac`'s node changed: its product code 2 in the project's
/// identity, parameter 4 (Stale timeout) 4000, and with `config` the serial baud rate of its
/// configuration 19200.
fn changed(text: &str, mac: u8, config: bool) -> String {
    let start = text.find(&format!("[[node]]\nmac = {mac}\n")).unwrap();
    let end = text[start + 1..].find("[[node]]\n").map_or(text.len(), |e| start + 1 + e);
    let mut node = text[start..end]
        .replacen(
            "\n[node.identity]\nvendor_id = 0x1234\ndevice_type = 0x000C\nproduct_code = 1\n",
            "\n[node.identity]\nvendor_id = 0x1234\ndevice_type = 0x000C\nproduct_code = 2\n",
            1,
        )
        .replacen("name = \"Stale timeout\"\nvalue = 3000\n", "name = \"Stale timeout\"\nvalue = 4000\n", 1);
    if config {
        node = node.replacen("baud = 9600\n", "baud = 19200\n", 1);
    }
    assert!(node.contains("product_code = 2\n") && node.contains("value = 4000\n"), "{node}");
    format!("{}{node}{}", &text[..start], &text[end..])
}

fn equal_parts(v: &Value, nodes: u64) {
    assert_eq!(v["ok"], true, "{v}");
    assert_eq!(v["equal"], true, "{v}");
    assert_eq!(differences(v), [], "{v}");
    assert_eq!(v["not_compared"].as_array().map(Vec::len), Some(0), "{v}");
    let c = &v["compared"];
    for part in ["nodes", "scan_list", "identity", "configuration"] {
        assert_eq!(c[part], nodes, "{part}: {v}");
    }
    assert_eq!(c["parameters"], 9 * nodes, "the breaker's 9 parameters each: {v}");
}

#[test]
#[ignore = "needs dnet-master built: run by scripts/check's project-console stage"]
fn sim_console_compares_the_project() {
    let dir = pty_rig::scratch("project-console-sim");
    let file = dir.join("plant.toml");
    let sim = ["--bus", "sim", "--slave-mac", "5,6"];
    let mut upload = sim.to_vec();
    upload.extend(["project", "upload", file.to_str().unwrap()]);
    let (code, out, err) = dnet(&upload);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("2 node(s) written"), "{out}");

    let (status, v) = compare(&sim, &file, &[], &[5, 6]);
    assert_eq!(status, 200, "{v}");
    equal_parts(&v, 2);

    let text = std::fs::read_to_string(&file).unwrap();
    let other = dir.join("other.toml");
    std::fs::write(&other, changed(&text, 6, true)).unwrap();
    let (status, v) = compare(&sim, &other, &[], &[5, 6]);
    assert_eq!(status, 200, "{v}");
    assert_eq!(v["equal"], false, "{v}");
    let d = differences(&v);
    let what: Vec<(u64, &str)> = d.iter().map(|d| (d.0, d.1.as_str())).collect();
    assert_eq!(
        what,
        [
            (6, "identity product_code (keying exact)"),
            (6, "configuration (CCV, Identity attribute 9)"),
            (6, "parameter 4 (Stale timeout)")
        ],
        "{v}"
    );
    assert_eq!((d[0].2.as_str(), d[0].3.as_str()), ("2", "1"), "{v}");
    assert_eq!((d[2].2.as_str(), d[2].3.as_str()), ("4000", "3000"), "{v}");
    let factory = format!("0x{:04X}", slave_fw::converter::consistency::FACTORY_CCV);
    assert_ne!(d[1].2, d[1].3, "{v}");
    assert_eq!(d[1].3, factory, "the simulated breaker stores the factory configuration: {v}");
    assert_eq!(v["compared"]["nodes"], 2, "{v}");

    // Without --project: 404, no verdict.
    let addr = free_addr();
    let mut args = sim.to_vec();
    args.extend(["ui", "--listen", &addr, "--no-history"]);
    let mut ui = Proc::spawn(pty_rig::bin("dnet-master"), &args);
    wait_ok(&addr, &[5], &ui);
    let (status, body) = get(&addr, "/api/project/compare");
    ui.terminate();
    assert_eq!(status, 404, "{body}");
    assert!(body.contains("\"project\":null") && body.contains("--project"), "{body}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
#[ignore = "needs dnet-master built: run by scripts/check's project-console stage"]
fn a_viewer_may_compare() {
    let dir = pty_rig::scratch("project-console-viewer");
    let users = dir.join("users.toml");
    let _ = std::fs::remove_file(&users);
    add_user(&users, "vera", "viewer", "veravera");
    // The identity and the scan list only: no configuration, no parameters.
    let file = dir.join("plant.toml");
    std::fs::write(
        &file,
        "format = 1\n\n[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n\n[node.identity]\n\
         vendor_id = 0x1234\ndevice_type = 0x000C\nproduct_code = 1\nmajor_revision = 1\nminor_revision = 1\n",
    )
    .unwrap();
    let (mut ui, addr) = spawn_ui(
        &["--bus", "sim", "--slave-mac", "5"],
        &["--no-history", "--users", users.to_str().unwrap(), "--project", file.to_str().unwrap()],
        Duration::from_secs(30),
        String::new,
    );
    let end = Instant::now() + Duration::from_secs(30);
    let r = request(&addr, "GET", "/api/project/compare", "", "");
    assert_eq!(r.status, 401, "no session: {}", r.body);
    let json = format!("Origin: http://{addr}\r\nContent-Type: application/json\r\n");
    let r = request(&addr, "POST", "/api/login", &json, r#"{"user":"vera","password":"veravera"}"#);
    assert_eq!(r.status, 200, "{}", r.body);
    let cookie = r.head.lines().find_map(|l| l.strip_prefix("Set-Cookie: ")).unwrap();
    let cookie = format!("Cookie: {}\r\n", cookie.split(';').next().unwrap());
    // Compared once the scanner has the node in I/O (before, its identity may not be read yet).
    loop {
        let body = request(&addr, "GET", "/api/state", &cookie, "").body;
        let state: Value = serde_json::from_str(&body).unwrap_or_default();
        if state["nodes"].as_array().is_some_and(|n| n.iter().any(|n| n["mac"] == 5 && n["status"] == "ok")) {
            break;
        }
        assert!(Instant::now() < end + Duration::from_secs(30), "MAC 5 never ok: {body}\n{}", ui.dump());
        std::thread::sleep(Duration::from_millis(200));
    }
    let r = request(&addr, "GET", "/api/project/compare", &cookie, "");
    assert_eq!(r.status, 200, "a viewer may compare: {}", r.body);
    let v: Value = serde_json::from_str(&r.body).unwrap();
    ui.terminate();
    assert_eq!(v["equal"], true, "{v}");
    let c = &v["compared"];
    assert_eq!((&c["nodes"], &c["identity"], &c["scan_list"]), (&1.into(), &1.into(), &1.into()), "{v}");
    assert_eq!((&c["configuration"], &c["parameters"]), (&0.into(), &0.into()), "{v}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
#[ignore = "needs dnet-master built: run by scripts/check's project-console stage"]
fn a_bad_project_is_refused_before_the_bus() {
    let dir = pty_rig::scratch("project-console-bad");
    let file = dir.join("bad.toml");
    std::fs::write(
        &file,
        "format = 1\n\n[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\ncolour = \"red\"\n",
    )
    .unwrap();
    // A serial port that does not exist: the bus would fail; the project is refused first.
    let (code, out, err) = dnet(&[
        "--bus",
        "slcan:/nonexistent/tty",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--no-history",
        "--project",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{out}\n{err}");
    assert!(err.contains(&format!("{}:7: unknown key `colour`", file.display())), "{err}");
    assert!(!out.contains("console at"), "refused before the console: {out}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check's project-console stage"]
fn slcan_console_compares_the_project() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("project-console-slcan", &["--period", "0.3"], None);
    let bus = rig.master_bus_arg();
    let file = rig.dir.join("plant.toml");
    let (code, out, err) =
        dnet(&["--bus", &bus, "project", "upload", file.to_str().unwrap(), "--from", "1", "--to", "10"]);
    assert_eq!(code, 0, "{out}\n{err}\n{}", rig.dump());
    let list = rig.dir.join("list.toml");
    std::fs::write(&list, "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n").unwrap();
    let scanlist = ["--scanlist", list.to_str().unwrap()];

    let (status, v) = compare(&["--bus", &bus], &file, &scanlist, &[5]);
    assert_eq!(status, 200, "{v}\n{}", rig.dump());
    equal_parts(&v, 1);

    let other = rig.dir.join("other.toml");
    std::fs::write(&other, changed(&std::fs::read_to_string(&file).unwrap(), 5, false)).unwrap();
    let (status, v) = compare(&["--bus", &bus], &other, &scanlist, &[5]);
    assert_eq!(status, 200, "{v}\n{}", rig.dump());
    let s = |x: &str| x.to_string();
    assert_eq!(
        differences(&v),
        [
            (5, s("identity product_code (keying exact)"), s("2"), s("1")),
            (5, s("parameter 4 (Stale timeout)"), s("4000"), s("3000")),
        ],
        "{v}"
    );
    assert_eq!(v["equal"], false, "{v}");
    let _ = std::fs::remove_dir_all(&rig.dir);
}
