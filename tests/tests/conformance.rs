//! The conformance suite against the soft slave passes; deliberately broken devices fail the check
//! that names their fault.

use can_io::bus::Bitrate;
use can_io::sim::{PowerOn, SimBus, SimDevice};
use converter_sim::device::SoftSlave;
use devicenet::{CanFrame, Instant, MacId};
use master_core::master::MasterConfig;
use master_core::session::Session;
use master_harness::cli::run;
use master_harness::conformance::{self, Category, Grade, SuiteOptions, SuiteReport};
use std::collections::VecDeque;
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
    assert_eq!(report.checks[0].id, "bring-up");
    assert_eq!(report.checks[0].grade, Grade::Pass);
    assert_eq!(report.frames_of(&report.checks[0]).len(), 28, "the 28-frame bring-up first");
    // The one advisory: the §3.4 row no master can provoke.
    let advisory: Vec<&str> =
        report.checks.iter().filter(|c| c.grade == Grade::Advisory).map(|c| c.id).collect();
    assert_eq!(advisory, ["alloc-resource-unavailable"]);
    // Every row of §3.4 has its check.
    for row in 1..=11 {
        let tag = format!("§3.4 row {row}");
        assert!(report.checks.iter().any(|c| c.section.contains(&tag)), "{tag}");
    }
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
fn no_device_fails_and_exits_1() {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    // Nobody at MAC 9: the soft slave sits at 5.
    let code = run(["dnet-master", "conformance", "--mac", "9"], &mut out, &mut err, false);
    assert_eq!(code, 1, "{}", String::from_utf8_lossy(&out));
}

/// A soft slave with a fault of its own: incoming frames may be rewritten, outgoing ones dropped,
/// and extra frames answered.
struct Broken {
    inner: SoftSlave,
    /// Rewrites (or drops, `None`) each received frame.
    rx: fn(&CanFrame) -> Option<CanFrame>,
    /// Keeps (`true`) or drops each transmitted frame; gets the count of dup-MAC requests so far.
    tx: fn(&CanFrame, &mut u32) -> bool,
    /// Extra frames answered to a received one.
    answer: fn(&CanFrame) -> Option<CanFrame>,
    extra: VecDeque<CanFrame>,
    count: u32,
}

impl Broken {
    fn new(
        rx: fn(&CanFrame) -> Option<CanFrame>,
        tx: fn(&CanFrame, &mut u32) -> bool,
        answer: fn(&CanFrame) -> Option<CanFrame>,
    ) -> Broken {
        Broken { inner: SoftSlave::reference(mac(5)), rx, tx, answer, extra: VecDeque::new(), count: 0 }
    }
}

impl SimDevice for Broken {
    fn mac(&self) -> MacId {
        self.inner.mac()
    }
    fn power_on(&mut self, now: Instant) {
        self.inner.power_on(now);
    }
    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        if let Some(a) = (self.answer)(frame) {
            self.extra.push_back(a);
        }
        if let Some(f) = (self.rx)(frame) {
            self.inner.handle_frame(&f, now);
        }
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.inner.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<CanFrame> {
        if let Some(f) = self.extra.pop_front() {
            return Some(f);
        }
        loop {
            let f = self.inner.poll_transmit()?;
            if (self.tx)(&f, &mut self.count) {
                return Some(f);
            }
        }
    }
    fn poll_at(&self) -> Option<Instant> {
        self.inner.poll_at()
    }
}

fn keep_rx(f: &CanFrame) -> Option<CanFrame> {
    Some(*f)
}
fn keep_tx(_: &CanFrame, _: &mut u32) -> bool {
    true
}
fn no_answer(_: &CanFrame) -> Option<CanFrame> {
    None
}
fn is_dup_mac(f: &CanFrame) -> bool {
    f.id().as_raw() == 0x42F
}

fn failing(device: Broken) -> (Vec<&'static str>, SuiteReport) {
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(device), PowerOn::WhenMasterOnline);
    let report = suite(&mut bus, mac(5));
    let ids = report.checks.iter().filter(|c| c.grade == Grade::Fail).map(|c| c.id).collect();
    (ids, report)
}

#[test]
fn a_device_answering_ucmm_fails_ucmm_silent() {
    // Answers every UCMM request to it with an open response (0x745).
    let answer = |f: &CanFrame| {
        (f.id().as_raw() == 0x780 && f.data().first() == Some(&0x05))
            .then(|| CanFrame::from_raw(0x745, &[0x00, 0xCB, 0x00, 0x34, 0x05, 0x00]).unwrap())
    };
    let (failed, _) = failing(Broken::new(keep_rx, keep_tx, answer));
    assert_eq!(failed, ["ucmm-silent"]);
}

#[test]
fn a_device_skipping_its_second_duplicate_mac_request_fails_dup_mac_startup() {
    let tx = |f: &CanFrame, n: &mut u32| {
        if is_dup_mac(f) && f.data()[0] & 0x80 == 0 {
            *n += 1;
            return *n != 2;
        }
        true
    };
    let (failed, report) = failing(Broken::new(keep_rx, tx, no_answer));
    assert_eq!(failed, ["dup-mac-startup"], "{:#?}", report.check("dup-mac-startup"));
}

#[test]
fn a_device_not_defending_its_mac_fails_dup_mac_answer() {
    let tx = |f: &CanFrame, _: &mut u32| !(is_dup_mac(f) && f.data()[0] & 0x80 != 0);
    let (failed, _) = failing(Broken::new(keep_rx, tx, no_answer));
    assert_eq!(failed, ["dup-mac-answer"]);
}

#[test]
fn a_device_serving_any_master_fails_non_owner_ignored() {
    // Takes every explicit request as if it came from the owner (master MAC 0).
    let rx = |f: &CanFrame| {
        let mut data = f.data().to_vec();
        if f.id().as_raw() == 0x42C {
            if let Some(h) = data.first_mut() {
                *h &= 0xC0;
            }
        }
        CanFrame::from_raw(f.id().as_raw(), &data).ok()
    };
    let (failed, _) = failing(Broken::new(rx, keep_tx, no_answer));
    assert_eq!(failed, ["non-owner-ignored"]);
}
