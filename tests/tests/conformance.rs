//! The conformance suite against the soft slave passes; every check fails against a mutant device
//! with the fault it tests (`conformance --self-test`).

use can_io::bus::Bitrate;
use can_io::sim::{PowerOn, SimBus};
use devicenet::MacId;
use dnet_conformance::mutants::{self, Mutant, MUTANTS};
use dnet_conformance::self_test::{self, SelfTestReport};
use dnet_conformance::{self as conformance, Category, Grade, Observer, Stopped, SuiteOptions, SuiteReport};
use harness_common::console::Console;
use master_core::master::MasterConfig;
use master_core::session::Session;
use master_harness::cli::{run, run_with};
use system_tests::{mac, sim_bus};

fn suite(bus: &mut can_io::sim::SimBus, target: MacId) -> SuiteReport {
    let mut session = Session::new(bus);
    conformance::run(&mut session, MasterConfig::default(), &SuiteOptions::new(target)).unwrap()
}

#[test]
fn the_soft_slave_passes() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let report = suite(&mut bus, mac(5));
    let mut text = Vec::new();
    conformance::write_text(&mut text, &report, false).unwrap();
    println!("{}", String::from_utf8_lossy(&text));
    assert_eq!(report.failed(), 0);
    assert_eq!(report.checks.len(), conformance::CHECKS);
    assert!(report.stopped.is_none());
    assert_eq!(report.checks[0].id, "bring-up");
    assert_eq!(report.checks[0].grade, Grade::Pass);
    assert_eq!(report.frames_of(&report.checks[0]).len(), 28, "the 28-frame bring-up first");
    // No advisory against the reference device.
    let advisory: Vec<&str> =
        report.checks.iter().filter(|c| c.grade == Grade::Advisory).map(|c| c.id).collect();
    assert!(advisory.is_empty(), "{advisory:?}");
    // Every row of §3.4 has its check, but row 11, which no master can provoke: the reports say so.
    for row in 1..=10 {
        let tag = format!("§3.4 row {row}");
        assert!(report.checks.iter().any(|c| c.section.contains(&tag)), "{tag}");
    }
    assert!(!report.checks.iter().any(|c| c.section.contains("§3.4 row 11")));
    assert_eq!(conformance::NOT_EXERCISED[0].section, "§3.4 row 11");
    assert!(String::from_utf8_lossy(&text).contains(
        "not checked: §3.4 row 11 (resources for the requested connections unavailable: 0x02/0x04)"
    ));
    assert_eq!(conformance::report_json(&report)["not_exercised"][0]["section"], "§3.4 row 11");
    assert!(conformance::html::render(&report)
        .contains("Not checked: Predefined Master/Slave Connection Set: Allocate/Release row 11"));
    // Every category ran.
    for cat in Category::ALL {
        assert!(report.checks.iter().any(|c| c.category == cat), "{cat:?}");
    }
}

#[test]
fn the_command_writes_text_json_and_html_and_exits_0() {
    let dir = std::env::temp_dir().join(format!("conformance-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let html = dir.join("report.html");
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let args = ["dnet-master", "--bus", "sim", "--json", "conformance", "--mac", "5", "--html"];
    let code = run(
        args.iter().map(|a| a.to_string()).chain([html.display().to_string()]),
        &mut out,
        &mut err,
        false,
    );
    assert_eq!(code, 0, "{}", String::from_utf8_lossy(&err));
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    assert_eq!(v["ok"], true);
    assert_eq!(v["summary"]["fail"], 0);
    assert_eq!(v["checks"][0]["id"], "bring-up");
    assert_eq!(v["checks"][0]["frames"].as_array().unwrap().len(), 28);
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.starts_with("<!DOCTYPE html>") && page.trim_end().ends_with("</html>"));
    assert!(!page.contains("<script") && !page.contains("<link"), "no external resources");
    let first_svg = &page[page.find("<svg").unwrap()..];
    let first_svg = &first_svg[..first_svg.find("</svg>").unwrap()];
    assert_eq!(first_svg.matches("class=\"arrow\"").count(), 28, "the bring-up as the first diagram");
    std::fs::remove_dir_all(&dir).unwrap();

    let (mut out, mut err) = (Vec::new(), Vec::new());
    assert_eq!(run(["dnet-master", "conformance", "--mac", "5"], &mut out, &mut err, false), 0);
    let text = String::from_utf8_lossy(&out);
    assert!(
        text.contains("Predefined Master/Slave Connection Set") && text.contains("result: no check failed"),
        "{text}"
    );
}

#[test]
fn no_device_stops_after_the_bring_up_and_exits_1() {
    let dir = temp_dir("absent");
    let log = dir.join("absent.log");
    let (mut out, mut err) = (Vec::new(), Vec::new());
    // Nobody at MAC 9: the soft slave sits at 5.
    let args = ["dnet-master", "--bus", "sim", "--slave-mac", "5", "conformance", "--mac", "9", "--log"];
    let code =
        run(args.iter().map(|a| a.to_string()).chain([log.display().to_string()]), &mut out, &mut err, false);
    let (out, err) = (String::from_utf8_lossy(&out), String::from_utf8_lossy(&err));
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(err.contains("error: no device answers at MAC 9"), "{err}");
    assert!(out.contains("FAIL      bring-up") && out.contains("1 of 52 checks run"), "{out}");
    assert!(!out.contains("dup-mac-answer"), "no other check ran:\n{out}");
    // The bring-up alone: the master's network access, the UCMM probes, the allocate.
    let frames = std::fs::read_to_string(&log).unwrap().lines().count();
    assert!((1..20).contains(&frames), "{frames} frames");

    // The same in the library: little bus time (the whole suite against nobody took 114 s).
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let report = suite(&mut bus, mac(9));
    assert_eq!(report.checks.len(), 1);
    assert!(matches!(&report.stopped, Some(Stopped::NoDevice { .. })), "{:?}", report.stopped);
    assert!(report.duration < devicenet::Duration::from_secs(10), "{}", report.duration);
    println!("absent device: stopped after {} of bus time", report.duration);

    // JSON: only the error document.
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let args = ["dnet-master", "--bus", "sim", "--slave-mac", "5", "--json", "conformance", "--mac", "9"];
    assert_eq!(run(args, &mut out, &mut err, false), 1);
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    assert_eq!(v["ok"], false);
    assert!(v["error"].as_str().unwrap().starts_with("no device answers at MAC 9"), "{v}");
    std::fs::remove_dir_all(&dir).unwrap();
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("conformance-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn an_unwritable_html_path_is_refused_before_any_frame() {
    let dir = temp_dir("unwritable");
    let log = dir.join("run.log");
    let html = dir.join("no-such-folder").join("report.html");
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let args = [
        "dnet-master",
        "--bus",
        "sim",
        "--log",
        &log.display().to_string(),
        "conformance",
        "--mac",
        "5",
        "--html",
        &html.display().to_string(),
    ]
    .map(str::to_string);
    let started = std::time::Instant::now();
    let code = run(args, &mut out, &mut err, false);
    let err = String::from_utf8_lossy(&err);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("cannot write") && err.contains("report.html"), "{err}");
    assert!(out.is_empty(), "nothing reported: {}", String::from_utf8_lossy(&out));
    let logged = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(logged.is_empty(), "no frame sent: {logged}");
    assert!(started.elapsed() < std::time::Duration::from_secs(5));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Records what an observer is told, in order.
#[derive(Default)]
struct Events {
    seen: Vec<String>,
    /// Asks `stop` for SIGINT once this many checks were judged.
    stop_after: Option<(usize, master_core::stop::Stop)>,
}

impl Observer for Events {
    fn start(&mut self, n: usize, id: &'static str, _title: &'static str) {
        self.seen.push(format!("start {n} {id}"));
    }
    fn judged(&mut self, check: &conformance::CheckResult, _frames: &[master_core::session::Record]) {
        self.seen.push(format!("judged {}", check.id));
        let judged = self.seen.iter().filter(|e| e.starts_with("judged")).count();
        if let Some((n, stop)) = &self.stop_after {
            if judged == *n {
                stop.request(master_core::stop::SIGINT);
            }
        }
    }
}

#[test]
fn each_verdict_is_reported_as_its_check_is_judged() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut events = Events::default();
    let report = conformance::run_observed(
        &mut session,
        MasterConfig::default(),
        &SuiteOptions::new(mac(5)),
        &mut events,
    )
    .unwrap();
    assert_eq!(report.checks.len(), conformance::CHECKS);
    // start, judged, start, judged, ...: each verdict before the next check starts.
    let expected: Vec<String> = report
        .checks
        .iter()
        .enumerate()
        .flat_map(|(k, c)| [format!("start {} {}", k + 1, c.id), format!("judged {}", c.id)])
        .collect();
    assert_eq!(events.seen, expected);

    // The command prints one verdict line per check, between its header and its summary.
    let (mut out, mut err) = (Vec::new(), Vec::new());
    assert_eq!(
        run(["dnet-master", "--bus", "sim", "conformance", "--mac", "5"], &mut out, &mut err, false),
        0
    );
    let text = String::from_utf8_lossy(&out);
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("dnet-master ") && lines[0].contains("transport sim"), "{text}");
    assert_eq!(lines[1], "timestamps: simulated bus clock, exact");
    let verdicts = lines
        .iter()
        .filter(|l| ["  PASS ", "  ADVISORY ", "  FAIL "].iter().any(|g| l.starts_with(g)))
        .count();
    assert_eq!(verdicts, conformance::CHECKS, "{text}");
    let summary = lines.iter().position(|l| l.starts_with("conformance of MAC 5")).unwrap();
    let last_verdict =
        lines.iter().rposition(|l| l.starts_with("  PASS ") || l.starts_with("  ADVISORY ")).unwrap();
    assert!(summary > last_verdict, "the summary at the end");
    assert!(text.contains("released through the Group 2 Only port"), "{text}");
}

#[test]
fn the_html_report_stands_alone_and_names_the_failed_check() {
    let mut bus = SimBus::new(Bitrate::K250);
    let device = mutants::find("does-not-defend-mac").unwrap().device(mac(5));
    bus.attach(Box::new(device), PowerOn::WhenMasterOnline);
    let report = suite(&mut bus, mac(5));
    let failed: Vec<&str> = report.checks.iter().filter(|c| c.grade == Grade::Fail).map(|c| c.id).collect();
    assert_eq!(failed, ["dup-mac-answer"]);
    let page = conformance::html::render(&report);
    let head = &page[..page.find("<h2>Verdicts").unwrap()];
    assert!(head.contains(">FAIL<"), "overall verdict in the header");
    assert!(head.contains("<a href=\"#check-dup-mac-answer\"><code>dup-mac-answer</code></a>"), "{head}");
    assert!(page.contains("id=\"check-dup-mac-answer\""), "the link's target");
    // Device identity as read, date, version, transport and timestamps, both MACs.
    for needle in [
        "vendor ID</th><td>4660 (0x1234)",
        "product name</th><td>Serial-DeviceNet Bridge",
        "serial number</th><td>0x12345678",
        "date and time (UTC)</th><td>20",
        harness_common::version(),
        "transport</th><td>sim",
        "simulated bus clock, exact",
        "master MAC ID</th><td>0",
        "device MAC ID</th><td>5",
        "Duplicate MAC ID check (network access)",
    ] {
        assert!(head.contains(needle) || page.contains(needle), "{needle} missing:\n{head}");
    }
    assert!(!page.contains("devicenet-notes") && !page.contains('§'), "no notes references in the page");
}

#[test]
fn a_stop_ends_the_run_with_the_checks_completed_and_releases_the_device() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let stop = master_core::stop::Stop::new();
    session.set_stop(stop.clone());
    let mut events = Events { stop_after: Some((8, stop)), ..Events::default() };
    let report = conformance::run_observed(
        &mut session,
        MasterConfig::default(),
        &SuiteOptions::new(mac(5)),
        &mut events,
    )
    .unwrap();
    assert_eq!(report.stopped, Some(Stopped::Interrupted(master_core::stop::SIGINT)));
    assert_eq!(report.checks.len(), 8);
    let last = report.checks.last().unwrap().frames.end;
    // After the last check: the releases through the Group 2 Only port (0x41E), answered.
    let after = &report.records[last..];
    assert!(
        after.iter().any(|r| r.frame.id().as_raw() == 0x42E && r.frame.data().get(1) == Some(&0x4C)),
        "{after:#?}"
    );
    let mut text = Vec::new();
    conformance::write_text(&mut text, &report, false).unwrap();
    let text = String::from_utf8(text).unwrap();
    assert!(text.contains("result: interrupted by SIGINT: 8 of 52 checks completed"), "{text}");
    let page = conformance::html::render(&report);
    assert!(page.contains("INTERRUPTED") && page.contains("interrupted by SIGINT"));
    assert_eq!(conformance::report_json(&report)["interrupted"], "SIGINT");
}

#[test]
fn sigint_during_the_command_exits_130_with_a_partial_report() {
    let dir = temp_dir("sigint");
    let html = dir.join("partial.html");
    let console = Console::plain();
    let stop = console.stop.clone();
    let asker = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_millis(2500));
        stop.request(master_core::stop::SIGINT);
    });
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let args = [
        "dnet-master",
        "--bus",
        "sim",
        "--realtime",
        "--json",
        "conformance",
        "--mac",
        "5",
        "--html",
        &html.display().to_string(),
    ]
    .map(str::to_string);
    let started = std::time::Instant::now();
    let code = run_with(args, &mut out, &mut err, &console);
    asker.join().unwrap();
    assert_eq!(code, 130, "{}", String::from_utf8_lossy(&err));
    assert!(started.elapsed() < std::time::Duration::from_secs(10), "stopped at once");
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    assert_eq!(v["ok"], false);
    assert_eq!(v["interrupted"], "SIGINT");
    assert_eq!(v["transport"], "sim");
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("interrupted by SIGINT"), "the HTML page is written");
    std::fs::remove_dir_all(&dir).unwrap();
}

// ----- every check can fail (conformance --self-test) -----------------------------------------

fn self_test() -> SelfTestReport {
    self_test::run(MasterConfig::default(), Bitrate::K250, &mut ()).unwrap()
}

#[test]
fn every_check_fails_against_a_mutant_and_every_mutant_is_caught_by_its_target() {
    let report = self_test();
    let mut text = Vec::new();
    self_test::write_text(&mut text, &report).unwrap();
    let text = String::from_utf8(text).unwrap();
    println!("{text}");
    assert!(report.reference_passed());
    assert_eq!(report.checks().len(), conformance::CHECKS);
    assert_eq!(report.mutants.len(), MUTANTS.len());
    assert!(report.uncaught_checks().is_empty(), "{:?}", report.uncaught_checks());
    assert!(report.surviving_mutants().is_empty(), "{:?}", report.surviving_mutants());
    assert!(report.passed());
    // Each mutant fails its target with a finding, and each target is a check of the suite.
    for m in &report.mutants {
        assert!(
            report.checks().contains(&m.mutant.target),
            "{}: unknown target {}",
            m.mutant.id,
            m.mutant.target
        );
        assert!(!m.evidence().is_empty(), "{}", m.mutant.id);
        assert!(m.run.stopped.is_none(), "{}: {:?}", m.mutant.id, m.run.stopped);
    }
    assert!(text.ends_with("result: every check can fail\n"), "{text}");
}

#[rstest::rstest]
#[case::ucmm("answers-ucmm", &["ucmm-silent"])]
#[case::second_dup_mac("skips-second-dup-mac", &["dup-mac-startup"])]
#[case::defence("does-not-defend-mac", &["dup-mac-answer"])]
#[case::any_master("serves-any-master", &["non-owner-ignored"])]
#[case::choice_zero("accepts-choice-zero", &["alloc-choice-zero"])]
#[case::group2_only("group2-only-no-additional-code", &["group2-only-invalid-service"])]
#[case::repeat("no-reack-of-repeat", &["duplicate-fragment"])]
#[case::gaa("short-attributes-all", &["identity-attributes"])]
#[case::watchdog("watchdog-3x-epr", &["watchdog-poll-timed-out", "watchdog-poll-auto-delete", "watchdog-explicit-auto-delete"])]
#[case::auto_reset("auto-reset-as-auto-delete", &["watchdog-poll-auto-reset"])]
#[case::idle("stops-after-idle-poll", &["idle-poll"])]
fn a_narrow_fault_fails_exactly_the_checks_that_test_it(#[case] id: &str, #[case] expected: &[&str]) {
    let mutant = mutants::find(id).unwrap();
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(mutant.device(mac(5))), PowerOn::WhenMasterOnline);
    let report = suite(&mut bus, mac(5));
    let failed: Vec<&str> = report.checks.iter().filter(|c| c.grade == Grade::Fail).map(|c| c.id).collect();
    assert_eq!(
        failed,
        expected,
        "{:#?}",
        report.checks.iter().filter(|c| c.grade == Grade::Fail).collect::<Vec<_>>()
    );
    assert!(report.stopped.is_none());
}

#[test]
fn the_self_test_fails_when_a_check_is_caught_by_no_mutant() {
    // With only two mutants, every check but theirs is caught by none.
    let some: Vec<&Mutant> =
        ["answers-ucmm", "does-not-defend-mac"].iter().map(|id| mutants::find(id).unwrap()).collect();
    let report = self_test::run_mutants(MasterConfig::default(), Bitrate::K250, &some, &mut ()).unwrap();
    assert!(report.reference_passed());
    assert!(!report.passed());
    let uncaught = report.uncaught_checks();
    assert!(
        uncaught.contains(&"duplicate-fragment") && uncaught.contains(&"out-of-sequence-fragment"),
        "{uncaught:?}"
    );
    assert!(!uncaught.contains(&"ucmm-silent") && !uncaught.contains(&"dup-mac-answer"));
    assert_eq!(uncaught.len(), conformance::CHECKS - 2);
    assert!(report.surviving_mutants().is_empty());
    let v = self_test::report_json(&report);
    assert_eq!(v["ok"], false);
    assert!(v["uncaught_checks"].as_array().unwrap().iter().any(|c| c == "duplicate-fragment"));
    let dup = v["checks"].as_array().unwrap().iter().find(|c| c["id"] == "duplicate-fragment").unwrap();
    assert_eq!(dup["caught_by"], serde_json::json!([]));
    let mut text = Vec::new();
    self_test::write_text(&mut text, &report).unwrap();
    let text = String::from_utf8(text).unwrap();
    assert!(text.contains("NOT CAUGHT duplicate-fragment"), "{text}");
    assert!(text.ends_with("result: FAILED\n"), "{text}");
}

#[test]
fn the_self_test_command_prints_the_matrix_and_its_json_lists_the_catchers_of_each_check() {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = run(["dnet-master", "--bus", "sim", "conformance", "--self-test"], &mut out, &mut err, false);
    let text = String::from_utf8_lossy(&out);
    assert_eq!(code, 0, "{text}{}", String::from_utf8_lossy(&err));
    assert!(text.contains("caught answers-ucmm"), "{text}");
    assert!(text.contains("self-test: 52 of 52 checks caught"), "{text}");

    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = run(["dnet-master", "--json", "conformance", "--self-test"], &mut out, &mut err, false);
    assert_eq!(code, 0, "{}", String::from_utf8_lossy(&err));
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    assert_eq!(v["ok"], true);
    assert_eq!(v["reference"]["passed"], true);
    let checks = v["checks"].as_array().unwrap();
    assert_eq!(checks.len(), conformance::CHECKS);
    let ucmm = checks.iter().find(|c| c["id"] == "ucmm-silent").unwrap();
    assert!(ucmm["caught_by"].as_array().unwrap().iter().any(|m| m == "answers-ucmm"), "{ucmm}");
    let m = v["mutants"].as_array().unwrap().iter().find(|m| m["id"] == "answers-ucmm").unwrap();
    assert_eq!(m["caught"], true);
    assert_eq!(m["target"], "ucmm-silent");
    assert!(m["evidence"][0].as_str().unwrap().contains("answered a UCMM open"), "{m}");

    // The HTML page: the matrix and every mutant's finding.
    let dir = temp_dir("self-test-html");
    let page = dir.join("self-test.html");
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let args = ["dnet-master", "conformance", "--self-test", "--html", page.to_str().unwrap()];
    assert_eq!(run(args, &mut out, &mut err, false), 0, "{}", String::from_utf8_lossy(&err));
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("PASS: every check can fail"), "{html}");
    assert!(html.contains("<th><code>ucmm-silent</code></th>"));
    assert!(html.contains("answered a UCMM open explicit connection request"));
    assert_eq!(html.matches("class=\"t\"").count(), MUTANTS.len(), "one target cell per mutant");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[rstest::rstest]
#[case::slcan(&["--bus", "slcan:/dev/null", "conformance", "--self-test"], "needs --bus sim")]
#[case::log(&["--log", "x.log", "conformance", "--self-test"], "--log has no meaning with --self-test")]
#[case::mac(&["conformance", "--self-test", "--mac", "7"], "cannot be used with")]
#[case::markdown_json(&["--json", "conformance", "--self-test", "--markdown"], "choose one")]
#[case::markdown_alone(&["conformance", "--markdown"], "--self-test")]
fn self_test_usage_errors_exit_2(#[case] args: &[&str], #[case] message: &str) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = run(std::iter::once("dnet-master").chain(args.iter().copied()), &mut out, &mut err, false);
    let err = String::from_utf8_lossy(&err);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(message), "{err}");
}

#[test]
fn the_guide_shows_the_current_matrix() {
    let page = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/src/test-engineer/conformance-self-test.md");
    let readme = std::fs::read_to_string(page).unwrap();
    let begin = "<!-- self-test matrix: begin (dnet-master conformance --self-test --markdown) -->\n";
    let end = "<!-- self-test matrix: end -->";
    let start = readme.find(begin).expect("the guide's self-test page has the matrix") + begin.len();
    let stop = readme[start..].find(end).expect("its end marker") + start;
    let shown = &readme[start..stop];
    let current = self_test::markdown(&self_test());
    assert!(
        shown == current,
        "the self-test matrix of docs/src/test-engineer/conformance-self-test.md is out of date: replace it with the output of\n  dnet-master conformance --self-test --markdown\n\n{current}"
    );
}
