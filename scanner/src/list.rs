//! The scan list file (TOML): read with errors naming the file, line, column and key; written
//! back in the same form.
//!
//! ```toml
//! # interscan_delay_ms = 5           # optional: computed from the list and the data rate
//! # expected_packet_rate_ms = 100    # optional: computed; every node's EPR
//!
//! [[node]]
//! mac = 5
//! connection = "poll"                # poll (default), strobe, cos or cyclic
//! vendor_id = 0x1234                 # electronic key: each optional
//! device_type = 0x000C
//! product_code = 1
//! major_revision = 1
//! # minor_revision = 1               # optional; keying "compatible": this minor revision or later
//! input_size = 18                    # poll response (Connection 2 attribute 7)
//! output_size = 8                    # poll command (Connection 2 attribute 8)
//! name = "breaker feeder 1"          # optional
//! adr = "config+address"             # optional: off (default), config, config+address (crate::adr)
//! keying = "compatible"              # optional: exact (default), compatible, disabled
//! enabled = false                    # optional: kept in the list, not scanned (maintenance)
//!
//! [[node]]
//! mac = 6
//! connection = "strobe"
//! input_size = 8                     # strobe response (Connection 3 attribute 7), at most 8
//! output_size = 0                    # always 0: the output is the node's bit of the strobe
//!
//! [[node]]
//! mac = 7
//! connection = "cos"
//! input_size = 18                    # production (Connection 4 attribute 7)
//! output_size = 8                    # the scanner's COS data (Connection 2 attribute 8)
//! inhibit_ms = 20                    # optional, COS only: production inhibit time (attribute 17)
//!
//! [[node]]
//! mac = 8
//! connection = "cyclic"
//! ack_suppression = true             # optional, COS and cyclic: nothing is acknowledged
//! input_size = 18
//! output_size = 8
//! ```
//!
//! A strobed node's input is its strobe response, never fragmented (protocol §II.1.3): more than 8
//! bytes is refused. Its output is one bit, byte `MAC / 8` bit `MAC % 8` of the scanner's strobe
//! command, as Rockwell's scanners map it (1 bit per node); no output assembly is consumed
//! (the EDS's `StrobeInfo` names no output), so `output_size` is 0, and the node's output image in
//! the scanner is 1 byte whose bit 0 is that bit.

use crate::model::{Keying, ScanEntry, ScanList};
use harness_common::error::HarnessError;
use master_core::master::io::IoKind;
use serde::Deserialize;
use std::ops::Range;

/// The largest I/O message the scanner reassembles (64 fragments of 7 bytes, protocol §4.2).
pub const MAX_IO_SIZE: u16 = master_core::decode::MAX_IO_MESSAGE as u16;

/// Line and column (1-based) of byte `at` in `text`.
fn line_col(text: &str, at: usize) -> (usize, usize) {
    let at = at.min(text.len());
    let before = text.get(..at).unwrap_or("");
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// The key written before `=` on the line holding byte `at`, if any.
fn key_at(text: &str, at: usize) -> Option<String> {
    let at = at.min(text.len());
    let start = text.get(..at)?.rfind('\n').map_or(0, |i| i + 1);
    let line = text.get(start..)?.lines().next()?;
    let (key, _) = line.split_once('=')?;
    let key = key.trim();
    (!key.is_empty() && !key.starts_with('#')).then(|| key.trim_matches('"').to_string())
}

fn located(
    text: &str,
    file: &str,
    span: Option<Range<usize>>,
    key: Option<String>,
    msg: &str,
) -> HarnessError {
    let (line, col) = span.as_ref().map_or((0, 0), |s| line_col(text, s.start));
    // An unknown key names itself (also a table header, `[node.keying]`, where no `=` is).
    let unknown = || msg.strip_prefix("unknown field `")?.split('`').next().map(str::to_string);
    let key = key.or_else(unknown).or_else(|| span.as_ref().and_then(|s| key_at(text, s.start)));
    HarnessError::ScanList { file: file.to_string(), line, column: col, key, message: msg.to_string() }
}

#[derive(Deserialize)]
struct SpannedNode {
    mac: Option<toml::Spanned<toml::Value>>,
    input_size: Option<toml::Spanned<toml::Value>>,
    output_size: Option<toml::Spanned<toml::Value>>,
    connection: Option<toml::Spanned<toml::Value>>,
    ack_suppression: Option<toml::Spanned<toml::Value>>,
    inhibit_ms: Option<toml::Spanned<toml::Value>>,
}

/// Where a node's value is written (`None`: not written).
type SpanOf = fn(&SpannedNode) -> Option<Range<usize>>;

#[derive(Deserialize)]
struct SpannedList {
    #[serde(default)]
    node: Vec<toml::Spanned<SpannedNode>>,
}

/// Reads the scan list file at `path` for a scanner at MAC `scanner_mac`
/// ([`parse_scan_list_for`]); a file that cannot be read is a usage error naming it.
pub fn read_scan_list(path: &std::path::Path, scanner_mac: u8) -> Result<ScanList, HarnessError> {
    let text = std::fs::read_to_string(path).map_err(|error| HarnessError::Read {
        path: path.display().to_string(),
        what: "scan list",
        error,
    })?;
    parse_scan_list_for(&text, &path.display().to_string(), Some(scanner_mac))
}

/// Reads a scan list from `text` (`file` names it in errors). Every error is a usage error naming
/// the file, line, column and key: TOML syntax, an unknown key, a value of the wrong type, a MAC
/// above 63 or given twice, a size above 448 bytes, a connection type other than `poll`,
/// `strobe`, `cos` or `cyclic`, a strobe input above 8 bytes or a strobe output that is not 0,
/// `ack_suppression` other than for COS or cyclic, `inhibit_ms` other than for COS, a list without
/// a node.
pub fn parse_scan_list(text: &str, file: &str) -> Result<ScanList, HarnessError> {
    parse_scan_list_for(text, file, None)
}

/// [`parse_scan_list`] for a scanner at MAC `scanner_mac`: a node at that MAC is refused too (the
/// scanner cannot scan itself).
pub fn parse_scan_list_for(
    text: &str,
    file: &str,
    scanner_mac: Option<u8>,
) -> Result<ScanList, HarnessError> {
    let list: ScanList =
        toml::from_str(text).map_err(|e| located(text, file, e.span(), None, e.message().trim()))?;
    // The same text again, keeping where each value is, for the checks below.
    let spans: Option<SpannedList> = toml::from_str(text).ok();
    let span_of = |i: usize, pick: fn(&SpannedNode) -> Option<Range<usize>>| -> Option<Range<usize>> {
        let n = spans.as_ref()?.node.get(i)?;
        pick(n.get_ref()).or_else(|| Some(n.span()))
    };
    if list.nodes.is_empty() {
        return Err(located(text, file, None, None, "no [[node]]: nothing to scan"));
    }
    let mut seen: Vec<(u8, usize)> = Vec::new();
    for (i, node) in list.nodes.iter().enumerate() {
        let mac_span = span_of(i, |n| n.mac.as_ref().map(|v| v.span()));
        if node.mac > 63 {
            return Err(located(
                text,
                file,
                mac_span,
                Some("mac".into()),
                &format!("MAC {} is out of range 0..=63", node.mac),
            ));
        }
        if let Some((_, first)) = seen.iter().find(|(m, _)| *m == node.mac) {
            let first_line = span_of(*first, |n| n.mac.as_ref().map(|v| v.span()))
                .map_or(0, |s| line_col(text, s.start).0);
            return Err(located(
                text,
                file,
                mac_span,
                Some("mac".into()),
                &format!("MAC {} is given twice (first at line {first_line})", node.mac),
            ));
        }
        if scanner_mac == Some(node.mac) {
            return Err(located(
                text,
                file,
                mac_span,
                Some("mac".into()),
                &format!(
                    "MAC {} is the scanner's own (--master-mac {}): give the node or the scanner another MAC",
                    node.mac, node.mac
                ),
            ));
        }
        seen.push((node.mac, i));
        for (key, value, pick) in [
            (
                "input_size",
                node.input_size,
                (|n: &SpannedNode| n.input_size.as_ref().map(|v| v.span()))
                    as fn(&SpannedNode) -> Option<Range<usize>>,
            ),
            ("output_size", node.output_size, |n: &SpannedNode| n.output_size.as_ref().map(|v| v.span())),
        ] {
            if value > MAX_IO_SIZE {
                return Err(located(
                    text,
                    file,
                    span_of(i, pick),
                    Some(key.into()),
                    &format!(
                        "{value} bytes: an I/O message has at most {MAX_IO_SIZE} bytes (64 fragments of 7)"
                    ),
                ));
            }
        }
        let Some(kind) = IoKind::ALL.into_iter().find(|k| k.name() == node.connection) else {
            return Err(located(
                text,
                file,
                span_of(i, |n| n.connection.as_ref().map(|v| v.span())),
                Some("connection".into()),
                &format!("connection type '{}': expected poll, strobe, cos or cyclic", node.connection),
            ));
        };
        let refusal: Option<(&str, SpanOf, String)> = match kind {
            IoKind::Strobe if node.input_size > 8 => Some((
                "input_size",
                |n| n.input_size.as_ref().map(|v| v.span()),
                format!(
                    "{} bytes: a strobe response carries at most 8 bytes, never fragmented (protocol §II.1.3); poll the node, or use cos or cyclic",
                    node.input_size
                ),
            )),
            IoKind::Strobe if node.output_size != 0 => Some((
                "output_size",
                |n| n.output_size.as_ref().map(|v| v.span()),
                format!(
                    "output_size {}: a strobed node's output is its bit of the strobe command, not an output assembly: output_size = 0",
                    node.output_size
                ),
            )),
            _ if node.ack_suppression && !kind.is_cos_cyclic() => Some((
                "ack_suppression",
                |n| n.ack_suppression.as_ref().map(|v| v.span()),
                format!("acknowledge suppression applies to cos and cyclic, not to {kind}"),
            )),
            _ if node.inhibit_ms.is_some() && kind != IoKind::ChangeOfState => Some((
                "inhibit_ms",
                |n| n.inhibit_ms.as_ref().map(|v| v.span()),
                format!("the production inhibit time applies to cos, not to {kind}"),
            )),
            _ => None,
        };
        if let Some((key, pick, msg)) = refusal {
            return Err(located(text, file, span_of(i, pick), Some(key.into()), &msg));
        }
    }
    let mut list = list;
    list.nodes.sort_by_key(|n| n.mac);
    Ok(list)
}

/// The scan list as TOML, in the form [`parse_scan_list`] reads (`parse(write(l)) == l`).
#[must_use]
pub fn write_scan_list(list: &ScanList) -> String {
    let mut out = String::from("# DeviceNet scan list (dnet-master scanner --scanlist FILE)\n");
    if let Some(d) = list.interscan_delay_ms {
        out.push_str(&format!("interscan_delay_ms = {d}\n"));
    }
    if let Some(e) = list.expected_packet_rate_ms {
        out.push_str(&format!("expected_packet_rate_ms = {e}\n"));
    }
    for n in &list.nodes {
        out.push_str(&entry_toml(n));
    }
    out
}

fn entry_toml(n: &ScanEntry) -> String {
    let mut s = format!("\n[[node]]\nmac = {}\nconnection = {}\n", n.mac, toml_string(&n.connection));
    if n.ack_suppression {
        s.push_str("ack_suppression = true\n");
    }
    if let Some(v) = n.inhibit_ms {
        s.push_str(&format!("inhibit_ms = {v}\n"));
    }
    if let Some(v) = n.vendor_id {
        s.push_str(&format!("vendor_id = 0x{v:04X}\n"));
    }
    if let Some(v) = n.device_type {
        s.push_str(&format!("device_type = 0x{v:04X}\n"));
    }
    if let Some(v) = n.product_code {
        s.push_str(&format!("product_code = {v}\n"));
    }
    if let Some(v) = n.major_revision {
        s.push_str(&format!("major_revision = {v}\n"));
    }
    if let Some(v) = n.minor_revision {
        s.push_str(&format!("minor_revision = {v}\n"));
    }
    s.push_str(&format!("input_size = {}\noutput_size = {}\n", n.input_size, n.output_size));
    if let Some(name) = &n.name {
        s.push_str(&format!("name = {}\n", toml_string(name)));
    }
    if !n.adr.is_off() {
        s.push_str(&format!("adr = \"{}\"\n", n.adr.name()));
    }
    match n.keying {
        Keying::Exact => {}
        Keying::Compatible => s.push_str("keying = \"compatible\"\n"),
        Keying::Disabled => s.push_str("keying = \"disabled\"\n"),
    }
    if !n.enabled {
        s.push_str("enabled = false\n");
    }
    s
}

/// A TOML basic string.
fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    const GOOD: &str = "[[node]]\nmac = 5\nvendor_id = 0x1234\nproduct_code = 1\ninput_size = 18\noutput_size = 8\nname = \"breaker \\\"A\\\"\"\n\n[[node]]\nmac = 3\ninput_size = 2\noutput_size = 0\n\n[[node]]\nmac = 9\nconnection = \"strobe\"\ninput_size = 8\noutput_size = 0\n\n[[node]]\nmac = 10\nconnection = \"cos\"\ninhibit_ms = 20\ninput_size = 18\noutput_size = 8\n\n[[node]]\nmac = 11\nconnection = \"cyclic\"\nack_suppression = true\ninput_size = 18\noutput_size = 8\n";

    #[test]
    fn reads_sorts_and_round_trips() {
        let list = parse_scan_list(GOOD, "l.toml").unwrap();
        assert_eq!(list.nodes.iter().map(|n| n.mac).collect::<Vec<_>>(), vec![3, 5, 9, 10, 11]);
        assert_eq!(list.nodes[1].vendor_id, Some(0x1234));
        assert_eq!(list.nodes[1].connection, "poll");
        let kinds: Vec<IoKind> = list.nodes.iter().map(ScanEntry::io_kind).collect();
        assert_eq!(
            kinds,
            [IoKind::Poll, IoKind::Poll, IoKind::Strobe, IoKind::ChangeOfState, IoKind::Cyclic]
        );
        assert_eq!((list.nodes[3].inhibit_ms, list.nodes[3].ack_suppression), (Some(20), false));
        assert_eq!((list.nodes[4].inhibit_ms, list.nodes[4].ack_suppression), (None, true));
        let again = parse_scan_list(&write_scan_list(&list), "w.toml").unwrap();
        assert_eq!(again, list);
        // ADR, keying and maintenance round-trip too.
        let mut edited = list.clone();
        edited.nodes[0].adr = crate::model::AdrMode::ConfigAddress;
        edited.nodes[1].adr = crate::model::AdrMode::Config;
        edited.nodes[1].keying = Keying::Compatible;
        edited.nodes[2].keying = Keying::Disabled;
        edited.nodes[3].enabled = false;
        let text = write_scan_list(&edited);
        assert!(text.contains("adr = \"config+address\"") && text.contains("enabled = false"), "{text}");
        assert_eq!(parse_scan_list(&text, "w.toml").unwrap(), edited);
    }

    #[rstest]
    #[case::mac_range(
        "[[node]]\nmac = 64\ninput_size = 1\noutput_size = 1\n",
        "l.toml:2:7: scan list (key `mac`): MAC 64 is out of range"
    )]
    #[case::mac_not_u8(
        "[[node]]\nmac = 300\ninput_size = 1\noutput_size = 1\n",
        "l.toml:2:7: scan list (key `mac`)"
    )]
    #[case::duplicate("[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n", "l.toml:6:7: scan list (key `mac`): MAC 5 is given twice (first at line 2)")]
    #[case::too_big(
        "[[node]]\nmac = 5\ninput_size = 449\noutput_size = 1\n",
        "l.toml:3:14: scan list (key `input_size`): 449 bytes"
    )]
    #[case::unknown_key(
        "[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\nprodcut_code = 3\n",
        "l.toml:5:1: scan list (key `prodcut_code`): unknown field `prodcut_code`"
    )]
    #[case::unknown_top_level_key(
        "interscan_delay = 5\n[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n",
        "l.toml:1:1: scan list (key `interscan_delay`): unknown field `interscan_delay`"
    )]
    #[case::unknown_table(
        "[scanner]\nmac = 1\n[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n",
        "l.toml:1:2: scan list (key `scanner`): unknown field `scanner`"
    )]
    #[case::unknown_key_in_a_node_table(
        "[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n[node.key]\nvendor_id = 1\n",
        "l.toml:5:7: scan list (key `key`): unknown field `key`"
    )]
    #[case::unknown_key_in_an_inline_table(
        "[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\nkey = { vendor = 1 }\n",
        "l.toml:5:1: scan list (key `key`): unknown field `key`"
    )]
    #[case::unknown_key_in_a_later_node(
        "[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n\n[[node]]\nmac = 6\ninput_size = 1\noutput_size = 1\nnmae = \"x\"\n",
        "l.toml:10:1: scan list (key `nmae`): unknown field `nmae`"
    )]
    #[case::empty("# nothing yet\n", "l.toml: scan list: no [[node]]: nothing to scan")]
    #[case::empty_with_settings(
        "interscan_delay_ms = 5\n",
        "l.toml: scan list: no [[node]]: nothing to scan"
    )]
    #[case::wrong_type(
        "[[node]]\nmac = \"five\"\ninput_size = 1\noutput_size = 1\n",
        "l.toml:2:7: scan list (key `mac`)"
    )]
    #[case::missing_size("[[node]]\nmac = 5\noutput_size = 1\n", "input_size")]
    #[case::syntax("[[node]\nmac = 5\n", "l.toml:1:")]
    #[case::connection(
        "[[node]]\nmac = 5\nconnection = \"multicast\"\ninput_size = 1\noutput_size = 1\n",
        "l.toml:3:14: scan list (key `connection`): connection type 'multicast'"
    )]
    #[case::strobe_input(
        "[[node]]\nmac = 5\nconnection = \"strobe\"\ninput_size = 18\noutput_size = 0\n",
        "l.toml:4:14: scan list (key `input_size`): 18 bytes: a strobe response carries at most 8 bytes"
    )]
    #[case::strobe_output(
        "[[node]]\nmac = 5\nconnection = \"strobe\"\ninput_size = 8\noutput_size = 1\n",
        "l.toml:5:15: scan list (key `output_size`): output_size 1: a strobed node's output is its bit"
    )]
    #[case::suppression_on_poll(
        "[[node]]\nmac = 5\nack_suppression = true\ninput_size = 8\noutput_size = 1\n",
        "l.toml:3:19: scan list (key `ack_suppression`): acknowledge suppression applies to cos and cyclic, not to poll"
    )]
    #[case::inhibit_on_cyclic(
        "[[node]]\nmac = 5\nconnection = \"cyclic\"\ninhibit_ms = 5\ninput_size = 8\noutput_size = 1\n",
        "l.toml:4:14: scan list (key `inhibit_ms`): the production inhibit time applies to cos, not to cyclic"
    )]
    fn bad_lists(#[case] text: &str, #[case] want: &str) {
        let e = parse_scan_list(text, "l.toml").unwrap_err().to_string();
        assert!(e.contains(want), "{e}");
    }

    #[test]
    fn the_scanner_s_own_mac_is_refused_where_it_is_written() {
        let text = "[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n\n[[node]]\nmac = 0\ninput_size = 1\noutput_size = 1\n";
        let e = parse_scan_list_for(text, "l.toml", Some(0)).unwrap_err();
        assert!(matches!(e, HarnessError::ScanList { line: 7, column: 7, .. }), "exit 2: {e:?}");
        assert_eq!(e.exit_code(), 2);
        assert!(
            e.to_string()
                .contains("l.toml:7:7: scan list (key `mac`): MAC 0 is the scanner's own (--master-mac 0)"),
            "{e}"
        );
        assert!(parse_scan_list_for(text, "l.toml", Some(9)).is_ok());
    }
}
