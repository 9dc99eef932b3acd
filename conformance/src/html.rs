//! The HTML report (`--html FILE`): one self-contained page (no external resources) that reads as
//! a stand-alone test report an engineer can attach to a ticket. Its header gives the overall
//! verdict, the failed checks by name (linked to their sections), why the run ended early if it
//! did, the device's identity as read during the run, the date and time (UTC), the tool version,
//! the transport and its timestamp source, and both MACs. Then the verdict table and, for every
//! check, its expectations, measurements and a sequence diagram of its frames as inline SVG. The
//! bring-up of protocol §2 is the first check, so its 28 frames are the first diagram.
//!
//! The page cites the protocol clauses by name ([`clause_names`]: "Duplicate MAC ID check
//! (network access)"), never the section numbers of the project's notes, which mean nothing to a
//! reader outside this repository.
//!
//! ## The diagrams
//!
//! Three lifelines: the master, the device under test, and every other node. Each frame is an
//! arrow from its sender, labelled with identifier and data above and its DeviceNet meaning below,
//! coloured by its verdict. Time runs downwards: each arrow sits at its time on the wire (shown on
//! the left, from the start of the check); the gap between two frames is drawn in proportion up to
//! 100 ms, and longer gaps are cut and marked with their length, so a 1 s acknowledge timeout does
//! not stretch the page.

use super::{Category, CheckResult, Grade, Stopped, SuiteReport};
use can_io::bus::Origin;
use devicenet::{Identifier, Instant, MacId};
use master_core::decode::hex;
use master_core::session::{is_from_device, Record, Verdict};
use std::fmt::Write as _;

/// Frames drawn per diagram; the rest are listed as a count (all are in the JSON report).
pub const MAX_DRAWN: usize = 80;

const WIDTH: f64 = 1060.0;
const X_TIME: f64 = 12.0;
const X_MASTER: f64 = 190.0;
const X_DEVICE: f64 = 690.0;
const X_OTHERS: f64 = 990.0;
const TOP: f64 = 64.0;
const MIN_STEP: f64 = 34.0;
const PX_PER_MS: f64 = 0.6;
/// Gaps longer than this are cut.
const CUT_MS: f64 = 100.0;

/// Escapes text for HTML and SVG.
#[must_use]
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

fn grade_class(g: Grade) -> &'static str {
    match g {
        Grade::Pass => "pass",
        Grade::Advisory => "advisory",
        Grade::Fail => "fail",
    }
}

/// Where a frame goes: from which lifeline to which.
fn lanes(r: &Record, device: MacId) -> (f64, f64) {
    match r.origin {
        Origin::Local => {
            let to_device = match Identifier::decode(r.frame.id()) {
                Identifier::Group2 { mac, .. } => mac == device,
                Identifier::Group3 { .. } => {
                    r.frame.data().first().is_some_and(|b| b & 0x3F == device.as_raw())
                }
                _ => false,
            };
            (X_MASTER, if to_device { X_DEVICE } else { X_OTHERS })
        }
        Origin::Remote if is_from_device(&r.frame, device) => (X_DEVICE, X_MASTER),
        Origin::Remote => (X_OTHERS, X_MASTER),
    }
}

fn colour(v: &Verdict) -> (&'static str, &'static str) {
    match v {
        Verdict::Fail(_) => ("#c62828", "\u{2718}"),
        Verdict::Ok(_) => ("#2e7d32", "\u{2714}"),
        Verdict::Sent => ("#1f4e9c", ""),
        Verdict::Info(_) | Verdict::Unchecked => ("#888888", "\u{00B7}"),
    }
}

fn truncate(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        let mut t: String = s.chars().take(n.saturating_sub(1)).collect();
        t.push('\u{2026}');
        t
    }
}

/// The sequence diagram of `records` as an SVG element.
#[must_use]
pub fn diagram(records: &[Record], device: MacId) -> String {
    let drawn = &records[..records.len().min(MAX_DRAWN)];
    let start = drawn.first().map_or(Instant::ZERO, |r| r.at);
    // Marker ids unique in the page: several diagrams share one document.
    let marker = format!("ah{}", drawn.first().map_or(0, |r| r.index));
    // Rows: y of each frame, and the cut gaps (y, length in ms).
    let mut ys = Vec::with_capacity(drawn.len());
    let mut cuts = Vec::new();
    let mut y = TOP;
    let mut prev: Option<Instant> = None;
    for r in drawn {
        if let Some(p) = prev {
            let gap = (r.at - p).total_micros() as f64 / 1000.0;
            if gap > CUT_MS {
                cuts.push((y + MIN_STEP, gap));
                y += MIN_STEP * 2.0;
            } else {
                y += MIN_STEP.max(gap * PX_PER_MS + MIN_STEP * 0.6);
            }
        }
        ys.push(y);
        prev = Some(r.at);
    }
    let height = y + if records.len() > drawn.len() { 70.0 } else { 40.0 };
    let mut s = String::new();
    let _ = write!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" class="seq" width="{WIDTH}" height="{height:.0}" viewBox="0 0 {WIDTH} {height:.0}" role="img" aria-label="sequence diagram">"##
    );
    let _ = write!(s, "<style>{SVG_STYLE}</style>");
    s.push_str(
        &format!(r##"<defs><marker id="{marker}" viewBox="0 0 10 10" refX="9" refY="5" markerWidth="7" markerHeight="7" orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" fill="context-stroke"/></marker></defs>"##),
    );
    for (x, label) in [
        (X_MASTER, "master".to_string()),
        (X_DEVICE, format!("device (MAC {device})")),
        (X_OTHERS, "other nodes".to_string()),
    ] {
        let _ = write!(
            s,
            r##"<rect x="{:.0}" y="8" width="140" height="24" rx="4" class="head"/><text x="{x:.0}" y="25" text-anchor="middle" class="headt">{}</text><line x1="{x:.0}" y1="32" x2="{x:.0}" y2="{:.0}" class="life"/>"##,
            x - 70.0,
            escape(&label),
            height - 10.0
        );
    }
    let _ = write!(s, r##"<text x="{X_TIME}" y="50" class="axis">time from the check's start</text>"##);
    for (cy, gap) in &cuts {
        let _ = write!(
            s,
            r##"<line x1="{X_TIME}" y1="{cy:.0}" x2="{:.0}" y2="{cy:.0}" class="cut"/><text x="{:.0}" y="{:.0}" class="cutt">{:.3} s</text>"##,
            WIDTH - 10.0,
            (X_MASTER + X_DEVICE) / 2.0,
            cy - 3.0,
            gap / 1000.0
        );
    }
    for (r, &y) in drawn.iter().zip(&ys) {
        let (x1, x2) = lanes(r, device);
        let (stroke, mark) = colour(&r.verdict);
        let t = (r.at - start).total_micros() as f64 / 1e6;
        let label = format!("{:03X}  {}", r.frame.id().as_raw(), hex(r.frame.data()));
        let (lx, anchor) = ((x1 + x2) / 2.0, "middle");
        let title = match &r.verdict {
            Verdict::Fail(f) => format!("#{} FAIL: {}", r.index, f.join("; ")),
            Verdict::Ok(n) | Verdict::Info(n) => format!("#{} {}", r.index, n),
            Verdict::Sent | Verdict::Unchecked => format!("#{} sent", r.index),
        };
        let _ = write!(
            s,
            r##"<g><title>{}</title><text x="{X_TIME}" y="{:.0}" class="time">{t:.6} s  #{}</text><line x1="{x1:.0}" y1="{y:.0}" x2="{x2:.0}" y2="{y:.0}" stroke="{stroke}" class="arrow" marker-end="url(#{marker})"/><text x="{lx:.0}" y="{:.0}" text-anchor="{anchor}" class="frame">{}</text><text x="{lx:.0}" y="{:.0}" text-anchor="{anchor}" class="meaning">{}</text><text x="{:.0}" y="{:.0}" fill="{stroke}" class="mark">{mark}</text></g>"##,
            escape(&title),
            y + 4.0,
            r.index,
            y - 5.0,
            escape(&label),
            y + 13.0,
            escape(&truncate(&r.meaning, 105)),
            x2.max(x1) + 8.0,
            y + 5.0,
        );
    }
    if records.len() > drawn.len() {
        let _ = write!(
            s,
            r##"<text x="{:.0}" y="{:.0}" text-anchor="middle" class="more">… {} more frames, not drawn (every frame is in the JSON report and the --log file)</text>"##,
            (X_MASTER + X_DEVICE) / 2.0,
            height - 30.0,
            records.len() - drawn.len()
        );
    }
    s.push_str("</svg>");
    s
}

/// The diagrams' own style, inside each SVG so that a diagram copied out of the page still renders.
const SVG_STYLE: &str = r#".head{fill:#eef2fb;stroke:#6b7fb3} .headt{font:bold 12px sans-serif;fill:#223}
.life{stroke:#b8c0d8;stroke-dasharray:4 3} .arrow{stroke-width:1.6}
.frame{font:11px ui-monospace,Menlo,Consolas,monospace;fill:#111} .meaning{font:10px sans-serif;fill:#555}
.time{font:10px ui-monospace,Menlo,Consolas,monospace;fill:#777} .axis{font:italic 10px sans-serif;fill:#999}
.cut{stroke:#bbb;stroke-dasharray:2 4} .cutt{font:italic 10px sans-serif;fill:#999;text-anchor:middle}
.mark{font:bold 13px sans-serif} .more{font:italic 11px sans-serif;fill:#777}
"#;

pub(crate) const STYLE: &str = r#"
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em;color:#222;max-width:1200px}
h1{font-size:1.5em} h2{margin-top:2em;border-bottom:1px solid #ccc} h3{font-size:1.05em;margin-bottom:.3em}
table{border-collapse:collapse;margin:1em 0} td,th{border:1px solid #ddd;padding:3px 8px;text-align:left;font-size:.9em;vertical-align:top}
th{background:#f4f4f4} code,.mono{font-family:ui-monospace,Menlo,Consolas,monospace}
.grade{font-weight:bold;padding:1px 6px;border-radius:3px;color:#fff;font-size:.85em}
.pass{background:#2e7d32} .advisory{background:#ef8f00} .fail{background:#c62828}
li.fail-e{color:#c62828} li.advisory-e{color:#a15c00} li.pass-e{color:#2e7d32}
p.verdict{font-size:1.2em} p.stopped{color:#c62828} table.facts th{width:14em}
section.check{margin:1.5em 0 2.5em 0} .section{color:#666;font-size:.9em}
svg.seq{border:1px solid #eee;background:#fcfcfc;margin-top:.5em}
"#;

/// The name of the clause behind section `number` of the notes (`3.4`), if it has one.
fn clause_name(number: &str) -> Option<&'static str> {
    Some(match number {
        "1" | "1.1" | "1.2" | "1.3" => "Message groups and identifiers",
        "1.4" => "Group 3 and Group 4 messages (UCMM)",
        "2" => "Connection establishment (reference start-up sequence)",
        "3" | "3.1" => "Explicit message format",
        "3.2" => "Service codes",
        "3.3" => "Error response",
        "3.4" => "Predefined Master/Slave Connection Set: Allocate/Release",
        "3.5" => "Duplicate MAC ID check message",
        "3.6" => "UCMM open/close",
        "4" | "4.1" => "Explicit message fragmentation (acknowledged)",
        "4.2" => "I/O message fragmentation",
        "5" | "5.1" => "Connection object attributes",
        "5.2" => "Connection object states",
        "5.3" => "Expected packet rate",
        "5.4" => "Watchdog timeout action",
        "6.1" => "DeviceNet object",
        "6.2" => "Identity object",
        "3.7" => "Device heartbeat and shutdown",
        "3.8" => "Offline Connection Set (Group 4)",
        "7" | "7.1" => "Duplicate MAC ID check (network access)",
        "7.4" => "Communication Faulted node recovery",
        "II.0" => "Corrections and confirmations (Part II)",
        "II.2.4" => "Acknowledge Handler object",
        "II.2.5" => "Allocation combinations",
        n if n == "II.1" || n.starts_with("II.1.") => "Bit-strobe I/O",
        n if n == "II.2" || n.starts_with("II.2.") => "Change of state and cyclic I/O",
        n if n == "II.5" || n.starts_with("II.5.") => "Device heartbeat",
        n if n == "II.6" || n.starts_with("II.6.") => "Offline Connection Set and faulted-node recovery",
        "8" => "Group 2 only slave behaviour",
        n if n == "9" || n.starts_with("9.") => "Scanner practice (not fixed by the specification)",
        _ => return None,
    })
}

/// `text` with every citation of a notes section (`§3.4`, `protocol §9.6`) replaced by the name of
/// its clause.
#[must_use]
pub fn clause_names(text: &str) -> String {
    let text = text.replace("protocol §", "§");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(at) = rest.find('§') {
        out.push_str(&rest[..at]);
        let after = &rest[at + '§'.len_utf8()..];
        // Part II sections are cited `§II.2.4`.
        let (part, body) = match after.strip_prefix("II.") {
            Some(b) => ("II.", b),
            None => ("", after),
        };
        let len = body.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(body.len());
        let number = body[..len].trim_end_matches('.');
        match clause_name(&format!("{part}{number}")) {
            Some(name) => out.push_str(name),
            None => out.push_str("clause"),
        }
        rest = &body[number.len()..];
    }
    out.push_str(rest);
    out
}

fn check_section(s: &mut String, report: &SuiteReport, c: &CheckResult) {
    let cls = grade_class(c.grade);
    let _ = write!(
        s,
        r#"<section class="check" id="check-{id}"><h3><span class="grade {cls}">{}</span> <code>{id}</code> — {}</h3><div class="section">{} · {} frame(s)</div><ul>"#,
        c.grade.label(),
        escape(&clause_names(c.title)),
        escape(&clause_names(c.section)),
        c.frames.len(),
        id = c.id,
    );
    for e in &c.expectations {
        let basis = match e.basis {
            super::Basis::Normative => "",
            super::Basis::Unconfirmed => " <em>(rule not confirmed by public sources)</em>",
            super::Basis::Free => " <em>(a value the device or the scanner chooses)</em>",
        };
        let frame = e.frame.map_or_else(String::new, |f| format!(" <span class=\"mono\">#{f}</span>"));
        let _ = write!(
            s,
            r#"<li class="{}-e">{}: {}{}{}</li>"#,
            grade_class(e.grade),
            e.grade.label().to_lowercase(),
            escape(&clause_names(&e.text)),
            basis,
            frame
        );
    }
    s.push_str("</ul>");
    if !c.measurements.is_empty() {
        s.push_str("<table><tr><th>measured</th><th>value</th></tr>");
        for m in &c.measurements {
            let _ = write!(
                s,
                "<tr><td>{}</td><td class=\"mono\">{:.3} {}</td></tr>",
                escape(&m.name),
                m.value,
                m.unit
            );
        }
        s.push_str("</table>");
    }
    let frames = report.frames_of(c);
    if frames.is_empty() {
        s.push_str(
            "<p class=\"section\">No frames of its own: it judges frames of the checks before it.</p>",
        );
    } else {
        s.push_str(&diagram(frames, report.target));
    }
    s.push_str("</section>");
}

/// The page's header: verdict, failed checks, identity, run facts.
fn header(s: &mut String, report: &SuiteReport) {
    let failed: Vec<&CheckResult> = report.checks.iter().filter(|c| c.grade == Grade::Fail).collect();
    let (cls, verdict) = match (&report.stopped, failed.is_empty()) {
        (Some(Stopped::Interrupted(_)), _) => ("fail", "INTERRUPTED"),
        (Some(Stopped::NoDevice { .. }), _) => ("fail", "NO DEVICE"),
        (None, true) => ("pass", "PASS"),
        (None, false) => ("fail", "FAIL"),
    };
    let _ = write!(
        s,
        "<p class=\"verdict\"><span class=\"grade {cls}\">{verdict}</span> {} of {} checks run: {} pass, {} advisory, {} fail</p>",
        report.checks.len(),
        super::CHECKS,
        report.count(Grade::Pass),
        report.count(Grade::Advisory),
        report.count(Grade::Fail),
    );
    if let Some(stopped) = &report.stopped {
        let _ = write!(
            s,
            "<p class=\"stopped\"><strong>The run ended early: {}.</strong> Only the checks completed are reported.</p>",
            escape(&stopped.text())
        );
    }
    if failed.is_empty() {
        s.push_str("<p>Failed checks: none.</p>");
    } else {
        s.push_str("<p>Failed checks:</p><ul class=\"failed\">");
        for c in &failed {
            let _ = write!(
                s,
                "<li><a href=\"#check-{id}\"><code>{id}</code></a> — {}</li>",
                escape(&clause_names(c.title)),
                id = c.id
            );
        }
        s.push_str("</ul>");
    }
    s.push_str("<table class=\"facts\">");
    let mut row = |k: &str, v: &str| {
        let _ = write!(s, "<tr><th>{}</th><td>{}</td></tr>", escape(k), escape(v));
    };
    row("device MAC ID", &report.target.to_string());
    for (k, v) in report.identity.rows() {
        row(k, &v);
    }
    row(
        "master MAC ID",
        &format!("{} (second master used by the tests: {})", report.master, report.second_master),
    );
    row("date and time (UTC)", &report.started);
    row("tool", &format!("dnet-master {}", harness_common::version()));
    row("transport", &report.transport);
    row("timestamps", report.timestamps.description());
    row("bus time", &super::report::seconds(report.duration));
    row("frames", &report.records.len().to_string());
    row("at the end", &report.release);
    s.push_str("</table>");
    if let Some(why) = report.timestamps.timing_advisory() {
        let _ = write!(
            s,
            "<p class=\"section\">Timing is not judged on this transport ({}): timing expectations are advisory and their values only indicative.</p>",
            escape(why)
        );
    }
    for n in super::NOT_EXERCISED {
        let _ = write!(
            s,
            "<p class=\"section\">Not checked: {} ({}): {}.</p>",
            escape(&clause_names(n.section)),
            escape(n.rule),
            escape(n.why)
        );
    }
    s.push_str("<p class=\"section\">Grades: an expectation the specification states firmly fails the check when it does not hold; a deviation where the rule is not confirmed by public sources or the value is the device's or the scanner's own choice, a check that could not be exercised, and timing that the transport cannot show are advisory. The suite passes when no check fails.</p>");
}

/// The whole page.
#[must_use]
pub fn render(report: &SuiteReport) -> String {
    let mut s = String::new();
    let title = format!("DeviceNet conformance test report: MAC {} on {}", report.target, report.transport);
    let _ = write!(
        s,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{STYLE}</style></head><body><h1>{}</h1>",
        escape(&title),
        escape(&title)
    );
    header(&mut s, report);
    s.push_str("<h2>Verdicts</h2><table><tr><th>category</th><th>check</th><th>grade</th><th>what</th><th>clause</th><th>frames</th></tr>");
    for c in &report.checks {
        let _ = write!(
            s,
            "<tr><td>{}</td><td><a href=\"#check-{id}\"><code>{id}</code></a></td><td><span class=\"grade {}\">{}</span></td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(c.category.title()),
            grade_class(c.grade),
            c.grade.label(),
            escape(&clause_names(c.title)),
            escape(&clause_names(c.section)),
            c.frames.len(),
            id = c.id
        );
    }
    s.push_str("</table>");
    for cat in Category::ALL {
        let checks: Vec<&CheckResult> = report.checks.iter().filter(|c| c.category == cat).collect();
        if checks.is_empty() {
            continue;
        }
        let _ = write!(s, "<h2>{}</h2>", escape(cat.title()));
        for c in checks {
            check_section(&mut s, report, c);
        }
    }
    s.push_str("</body></html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escaping() {
        assert_eq!(escape("<a href=\"x\">&'"), "&lt;a href=&quot;x&quot;&gt;&amp;&#39;");
    }

    #[test]
    fn citations_become_clause_names() {
        assert_eq!(
            clause_names("§7.1 (1), §3.5"),
            "Duplicate MAC ID check (network access) (1), Duplicate MAC ID check message"
        );
        assert_eq!(
            clause_names("0x08/0x03 (protocol §9.6)"),
            "0x08/0x03 (Scanner practice (not fixed by the specification))"
        );
        assert_eq!(
            clause_names("§3.4 row 1."),
            "Predefined Master/Slave Connection Set: Allocate/Release row 1."
        );
        assert!(!clause_names("§2 frames 6-7, §6.2 attr 5").contains('§'));
        assert_eq!(
            clause_names("§II.1, §II.2.4, §7.4"),
            "Bit-strobe I/O, Acknowledge Handler object, Communication Faulted node recovery"
        );
    }

    #[test]
    fn truncation() {
        assert_eq!(truncate("abcdef", 4), "abc\u{2026}");
        assert_eq!(truncate("abc", 4), "abc");
    }

    #[test]
    fn empty_diagram_is_valid_svg() {
        let svg = diagram(&[], MacId::from_low_bits(5));
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
    }
}
