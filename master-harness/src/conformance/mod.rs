//! The conformance suite (`dnet-master conformance --mac N`): the checks a scanner and a
//! conformance lab apply to a group-2-only DeviceNet slave, run against any such device on any bus,
//! category by category, each citing the section of `../shared/devicenet-notes.md` it checks.
//!
//! ## Grades
//!
//! Every check is a list of expectations, each with the firmness of its source in the notes
//! ([`Basis`]). A normative expectation that does not hold fails the check; one the notes mark
//! **UNCONFIRMED** or **FREE** (a value that is a device's or a master's own choice) only makes it
//! [`Grade::Advisory`]. The suite passes (exit status 0) when no check fails.
//!
//! ## The checks
//!
//! | category | checks |
//! |---|---|
//! | network access | the bring-up of §2 (the first diagram); the device's own duplicate MAC ID check (§7.1); it answers a duplicate MAC ID request for its MAC (§7.1 rule 3); it stays silent to UCMM (§3.4, §1.4); it ignores traffic to other MACs (§8) |
//! | Predefined Master/Slave Connection Set | every row of the validation table of §3.4, allocation through the Group 2 Only port and through the explicit connection, ownership (DeviceNet attribute 5, Identity status bit 0), release and re-allocation |
//! | explicit messaging | Identity (§6.2), DeviceNet (§6.1) and Connection (§5.1) attributes readable with the right sizes and values; settable vs not settable; unknown class, instance, attribute and service (§3.3); fragmented request and response; a missing acknowledgement, a duplicated fragment, an out-of-sequence fragment, an oversized request (§4.1) |
//! | connections | poll ignored before the EPR is set; EPR round trip; the inactivity watchdog measured against 4 × EPR for each timeout action; deferred delete; idle polls; I/O fragmentation of the poll response; requests from a master that does not own the device ignored (§4.2, §5, §8) |
//! | timing | poll response latency (min, median, 99th percentile) and explicit response latency, with the limit a scanner applies |
//!
//! Every frame of every check is kept ([`SuiteReport::records`], each check's
//! [`CheckResult::frames`]) and judged like the rest of the harness's frames.
//!
//! ## Running it
//!
//! ```
//! use can_io::bus::Bitrate;
//! use can_io::sim::{PowerOn, SimBus};
//! use master_harness::conformance::{self, SuiteOptions};
//! use master_core::master::MasterConfig;
//! use master_core::session::Session;
//! use converter_sim::device::SoftSlave;
//! use devicenet::MacId;
//!
//! let mut bus = SimBus::new(Bitrate::K250);
//! bus.attach(Box::new(SoftSlave::reference(MacId::new(5).unwrap())), PowerOn::WhenMasterOnline);
//! let mut session = Session::new(&mut bus);
//! let report = conformance::run(&mut session, MasterConfig::default(), &SuiteOptions::new(MacId::new(5).unwrap())).unwrap();
//! assert_eq!(report.failed(), 0);
//! ```

mod checks;
pub mod command;
pub mod html;
pub mod report;
mod runner;

use crate::error::HarnessError;
use devicenet::{Duration, MacId};
use master_core::master::MasterConfig;
use master_core::session::{Record, Session};
use serde::Serialize;
use std::ops::Range;

pub use report::{report_json, write_text};

/// The categories of the suite, in the order they run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Category {
    /// Duplicate MAC ID check, UCMM, traffic to other nodes.
    NetworkAccess,
    /// The Predefined Master/Slave Connection Set: allocation and release.
    ConnectionSet,
    /// Explicit messaging: objects, errors, fragmentation.
    Explicit,
    /// The explicit and poll connections: states, watchdogs, I/O.
    Connections,
    /// Response latencies.
    Timing,
}

impl Category {
    /// Every category, in order.
    pub const ALL: [Category; 5] = [
        Category::NetworkAccess,
        Category::ConnectionSet,
        Category::Explicit,
        Category::Connections,
        Category::Timing,
    ];

    /// The heading shown in reports.
    pub fn title(self) -> &'static str {
        match self {
            Category::NetworkAccess => "Network access",
            Category::ConnectionSet => "Predefined Master/Slave Connection Set",
            Category::Explicit => "Explicit messaging",
            Category::Connections => "Connections",
            Category::Timing => "Timing",
        }
    }
}

/// How firm the rule behind an expectation is in the notes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Basis {
    /// Stated by the notes' sources without reservation: a deviation fails.
    Normative,
    /// Marked **UNCONFIRMED** in the notes: a deviation is advisory.
    Unconfirmed,
    /// A **FREE** value (the device's or the master's choice): a deviation is advisory.
    Free,
}

/// The grade of an expectation or a check.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Grade {
    /// As required.
    Pass,
    /// Deviates where the notes are not firm, or could not be exercised; worth a look.
    Advisory,
    /// Deviates from a firm rule.
    Fail,
}

impl Grade {
    /// `PASS`, `ADVISORY`, `FAIL`.
    pub fn label(self) -> &'static str {
        match self {
            Grade::Pass => "PASS",
            Grade::Advisory => "ADVISORY",
            Grade::Fail => "FAIL",
        }
    }
}

/// One expectation of a check and how it came out.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Expectation {
    /// What was expected and what was seen.
    pub text: String,
    /// Its grade.
    pub grade: Grade,
    /// The firmness of its rule.
    pub basis: Basis,
    /// The record (index into [`SuiteReport::records`]) that shows it, if one does.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame: Option<usize>,
}

/// A measured value (timing, counts).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Measurement {
    /// What it is.
    pub name: String,
    /// Its value.
    pub value: f64,
    /// Its unit (`ms`, `frames`, …).
    pub unit: &'static str,
}

/// The outcome of one check.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckResult {
    /// Short stable name (`dup-mac-answer`).
    pub id: &'static str,
    /// What is checked.
    pub title: &'static str,
    /// Its category.
    pub category: Category,
    /// The sections of the notes it checks (`§3.4 row 1`).
    pub section: &'static str,
    /// The worst grade of its expectations.
    pub grade: Grade,
    /// Its expectations, in the order they were checked.
    pub expectations: Vec<Expectation>,
    /// Values measured.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub measurements: Vec<Measurement>,
    /// Its frames: a range of [`SuiteReport::records`].
    #[serde(skip)]
    pub frames: Range<usize>,
}

impl CheckResult {
    /// The expectations that did not pass.
    pub fn findings(&self) -> impl Iterator<Item = &Expectation> {
        self.expectations.iter().filter(|e| e.grade != Grade::Pass)
    }
}

/// What the suite runs against and how.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SuiteOptions {
    /// The device under test.
    pub target: MacId,
    /// Expected packet rate for the poll connection in the bring-up and the connection checks, ms.
    pub epr_ms: u16,
    /// Poll cycles measured for the poll latency.
    pub latency_polls: u32,
    /// Explicit requests measured for the explicit latency.
    pub latency_requests: u32,
}

impl SuiteOptions {
    /// The defaults for `target`: EPR 100 ms, 200 polls and 50 explicit requests timed.
    pub fn new(target: MacId) -> SuiteOptions {
        SuiteOptions { target, epr_ms: 100, latency_polls: 200, latency_requests: 50 }
    }
}

/// The whole suite's outcome.
#[derive(Clone, Debug)]
pub struct SuiteReport {
    /// The device under test.
    pub target: MacId,
    /// The master's MAC ID.
    pub master: MacId,
    /// The MAC the suite used as a second master (conflicts, non-owner requests).
    pub second_master: MacId,
    /// The bus interface name.
    pub bus: String,
    /// Every check, in the order run.
    pub checks: Vec<CheckResult>,
    /// Every frame of the run.
    pub records: Vec<Record>,
    /// Bus time the suite took.
    pub duration: Duration,
}

impl SuiteReport {
    /// Checks with this grade.
    pub fn count(&self, grade: Grade) -> usize {
        self.checks.iter().filter(|c| c.grade == grade).count()
    }

    /// Checks that failed.
    pub fn failed(&self) -> usize {
        self.count(Grade::Fail)
    }

    /// The check named `id`.
    pub fn check(&self, id: &str) -> Option<&CheckResult> {
        self.checks.iter().find(|c| c.id == id)
    }

    /// The frames of `check`.
    pub fn frames_of(&self, check: &CheckResult) -> &[Record] {
        self.records.get(check.frames.clone()).unwrap_or(&[])
    }
}

/// Runs the whole suite against `opts.target` on `session`, as a master with `config`. Only a
/// failing bus stops it: every other problem is a finding of the check it happened in.
pub fn run(
    session: &mut Session<'_>,
    config: MasterConfig,
    opts: &SuiteOptions,
) -> Result<SuiteReport, HarnessError> {
    if opts.target == config.mac {
        return Err(HarnessError::Usage(format!("the device's MAC {} is the master's own MAC", opts.target)));
    }
    let master_mac = config.mac;
    let start = session.now();
    let bus = session.bus_name().to_string();
    let (checks, second_master) = {
        let mut runner = runner::Runner::new(session, config, opts.clone());
        checks::run_all(&mut runner)?;
        (runner.take_results(), runner.second_master())
    };
    let end = session.now();
    Ok(SuiteReport {
        target: opts.target,
        master: master_mac,
        second_master,
        bus,
        checks,
        records: session.records().to_vec(),
        duration: end - start,
    })
}
