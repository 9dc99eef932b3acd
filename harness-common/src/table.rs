//! The transcript as the user sees it: the frame-by-frame table and the one JSON form of a record,
//! shared by every command's output and the conformance reports.

use devicenet::MacId;
use master_core::decode;
use master_core::session::{Record, Verdict};
use serde::Serialize;
use std::io::Write;

/// One record as JSON (the `--json` output of every command and the conformance report).
#[derive(Serialize)]
pub struct RecordJson<'a> {
    index: usize,
    time_us: u64,
    direction: &'a str,
    id: String,
    data: String,
    meaning: &'a str,
    verdict: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    note: Option<&'a str>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    failures: Vec<&'a str>,
}

/// `r` in its JSON form; `device` decides its direction.
pub fn record_json<'a>(r: &'a Record, device: Option<MacId>) -> RecordJson<'a> {
    let (verdict, note, failures) = match &r.verdict {
        Verdict::Sent => ("sent", None, Vec::new()),
        Verdict::Ok(n) => ("ok", Some(n.as_str()), Vec::new()),
        Verdict::Fail(f) => ("fail", None, f.iter().map(String::as_str).collect()),
        Verdict::Info(n) => ("info", Some(n.as_str()), Vec::new()),
        Verdict::Unchecked => ("unchecked", None, Vec::new()),
    };
    RecordJson {
        index: r.index,
        time_us: r.at.total_micros(),
        direction: r.direction(device),
        id: format!("{:03X}", r.frame.id().as_raw()),
        data: decode::hex(r.frame.data()).replace(' ', ""),
        meaning: &r.meaning,
        verdict,
        note,
        failures,
    }
}

/// Prints the frame-by-frame table: index, time, direction, identifier, data, meaning, verdict.
pub fn print_table(out: &mut dyn Write, records: &[Record], device: Option<MacId>) -> std::io::Result<()> {
    writeln!(
        out,
        "{:>4}  {:>14}  {:<3}  {:<3}  {:<23}  {:<70}  verdict",
        "#", "time", "dir", "id", "data", "meaning"
    )?;
    for r in records {
        writeln!(
            out,
            "{:>4}  {:>14}  {:<3}  {:03X}  {:<23}  {:<70}  {}",
            r.index,
            r.at.to_string(),
            r.direction(device),
            r.frame.id().as_raw(),
            decode::hex(r.frame.data()),
            r.meaning,
            r.verdict.label()
        )?;
    }
    Ok(())
}
