//! `dnet-master ui --opcua` as a process, used by an independent OPC UA client: PyPI asyncua
//! (`tests/python/opcua_client.py`).
//!
//! - `read`: anonymous browse and read of every node, each value compared with the console's
//!   `GET /api/node/MAC`, the currents' EngineeringUnits, an anonymous Close refused;
//! - `call` (with `--users` and `--opcua-pki`): anonymous and viewer calls refused, a wrong
//!   password refused, the operator's Close and Open carried out and seen by subscription as the
//!   breaker reports its switch, SetOutput carried out and one of the wrong size refused; afterwards the audit table of the history holds every call with
//!   its user and result.
//!
//! On the simulated bus, and on the real SLCAN path (the soft slave and the simulated breaker on
//! socat pty pairs, pty-rig). And the refusal of a non-loopback address without `--users`.
//!
//! Needs the built `dnet-master` (and `dnet-soft-slave`, `dnet-sim-breaker` for the pty test), a
//! Python with asyncua (`DNET_PYTHON`, default `.venv/bin/python`) and socat: ignored in the plain
//! host-test run, run by `scripts/check` with `-- --ignored`.

use pty_rig::console::{add_user, console_url, stop_ui};
use pty_rig::{bin, in_ci, require_socat, scratch, workspace_dir, Proc, PtyRig};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

/// The operator's and the viewer's passwords in the users file the tests write.
const OPERATOR: (&str, &str) = ("op", "operator password");
const VIEWER: (&str, &str) = ("vi", "viewer password");

/// The Python with asyncua, or `None` (skipped) outside CI; in CI a missing asyncua fails.
fn require_asyncua() -> Option<PathBuf> {
    let python = std::env::var_os("DNET_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_dir().join(".venv/bin/python"));
    let ok = Command::new(&python)
        .args(["-c", "import asyncua, cryptography"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let how = format!("{} cannot import asyncua: .venv/bin/pip install asyncua==2.1.0", python.display());
    assert!(ok || !in_ci(), "{how}");
    if !ok {
        eprintln!("skipped: {how}");
    }
    ok.then_some(python)
}

/// Starts `dnet-master BUS ui ... --opcua 127.0.0.1:0 EXTRA`; the process, the console's URL and
/// the OPC UA endpoint URL.
fn start_ui(bus: &str, extra: &[&str]) -> (Proc, String, String) {
    let mut args = vec!["--bus", bus, "ui", "--listen", "127.0.0.1:0", "--opcua", "127.0.0.1:0"];
    args.extend_from_slice(extra);
    let p = Proc::spawn(bin("dnet-master"), &args);
    let opcua = p
        .wait_stdout("opc ua at ", Duration::from_secs(30))
        .unwrap_or_else(|| panic!("no OPC UA endpoint\n{}", p.dump()));
    let console = console_url(&p, Duration::from_secs(30));
    (p, console, opcua.trim_start_matches("opc ua at ").trim().to_string())
}

/// Waits until the OPC UA server shows every node of the scan list out of `initializing` (at most
/// `limit`): read anonymously, so it works with logins on the console too.
fn wait_scanning(python: &Path, url: &str, macs: &[u8], limit: Duration) {
    let script = "import asyncio,sys,time\n\
        from asyncua import Client\n\
        async def main():\n\
        \x20   end=time.time()+float(sys.argv[2])\n\
        \x20   while time.time()<end:\n\
        \x20       try:\n\
        \x20           async with Client(sys.argv[1]) as c:\n\
        \x20               ns=await c.get_namespace_index('urn:dnet-master:devicenet')\n\
        \x20               ok=True\n\
        \x20               for mac in sys.argv[3].split(','):\n\
        \x20                   n=await c.nodes.objects.get_child([f'{ns}:DeviceNet',f'{ns}:MAC{int(mac):02d}',f'{ns}:Status',f'{ns}:Status'])\n\
        \x20                   ok=ok and (await n.read_value())!='initializing'\n\
        \x20               if ok: return 0\n\
        \x20       except Exception: pass\n\
        \x20       await asyncio.sleep(0.3)\n\
        \x20   return 1\n\
        sys.exit(asyncio.run(main()))\n";
    let list: Vec<String> = macs.iter().map(ToString::to_string).collect();
    let ok = Command::new(python)
        .args(["-c", script, url, &limit.as_secs().to_string(), &list.join(",")])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "the OPC UA server never showed MACs {macs:?} scanned within {limit:?}");
}

/// Runs the client in `mode` with `args`; its `compared:` count, after checking it passed.
fn run_client(python: &Path, mode: &str, args: &[&str], p: &Proc) -> usize {
    let script = workspace_dir().join("tests/python/opcua_client.py");
    let out =
        Command::new(python).arg(&script).arg(mode).args(args).output().expect("the Python client runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "client {mode} failed:\n{stdout}\n{stderr}\n{}", p.dump());
    eprintln!("{stdout}");
    let line = stdout.lines().find(|l| l.starts_with("compared: ")).unwrap_or_default();
    line.split_whitespace().nth(1).and_then(|n| n.parse().ok()).unwrap_or_else(|| panic!("{stdout}"))
}

/// A users file with an operator and a viewer, made by `dnet-master user add`.
fn users_file(dir: &Path) -> PathBuf {
    let path = dir.join("users.toml");
    let _ = std::fs::remove_file(&path);
    for ((name, password), role) in [(OPERATOR, "operator"), (VIEWER, "viewer")] {
        add_user(&path, name, role, password);
    }
    path
}

/// The audit rows of the history: `user|via|mac|what|result`, oldest first.
fn audit_rows(python: &Path, history: &Path) -> Vec<String> {
    let script = "import sqlite3,sys\n\
        for r in sqlite3.connect(sys.argv[1]).execute('select user,via,mac,what,result from audit order by id'):\n\
        \x20   print('|'.join(str(x) for x in r))\n";
    let out = Command::new(python).args(["-c", script, history.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).lines().map(str::to_string).collect()
}

/// The read check: anonymous, compared with the console.
fn read_check(python: &Path, bus: &str, extra: &[&str], macs: &[u8], limit: Duration) -> usize {
    let (mut p, console, url) = start_ui(bus, &[&["--no-history"][..], extra].concat());
    wait_scanning(python, &url, macs, limit);
    let n = macs.len().to_string();
    let compared = run_client(python, "read", &["--url", &url, "--console", &console, "--min-nodes", &n], &p);
    stop_ui(&mut p, Duration::from_secs(30), "");
    compared
}

/// The call check on MAC 5 with accounts and the encrypted endpoint; the audit rows.
fn call_check(python: &Path, bus: &str, dir: &Path, limit: Duration) -> Vec<String> {
    let users = users_file(dir);
    let history = dir.join("history.sqlite");
    let _ = std::fs::remove_file(&history);
    let pki = dir.join("pki");
    let (u, h, k) = (users.to_str().unwrap(), history.to_str().unwrap(), pki.to_str().unwrap());
    let (mut p, _, url) = start_ui(bus, &["--users", u, "--history", h, "--opcua-pki", k]);
    wait_scanning(python, &url, &[5], limit);
    let args = ["--url", &url, "--mac", "5", "--user", OPERATOR.0, "--password", OPERATOR.1];
    let args = [&args[..], &["--viewer", VIEWER.0, "--viewer-password", VIEWER.1]].concat();
    let compared = run_client(python, "call", &args, &p);
    assert_eq!(compared, 8, "four refusals, Close and Open, SetOutput carried out and refused");
    stop_ui(&mut p, Duration::from_secs(30), "");
    assert!(pki.join("own/cert.der").is_file(), "the server's certificate is made in --opcua-pki");
    audit_rows(python, &history)
}

/// The audit log holds each call with its user and result: the two anonymous refusals, the
/// viewer's, the operator's two breaker commands and two SetOutput (in the order made).
fn assert_audited(rows: &[String]) {
    let opcua: Vec<&String> = rows.iter().filter(|r| r.contains("|opcua|")).collect();
    assert_eq!(opcua.len(), 7, "{rows:#?}");
    assert!(
        opcua[..2].iter().all(|r| r.starts_with("anonymous|opcua|5|") && r.contains("|refused: ")),
        "{rows:#?}"
    );
    assert!(opcua[2].starts_with("vi|opcua|5|close|refused: role viewer"), "{rows:#?}");
    assert!(opcua[3].starts_with("op|opcua|5|") && opcua[3].ends_with("|ok"), "{rows:#?}");
    assert!(opcua[4].starts_with("op|opcua|5|") && opcua[4].ends_with("|ok"), "{rows:#?}");
    assert!(opcua[5].starts_with("op|opcua|5|output ") && opcua[5].ends_with("|ok"), "{rows:#?}");
    assert!(opcua[6].starts_with("op|opcua|5|output 01 02 03|failed: "), "{rows:#?}");
}

#[test]
#[ignore = "needs the built dnet-master and asyncua: run by scripts/check"]
fn asyncua_reads_what_the_console_shows_on_the_simulated_bus() {
    let Some(python) = require_asyncua() else { return };
    let dir = scratch("opcua-sim-read");
    // MAC 5 is the simulated breaker; nothing answers at MAC 20 (not_present, code 78).
    let list = dir.join("plant.toml");
    std::fs::write(
        &list,
        "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n\n[[node]]\nmac = 20\ninput_size = 4\noutput_size = 2\n",
    )
    .unwrap();
    let compared = read_check(
        &python,
        "sim",
        &["--scanlist", list.to_str().unwrap()],
        &[5, 20],
        Duration::from_secs(60),
    );
    // 11 per node and the breaker's 9 inputs and parameters, its unit and its refusal.
    assert!(compared >= 2 * 11 + 9 + 2, "compared {compared}");
}

#[test]
#[ignore = "needs the built dnet-master and asyncua: run by scripts/check"]
fn asyncua_calls_close_and_open_as_an_operator_only_on_the_simulated_bus() {
    let Some(python) = require_asyncua() else { return };
    let dir = scratch("opcua-sim-call");
    let rows = call_check(&python, "sim", &dir, Duration::from_secs(60));
    assert_audited(&rows);
}

#[test]
#[ignore = "needs socat, the built programs and asyncua: run by scripts/check"]
fn asyncua_reads_and_switches_the_breaker_over_slcan() {
    let Some(python) = require_asyncua() else { return };
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("opcua-slcan", &["--period", "0.3"], None);
    let bus = rig.master_bus_arg();
    let compared = read_check(&python, &bus, &[], &[5], Duration::from_secs(90));
    assert!(compared >= 11 + 9 + 2, "compared {compared}\n{}", rig.dump());
    let rows = call_check(&python, &bus, &rig.dir, Duration::from_secs(90));
    assert_audited(&rows);
    // The breaker itself received both commands over its serial line.
    let log = rig.breaker_log();
    assert!(log.contains("command close") && log.contains("command open"), "{log}");
}

#[test]
#[ignore = "needs the built dnet-master: run by scripts/check"]
fn a_non_loopback_address_without_users_is_refused_before_the_bus() {
    for args in
        [&["--opcua", "0.0.0.0:0"][..], &["--opcua", "http://127.0.0.1:4840"], &["--opcua-pki", "/tmp"]]
    {
        let out = Command::new(bin("dnet-master"))
            .args(["--bus", "sim", "ui", "--listen", "127.0.0.1:0", "--no-history", "--cycles", "1"])
            .args(args)
            .output()
            .expect("dnet-master runs");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stdout}\n{stderr}");
        assert!(!stdout.contains("console at"), "{args:?}: the console started: {stdout}");
        assert!(stderr.contains("--opcua"), "{args:?}: {stderr}");
    }
}
