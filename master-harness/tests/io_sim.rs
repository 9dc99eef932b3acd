//! `connect --io`, `monitor --io` and `recover` as the command line runs them on the simulated
//! bus, with the real slave (issue 14, `docs/src/reference/io-connections.md`): every frame checked, the JSON
//! and the text, exit statuses, and bad options refused with exit status 2.

use serde_json::Value;

fn run(args: &[&str]) -> (u8, String, String) {
    let mut all = vec!["dnet-master"];
    all.extend_from_slice(args);
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn json(args: &[&str]) -> (u8, Value) {
    let mut all = vec!["--json"];
    all.extend_from_slice(args);
    let (code, out, err) = run(&all);
    let v = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}\n{err}"));
    (code, v)
}

#[test]
fn connect_io_strobe_exchanges_and_checks_every_frame() {
    let (code, v) = json(&["connect", "--io", "strobe", "--polls", "4"]);
    assert_eq!((code, &v["failures"]), (0, &Value::from(0)), "{v}");
    let io = &v["device"]["io"];
    assert_eq!(io["kind"], "strobe");
    assert_eq!((io["instance"].as_u64(), io["strobe_responses"].as_u64()), (Some(3), Some(4)), "{v}");
    assert_eq!((io["produced_id"].as_u64(), io["consumed_id"].as_u64()), (Some(0x385), Some(0x400)));
    // The first min(18, 8) input bytes, never fragmented.
    assert_eq!(v["device"]["produced_size"], 8);
    let strobes = v["frames"].as_array().unwrap().iter().filter(|f| f["id"] == "400").count();
    assert_eq!(strobes, 4, "{v}");
}

#[test]
fn connect_io_cos_and_cyclic_acknowledge_every_production() {
    for kind in ["cos", "cyclic"] {
        let (code, v) = json(&["connect", "--io", kind, "--polls", "5"]);
        assert_eq!((code, &v["failures"]), (0, &Value::from(0)), "{kind}: {v}");
        let io = &v["device"]["io"];
        assert_eq!(io["productions"], 5, "{kind}: {io}");
        assert_eq!(io["acks_sent"], 5, "{kind}: {io}");
        assert_eq!((io["outputs_sent"].as_u64(), io["outputs_acknowledged"].as_u64()), (Some(5), Some(5)));
        assert_eq!((io["produced_id"].as_u64(), io["consumed_id"].as_u64()), (Some(0x345), Some(0x42A)));
        assert_eq!((io["ack_timer_ms"].as_u64(), io["retry_limit"].as_u64()), (Some(16), Some(1)));
        assert_eq!(v["device"]["produced_size"], 18);
        let acks = v["frames"].as_array().unwrap().iter().filter(|f| f["id"] == "42A").count();
        assert_eq!(acks, 5, "{kind}");
    }
    let (_, v) = json(&["connect", "--io", "cyclic", "--polls", "5"]);
    let io = &v["device"]["io"];
    assert!(
        io["interval_min_ms"].as_f64().unwrap() >= 95.0 && io["interval_max_ms"].as_f64().unwrap() <= 105.0,
        "{io}"
    );
}

#[test]
fn connect_io_with_acknowledge_suppression_and_settings() {
    let (code, out, err) = run(&[
        "connect",
        "--io",
        "cos",
        "--ack-suppression",
        "--inhibit",
        "20",
        "--epr",
        "200",
        "--polls",
        "3",
    ]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(
        out.contains("cos (acknowledge suppression) produced 18 / consumed 8 bytes, EPR 200 ms"),
        "{out}"
    );
    assert!(
        out.contains("consumed ID 0xFFFF; inhibit time 20 ms; 3 production(s), 0 acknowledged by the master"),
        "{out}"
    );
    assert!(!out.contains(" 42A "), "no acknowledgement under suppression:\n{out}");
    assert!(out.contains("00 4C 03 01 11"), "released without the 0x40 bit:\n{out}");
    let (code, v) =
        json(&["connect", "--io", "cyclic", "--ack-timer", "40", "--retry-limit", "3", "--polls", "2"]);
    assert_eq!(code, 0, "{v}");
    assert_eq!(
        (v["device"]["io"]["ack_timer_ms"].as_u64(), v["device"]["io"]["retry_limit"].as_u64()),
        (Some(40), Some(3))
    );
}

#[test]
fn connect_without_io_is_the_reference_bring_up() {
    let (code, v) = json(&["connect"]);
    assert_eq!(code, 0);
    // The 28 frames of the reference bring-up, then the Release of what it allocated.
    assert_eq!(v["frames"].as_array().unwrap().len(), 30);
    assert_eq!(v["frames"][16]["data"], "004B03010200");
    assert!(v["device"].get("io").is_none(), "{v}");
}

#[test]
fn monitor_io_takes_a_sample_per_production_or_strobe() {
    let (code, v) = json(&["monitor", "--io", "cyclic", "--count", "3"]);
    assert_eq!((code, &v["failures"]), (0, &Value::from(0)), "{v}");
    let samples = v["samples"].as_array().unwrap();
    assert_eq!(samples.len(), 3);
    assert!(samples.iter().all(|s| s["raw"].as_array().unwrap().len() == 18), "{v}");
    let t: Vec<u64> = samples.iter().map(|s| s["time_us"].as_u64().unwrap()).collect();
    assert!(t.windows(2).all(|w| (99_000..=101_000).contains(&(w[1] - w[0]))), "{t:?}");
    let (code, v) = json(&["monitor", "--io", "strobe", "--count", "2", "--epr", "50"]);
    assert_eq!((code, &v["failures"]), (0, &Value::from(0)), "{v}");
    assert!(v["samples"].as_array().unwrap().iter().all(|s| s["raw"].as_array().unwrap().len() == 8), "{v}");
    let (code, out, _) = run(&["monitor", "--io", "cos", "--count", "2"]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("switch open") && out.contains("2 samples"), "{out}");
}

#[test]
fn recover_brings_the_faulted_twin_to_a_new_mac() {
    let (code, out, err) = run(&["--slave-mac", "5,5", "recover", "--mac", "5", "--to", "9"]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("1 Communication Faulted node(s) answered"), "{out}");
    assert!(out.contains("long Identify answered; offline ownership answered"), "{out}");
    assert!(
        out.contains("Change MAC ID to 9: duplicate MAC ID requests at MAC 9 after 1 and 1001 ms"),
        "{out}"
    );
    assert!(
        out.contains("on-line at MAC 9: explicit connection allocated, serial number 0x12355678"),
        "{out}"
    );
    assert!(out.contains("every check holds"), "{out}");
    let (code, v) = json(&["--slave-mac", "5,5", "recover", "--mac", "5", "--to", "9"]);
    assert_eq!(code, 0, "{v}");
    let r = &v["recover"];
    assert_eq!((r["new_mac"].as_u64(), r["online"].as_bool()), (Some(9), Some(true)), "{v}");
    assert_eq!(r["found"][0]["serial_number"], 0x1235_5678);
    assert_eq!(r["dup_mac_requests_ms"].as_array().unwrap().len(), 2);
}

#[test]
fn recover_lists_without_a_new_mac_and_fails_clearly() {
    let (code, v) = json(&["--slave-mac", "5,5", "recover", "--mac", "5"]);
    assert_eq!(code, 0, "{v}");
    assert_eq!(v["recover"]["found"].as_array().unwrap().len(), 1);
    assert!(v["recover"]["new_mac"].is_null());
    // Nobody faulted: what was sent, and that nothing answered.
    let (code, _, err) = run(&["recover", "--mac", "5", "--to", "9", "--attempts", "2"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("Who (0x7ED 45 4B 03)")
            && err.contains("sent 2 time(s)")
            && err.contains("no node answered"),
        "{err}"
    );
    // The new MAC taken: the node faults again.
    let (code, _, err) = run(&["--slave-mac", "5,5,9", "recover", "--mac", "5", "--to", "9"]);
    assert_eq!(code, 1);
    assert!(err.contains("MAC 9 is taken") && err.contains("Communication Faulted again"), "{err}");
}

#[test]
fn bad_io_and_recover_options_are_usage_errors() {
    for (args, says) in [
        (
            &["connect", "--io", "strobe", "--ack-suppression"][..],
            "--ack-suppression applies to --io cos and --io cyclic",
        ),
        (&["connect", "--io", "multicast"][..], "expected poll, strobe, cos or cyclic"),
        (&["connect", "--io", "cos", "--ack-suppression", "--retry-limit", "2"][..], "turns off"),
        (&["connect", "--io", "strobe", "--output", "0201"][..], "no output data"),
        (&["monitor", "--io", "poll", "--inhibit", "5"][..], "--inhibit applies"),
        (&["recover", "--mac", "5", "--to", "0"][..], "master's own MAC"),
        (&["recover", "--mac", "5", "--delay-byte", "7"][..], "7"),
        (&["recover", "--mac", "64"][..], "out of range"),
    ] {
        let (code, out, err) = run(args);
        assert_eq!(code, 2, "{args:?}: {out}\n{err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
