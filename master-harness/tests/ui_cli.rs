//! `dnet-master ui`'s bad input and unavailable parts, through the program: an address in use, a
//! history that cannot be opened and a malformed broker URL are refused before the bus is touched
//! (exit 2, the thing named); a broker that is down is not an error: the scanner scans to the end.

use std::process::{Command, Output};

fn dnet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-master")).args(args).output().expect("run dnet-master")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-ui-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn an_address_in_use_is_refused_and_named() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let dir = scratch("in-use");
    let history = dir.join("h.sqlite");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        &addr,
        "--history",
        history.to_str().unwrap(),
        "--cycles",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains(&format!("cannot listen on {addr}")), "{}", text(&o));
}

#[test]
fn a_history_that_cannot_be_opened_is_refused_and_named() {
    let o =
        dnet(&["--bus", "sim", "ui", "--listen", "127.0.0.1:0", "--history", "/nonexistent/dir/h.sqlite"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("/nonexistent/dir/h.sqlite"), "{}", text(&o));
    let dir = scratch("not-a-db");
    let bogus = dir.join("notes.sqlite");
    std::fs::write(&bogus, "these are not a database, just text long enough to be read as a header").unwrap();
    let o = dnet(&["--bus", "sim", "ui", "--listen", "127.0.0.1:0", "--history", bogus.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("is not an SQLite database"), "{}", text(&o));
}

#[test]
fn a_malformed_broker_url_is_refused() {
    let dir = scratch("bad-url");
    let history = dir.join("h.sqlite");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--mqtt",
        "http://x",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--mqtt http://x"), "{}", text(&o));
}

#[test]
fn a_broker_that_is_down_does_not_stop_the_scanner() {
    // Nothing listens on a port just released.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let dir = scratch("broker-down");
    let history = dir.join("h.sqlite");
    let url = format!("mqtt://127.0.0.1:{port}");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--mqtt",
        &url,
        "--cycles",
        "30",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.starts_with("console at http://127.0.0.1:"), "{out}");
    assert!(out.contains("  5  ok"), "node 5 kept in I/O: {out}");
    assert!(out.contains("30 cycle(s)"), "{out}");
}

#[test]
fn a_run_that_exchanged_nothing_is_not_a_success() {
    // --cycles 0: the node is allocated but no poll was answered yet: exit 1, as scanner.
    let dir = scratch("no-cycles");
    let history = dir.join("h.sqlite");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--cycles",
        "0",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("initializing"), "{}", text(&o));
}
