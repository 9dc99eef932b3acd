//! `dnet-master project upload|compare|download` on the simulated bus (in process) and on the real
//! SLCAN path (the `dnet-master` program against `dnet-soft-slave --state FILE` on socat ptys):
//! upload, compare equal (exit 0), change a parameter or the configuration, compare (exit 1, the
//! difference named), download, compare equal again; a project file with an unknown key refused
//! with file and line (exit 2); nothing compared is a failure, never "equal".

use pty_rig::{require_socat, Proc, PtyRig};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// `dnet-master ARGS` in process: exit status, standard output, standard error.
fn run(args: &[&str]) -> (u8, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut all = vec!["dnet-master"];
    all.extend_from_slice(args);
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn scratch(test: &str) -> PathBuf {
    pty_rig::scratch(test)
}

/// The reference breaker's description with another serial baud rate and stale timeout.
fn changed_description(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(pty_rig::workspace_dir().join("slave-fw/descriptions/breaker.toml"))
        .unwrap()
        .replace("baud = 9600", "baud = 19200")
        .replace("stale_timeout_ms = 3000", "stale_timeout_ms = 4000");
    assert!(
        text.contains("baud = 19200") && text.contains("stale_timeout_ms = 4000"),
        "the description changed"
    );
    let path = dir.join("changed.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn sim_upload_compare_change_download() {
    let dir = scratch("project-sim");
    let file = dir.join("plant.toml");
    let f = file.to_str().unwrap();
    let (code, out, err) = run(&["--slave-mac", "5,6", "project", "upload", f]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("2 node(s) written"), "{out}");
    let text = std::fs::read_to_string(&file).unwrap();
    for needle in
        ["mac = 5", "mac = 6", "[profile.serial]", "name = \"Serial baud rate\"", "keying = \"exact\""]
    {
        assert!(text.contains(needle), "{needle} not in the project:\n{text}");
    }

    let (code, out, err) = run(&["--slave-mac", "5,6", "project", "compare", f]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("2 node(s) compared (18 parameter(s)"), "{out}");
    assert!(out.contains("the network equals the project"), "{out}");

    // The same network with another configuration: each difference named, exit 1.
    let changed = changed_description(&dir);
    let c = changed.to_str().unwrap();
    let (code, out, err) = run(&["--slave-mac", "5,6", "--slave-config", c, "project", "compare", f]);
    assert_eq!(code, 1, "{out}\n{err}");
    for needle in [
        "MAC 5: configuration profile.serial.baud: file 9600, network 19200",
        "MAC 6: configuration profile.health.stale_timeout_ms: file 3000, network 4000",
        "MAC 5: parameter 1 (Serial baud rate): file 9600, network 19200",
        "MAC 6: parameter 4 (Stale timeout): file 3000, network 4000",
        "8 difference(s)",
    ] {
        assert!(out.contains(needle), "{needle}:\n{out}");
    }

    // Download restores it, and the comparison after it (in the same run) is equal.
    let (code, out, err) = run(&["--slave-mac", "5,6", "--slave-config", c, "project", "download", f]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("MAC 5: configuration downloaded"), "{out}");
    assert!(out.contains("MAC 6: configuration downloaded"), "{out}");
    assert!(out.contains("the network equals the project"), "{out}");

    // A node missing is a difference; no node of the file answering is a failure, not "equal".
    let (code, out, _) = run(&["--slave-mac", "5", "project", "compare", f]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("MAC 6: node: file present, network absent"), "{out}");
    let (code, out, err) = run(&["--slave-mac", "9", "project", "compare", f]);
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(err.contains("nothing compared"), "{err}");
    assert!(!out.contains("equals"), "{out}");
}

#[test]
fn unknown_keys_are_refused_with_file_and_line() {
    let dir = scratch("project-bad");
    let file = dir.join("bad.toml");
    std::fs::write(
        &file,
        "format = 1\n\n[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\ncolour = \"red\"\n",
    )
    .unwrap();
    let (code, out, err) = run(&["project", "compare", file.to_str().unwrap()]);
    assert_eq!(code, 2, "{out}\n{err}");
    assert!(err.contains(&format!("{}:7: unknown key `colour`", file.display())), "{err}");
}

/// `dnet-master --bus <rig> ARGS` as a program.
fn dnet(rig: &PtyRig, args: &[&str]) -> (i32, String, String) {
    let bus = rig.master_bus_arg();
    let mut all = vec!["--bus", bus.as_str()];
    all.extend_from_slice(args);
    let mut p = Proc::spawn(pty_rig::bin("dnet-master"), &all);
    let status = p
        .wait(Duration::from_secs(120))
        .unwrap_or_else(|| panic!("dnet-master {args:?} hangs\n{}", p.dump()));
    (status.code().unwrap_or(-1), p.stdout.text(), p.stderr.text())
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn slcan_upload_compare_change_download() {
    if !require_socat() {
        return;
    }
    let mut rig = PtyRig::breaker("project-slcan", &["--period", "0.3"], None);
    rig.stop_slave();
    let state = rig.dir.join("state.json");
    rig.start_slave_with(None, &["--state", state.to_str().unwrap()]);
    let file = rig.dir.join("plant.toml");
    let f = file.to_str().unwrap();
    let range = ["--from", "1", "--to", "10"];
    let project = |action: &str| -> Vec<String> {
        let mut v = vec!["project".to_string(), action.to_string(), f.to_string()];
        v.extend(range.iter().map(|s| s.to_string()));
        v
    };
    let call = |rig: &PtyRig, args: Vec<String>| {
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        dnet(rig, &refs)
    };

    let (code, out, err) = call(&rig, project("upload"));
    assert_eq!(code, 0, "{out}\n{err}\n{}", rig.dump());
    assert!(out.contains("1 node(s) written"), "{out}");
    let (code, out, err) = call(&rig, project("compare"));
    assert_eq!(code, 0, "{out}\n{err}\n{}", rig.dump());
    assert!(out.contains("the network equals the project"), "{out}");

    // A parameter changed by a commissioning tool.
    let (code, out, err) = dnet(&rig, &["params", "--mac", "5", "--set", "Stale timeout=4000"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let (code, out, err) = call(&rig, project("compare"));
    assert_eq!(code, 1, "{out}\n{err}\n{}", rig.dump());
    assert!(out.contains("MAC 5: parameter 4 (Stale timeout): file 3000, network 4000"), "{out}");
    let (code, out, err) = call(&rig, project("download"));
    assert_eq!(code, 0, "{out}\n{err}\n{}", rig.dump());
    assert!(out.contains("MAC 5: parameter 4 (Stale timeout) set to 3000 (was 4000)"), "{out}");
    let (code, out, err) = call(&rig, project("compare"));
    assert_eq!(code, 0, "{out}\n{err}");

    // The configuration changed by a download of another description.
    let changed = changed_description(&rig.dir);
    let (code, out, err) = dnet(&rig, &["configure", "--mac", "5", changed.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}\n{err}");
    let (code, out, err) = call(&rig, project("compare"));
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(
        out.contains("MAC 5: configuration profile.health.stale_timeout_ms: file 3000, network 4000"),
        "{out}"
    );
    let (code, out, err) = call(&rig, project("download"));
    assert_eq!(code, 0, "{out}\n{err}\n{}", rig.dump());
    assert!(out.contains("MAC 5: configuration downloaded"), "{out}");
    let (code, out, err) = call(&rig, project("compare"));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("the network equals the project"), "{out}");
    let _ = std::fs::remove_dir_all(&rig.dir);
}
