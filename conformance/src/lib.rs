//! # dnet-conformance
//!
//! The conformance suite (`dnet-master conformance --mac N`): the checks a scanner and a
//! conformance lab apply to a group-2-only DeviceNet slave, run against any such device on any bus,
//! category by category, each citing the section of the guide's protocol reference it checks
//! (`docs/src/protocol/`, cited as protocol §N).
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
//! | Predefined Master/Slave Connection Set | every row of the validation table of §3.4 but row 11 ([`NOT_EXERCISED`]), allocation through the Group 2 Only port and through the explicit connection, ownership (DeviceNet attribute 5, Identity status bit 0), release and re-allocation; the combinations of §II.2.5, COS with cyclic refused, a release naming acknowledge suppression refused |
//! | explicit messaging | Identity (§6.2), DeviceNet (§6.1) and Connection (§5.1) attributes readable with the right sizes and values; Identity Get_Attributes_All whole attributes in order; settable vs not settable; unknown class, instance, attribute and service (§3.3); fragmented request and response; a missing acknowledgement, a duplicated fragment, an out-of-sequence fragment, an oversized request (§4.1) |
//! | connections | poll ignored before the EPR is set; EPR round trip; the inactivity watchdog measured against 4 × EPR for each timeout action; deferred delete; idle polls; I/O fragmentation of the poll response; requests from a master that does not own the device ignored (§4.2, §5, §8) |
//! | I/O connections (issue 14) | bit-strobe (§II.1), change of state acknowledged and suppressed, cyclic (§II.2), the Acknowledge Handler (§II.2.4), the device heartbeat (§II.5) |
//! | timing | poll response latency (min, median, 99th percentile) and explicit response latency, with the limit a scanner applies |
//! | Offline Connection Set | the device faulted by a duplicate MAC ID response (§7.1 rule 3), then Who, Identify, ownership and Change MAC ID (§7.4, §II.6); last, and "not run" (advisory) when the device does not fault |
//!
//! ## Timing and transports
//!
//! Timing expectations (the interval between the device's duplicate MAC ID requests, latencies,
//! watchdog expiry, the re-send of an unacknowledged fragment) are judged only where the
//! transport's timestamps show the device's timing ([`Timestamps`]): the simulated bus's clock and
//! SocketCAN's kernel timestamps. On SLCAN (`slcan:…`) frames are buffered on a serial line and
//! arrive in bursts, so those expectations are advisory with the reason ([`BUFFERED_TIMING`]).
//! Every report names the transport and its timestamp source.
//!
//! ## Ending early
//!
//! The run stops after the bring-up when the device sent nothing at all (no duplicate MAC ID
//! check, no answer to the Allocate through the Group 2 Only port): [`Stopped::NoDevice`], one
//! check reported, a few seconds of bus time instead of the whole suite's timeouts. A stop
//! requested on the session (SIGINT, SIGTERM) ends it with the checks completed so far
//! ([`Stopped::Interrupted`]). Either way, and at the normal end, what the suite allocated is
//! released unless [`SuiteOptions::keep`]. An [`Observer`] hears of each check as it starts and as
//! it is judged, which is how `dnet-master conformance` prints each verdict at once
//! ([`command`]).
//!
//! Every frame of every check is kept ([`SuiteReport::records`], each check's
//! [`CheckResult::frames`]) and judged like the rest of the harness's frames.
//!
//! ## Every check can fail
//!
//! [`self_test`] (`conformance --self-test`) runs the suite against the reference soft slave and
//! against each of the [`mutants`] (the reference device with one deliberate fault, as a hook
//! around the real node): the reference must pass, each mutant must fail its target check, and
//! every check must fail against at least one mutant. A rule no master can provoke is not a check
//! but a [`NOT_EXERCISED`] entry, named in every report.
//!
//! ## Running it
//!
//! ```
//! use can_io::bus::Bitrate;
//! use can_io::sim::{PowerOn, SimBus};
//! use dnet_conformance::{self as conformance, SuiteOptions};
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
pub use converter_sim::mutants;
pub mod report;
mod runner;
pub mod self_test;

use devicenet::{Duration, MacId};
use harness_common::error::HarnessError;
use master_core::error::MasterError;
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
    /// Bit-strobe, change of state, cyclic, the Acknowledge Handler, the heartbeat (issue 14).
    IoConnections,
    /// Response latencies.
    Timing,
    /// The Offline Connection Set: a Communication Faulted node recovered (last: it faults the
    /// device).
    OfflineSet,
}

impl Category {
    /// Every category, in order.
    pub const ALL: [Category; 7] = [
        Category::NetworkAccess,
        Category::ConnectionSet,
        Category::Explicit,
        Category::Connections,
        Category::IoConnections,
        Category::Timing,
        Category::OfflineSet,
    ];

    /// The heading shown in reports.
    #[must_use]
    pub fn title(self) -> &'static str {
        match self {
            Category::NetworkAccess => "Network access",
            Category::ConnectionSet => "Predefined Master/Slave Connection Set",
            Category::Explicit => "Explicit messaging",
            Category::Connections => "Connections",
            Category::IoConnections => "I/O connections, Acknowledge Handler, heartbeat",
            Category::Timing => "Timing",
            Category::OfflineSet => "Offline Connection Set",
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
    #[must_use]
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
    /// The bus in `--bus` form (`sim`, `socketcan:can0`, `slcan:/dev/ttyACM0@115200`): named in the
    /// reports, and it decides what the frames' times can show ([`Timestamps`]). `None`: the
    /// session's bus name.
    pub transport: Option<String>,
    /// Leave the device's connections allocated at the end (`--keep`); by default the suite
    /// releases them, after an interruption too.
    pub keep: bool,
}

impl SuiteOptions {
    /// The defaults for `target`: EPR 100 ms, 200 polls and 50 explicit requests timed, the
    /// session's bus, everything released at the end.
    #[must_use]
    pub fn new(target: MacId) -> SuiteOptions {
        SuiteOptions {
            target,
            epr_ms: 100,
            latency_polls: 200,
            latency_requests: 50,
            transport: None,
            keep: false,
        }
    }
}

/// Where the times of the recorded frames come from, which decides whether the suite can judge
/// timing (intervals between frames, latencies, watchdog expiry).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Timestamps {
    /// The simulated bus's own clock: exact.
    SimulatedClock,
    /// SocketCAN: the kernel's receive timestamps.
    Kernel,
    /// SLCAN: the host's receive time of lines buffered on a serial line; frames arrive in bursts,
    /// so timing is only advisory.
    HostBuffered,
}

/// Why timing expectations are advisory on a transport that buffers frames.
pub const BUFFERED_TIMING: &str =
    "SLCAN on a serial line: frames arrive in bursts, their arrival times do not show the device's timing";

impl Timestamps {
    /// The source of the timestamps of `transport` (in `--bus` form): `slcan:…` buffers,
    /// `socketcan:…` has kernel timestamps, anything else is the simulated bus.
    #[must_use]
    pub fn of_transport(transport: &str) -> Timestamps {
        if transport.starts_with("slcan") {
            Timestamps::HostBuffered
        } else if transport.starts_with("socketcan") {
            Timestamps::Kernel
        } else {
            Timestamps::SimulatedClock
        }
    }

    /// What the source is, in words.
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            Timestamps::SimulatedClock => "simulated bus clock, exact",
            Timestamps::Kernel => "kernel receive timestamps (SocketCAN)",
            Timestamps::HostBuffered => {
                "host receive time of buffered serial lines (SLCAN): timing checks advisory"
            }
        }
    }

    /// Why timing cannot be judged from these timestamps, if it cannot.
    #[must_use]
    pub fn timing_advisory(self) -> Option<&'static str> {
        match self {
            Timestamps::HostBuffered => Some(BUFFERED_TIMING),
            Timestamps::SimulatedClock | Timestamps::Kernel => None,
        }
    }
}

/// The device's identity as read during the run (Identity object instance 1, protocol §6.2); a
/// value the run did not read is `None` ("not read" in the reports).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct DeviceIdentity {
    /// Attribute 1.
    pub vendor_id: Option<u16>,
    /// Attribute 2.
    pub device_type: Option<u16>,
    /// Attribute 3.
    pub product_code: Option<u16>,
    /// Attribute 4: major, minor.
    pub revision: Option<(u8, u8)>,
    /// Attribute 6.
    pub serial_number: Option<u32>,
    /// Attribute 7.
    pub product_name: Option<String>,
}

impl DeviceIdentity {
    /// Takes attribute `attr` of Identity instance 1 from the value `data` read.
    pub(crate) fn note(&mut self, attr: u8, data: &[u8]) {
        match (attr, data) {
            (1, [a, b]) => self.vendor_id = Some(u16::from_le_bytes([*a, *b])),
            (2, [a, b]) => self.device_type = Some(u16::from_le_bytes([*a, *b])),
            (3, [a, b]) => self.product_code = Some(u16::from_le_bytes([*a, *b])),
            (4, [major, minor]) => self.revision = Some((*major, *minor)),
            (6, [a, b, c, d]) => self.serial_number = Some(u32::from_le_bytes([*a, *b, *c, *d])),
            (7, _) => {
                if let Some(name) = master_core::decode::short_string(data) {
                    self.product_name = Some(name.to_string());
                }
            }
            _ => {}
        }
    }

    /// `(label, value)` rows for the reports, "not read" where the run did not read it.
    #[must_use]
    pub fn rows(&self) -> Vec<(&'static str, String)> {
        let nr = || "not read".to_string();
        vec![
            ("vendor ID", self.vendor_id.map_or_else(nr, |v| format!("{v} (0x{v:04X})"))),
            ("device type", self.device_type.map_or_else(nr, |v| format!("{v} (0x{v:04X})"))),
            ("product code", self.product_code.map_or_else(nr, |v| format!("{v} (0x{v:04X})"))),
            ("revision", self.revision.map_or_else(nr, |(a, b)| format!("{a}.{b:03}"))),
            ("serial number", self.serial_number.map_or_else(nr, |v| format!("0x{v:08X}"))),
            ("product name", self.product_name.clone().unwrap_or_else(nr)),
        ]
    }
}

/// Why the suite ended before its last check.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Stopped {
    /// No device answers at the MAC: every other check would only time out.
    NoDevice {
        /// The MAC.
        mac: MacId,
        /// What was not seen.
        detail: String,
    },
    /// SIGINT or SIGTERM (the signal's number): the checks completed so far are reported.
    Interrupted(i32),
}

impl Stopped {
    /// The reason in words (`interrupted by SIGINT`, `no device answers at MAC 7: …`).
    #[must_use]
    pub fn text(&self) -> String {
        match self {
            Stopped::NoDevice { mac, detail } => format!("no device answers at MAC {mac}: {detail}"),
            Stopped::Interrupted(s) => format!("interrupted by {}", master_core::stop::signal_name(*s)),
        }
    }
}

/// Follows a run check by check: the command prints each verdict as it comes and shows progress.
/// Every method does nothing by default.
pub trait Observer {
    /// Check number `n` (from 1) of [`CHECKS`] starts.
    fn start(&mut self, _n: usize, _id: &'static str, _title: &'static str) {}
    /// The current check waits on the bus for a while (`what`: "waiting 4 x EPR …").
    fn wait(&mut self, _what: &str) {}
    /// A check was judged; `frames` are its records.
    fn judged(&mut self, _check: &CheckResult, _frames: &[Record]) {}
}

/// An observer that does nothing.
impl Observer for () {}

/// The number of checks in the suite.
pub const CHECKS: usize = 52;

/// A rule of the notes the suite does not check, and why: listed in every report, so a green
/// report never suggests it was checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct NotExercised {
    /// The section of the notes.
    pub section: &'static str,
    /// The rule.
    pub rule: &'static str,
    /// Why no master can check it.
    pub why: &'static str,
}

/// The rules the suite does not check. A check that can only ever pass is not a check: the
/// self-test ([`self_test`]) demands that every check fail against some mutant, so a rule no
/// master can provoke is listed here instead.
pub const NOT_EXERCISED: &[NotExercised] = &[NotExercised {
    section: "§3.4 row 11",
    rule: "resources for the requested connections unavailable: 0x02/0x04",
    why: "an internal limit of the device (GC/AN): no request from the bus provokes it",
}];

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
    /// The bus in `--bus` form.
    pub transport: String,
    /// Where the frames' times come from.
    pub timestamps: Timestamps,
    /// When the run started, UTC (`2025-01-31 14:05:09 UTC`).
    pub started: String,
    /// The device's identity as read during the run.
    pub identity: DeviceIdentity,
    /// Every check, in the order run.
    pub checks: Vec<CheckResult>,
    /// Why the run ended early, if it did.
    pub stopped: Option<Stopped>,
    /// What the suite released at the end, or kept (`--keep`).
    pub release: String,
    /// Every frame of the run.
    pub records: Vec<Record>,
    /// Bus time the suite took.
    pub duration: Duration,
}

impl SuiteReport {
    /// Checks with this grade.
    #[must_use]
    pub fn count(&self, grade: Grade) -> usize {
        self.checks.iter().filter(|c| c.grade == grade).count()
    }

    /// Checks that failed.
    #[must_use]
    pub fn failed(&self) -> usize {
        self.count(Grade::Fail)
    }

    /// The suite passed: it ran to its end and no check failed.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.stopped.is_none() && self.failed() == 0
    }

    /// The check named `id`.
    #[must_use]
    pub fn check(&self, id: &str) -> Option<&CheckResult> {
        self.checks.iter().find(|c| c.id == id)
    }

    /// The frames of `check`.
    #[must_use]
    pub fn frames_of(&self, check: &CheckResult) -> &[Record] {
        self.records.get(check.frames.clone()).unwrap_or(&[])
    }
}

/// The current time, UTC, as `2025-01-31 14:05:09 UTC`.
#[must_use]
pub fn utc_now() -> String {
    let t = time::OffsetDateTime::now_utc();
    format!(
        "{:04}-{:02}-{:02} {:02}:{:02}:{:02} UTC",
        t.year(),
        u8::from(t.month()),
        t.day(),
        t.hour(),
        t.minute(),
        t.second()
    )
}

/// Runs the whole suite against `opts.target` on `session`, as a master with `config`. See
/// [`run_observed`].
pub fn run(
    session: &mut Session<'_>,
    config: MasterConfig,
    opts: &SuiteOptions,
) -> Result<SuiteReport, HarnessError> {
    run_observed(session, config, opts, &mut ())
}

/// Runs the whole suite, telling `observer` about each check as it starts and as it is judged.
///
/// Only a failing bus ends it with an error: every other problem is a finding of the check it
/// happened in. It ends early, with the checks completed so far and [`SuiteReport::stopped`] set,
/// when no device answers at the MAC after the bring-up, and when the session's stop is requested
/// (SIGINT, SIGTERM). At the end (an early one too) it releases what it allocated through the
/// Group 2 Only port, unless [`SuiteOptions::keep`]; the session's stop watch is removed for that.
pub fn run_observed(
    session: &mut Session<'_>,
    config: MasterConfig,
    opts: &SuiteOptions,
    observer: &mut dyn Observer,
) -> Result<SuiteReport, HarnessError> {
    if opts.target == config.mac {
        return Err(HarnessError::DeviceIsMaster { mac: opts.target });
    }
    let master_mac = config.mac;
    let started = utc_now();
    let start = session.now();
    let bus = session.bus_name().to_string();
    let transport = opts.transport.clone().unwrap_or_else(|| bus.clone());
    let timestamps = Timestamps::of_transport(&transport);
    let (checks, second_master, identity, stopped, release) = {
        let mut runner = runner::Runner::new(session, config, opts.clone(), timestamps, observer);
        let stopped = match checks::run_all(&mut runner) {
            Ok(()) => None,
            Err(HarnessError::NoDevice { mac, detail }) => Some(Stopped::NoDevice { mac, detail }),
            Err(HarnessError::Master(MasterError::Interrupted { signal })) => {
                Some(Stopped::Interrupted(signal))
            }
            Err(e) => return Err(e),
        };
        let release = runner.finish(opts.keep, stopped.is_some())?;
        (runner.take_results(), runner.second_master(), runner.identity(), stopped, release)
    };
    let end = session.now();
    Ok(SuiteReport {
        target: opts.target,
        master: master_mac,
        second_master,
        bus,
        transport,
        timestamps,
        started,
        identity,
        checks,
        stopped,
        release,
        records: session.records().to_vec(),
        duration: end - start,
    })
}
