//! The health report: the figures of [`Health`], a score out of 100 and findings in plain words,
//! as JSON ([`HealthReport`], serde) and CSV ([`HealthReport::csv`]).
//!
//! ## The score
//!
//! 100, less (each term capped as shown):
//!
//! | what | less |
//! |---|---|
//! | the controller error warning / error passive / bus-off now | 10 / 25 / 50 |
//! | each bus-off since the start (or the last clear) | 10, at most 30 |
//! | error frames per 1000 frames | 2 each, at most 20 |
//! | bus load above 60 % / above 80 % (over a second or more) | 10 / 20 |
//! | each node's drop-outs | 5 each, at most 30 |
//! | a node whose mean response is slow (over 2 ms and over 3 × the median of the nodes' means) | 5 each |
//!
//! The score is at least 0. The findings name what cost points, worst first.

use super::{Cause, Dropped, Health, Incident};
use can_io::bus::health::ErrorState;
use devicenet::Instant;
use serde::Serialize;
use std::fmt::Write as _;

/// The bus part of the report (`scanner --json`'s `bus`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BusHealthReport {
    /// The controller's state (`active`, `warning`, `passive`, `bus_off`), `unknown` when the bus
    /// does not report it.
    pub state: &'static str,
    /// Error frames since the start or the last clear (`null`: the bus does not report them).
    pub error_frames: Option<u64>,
    /// Transmit error counter now (`null`: not reported).
    pub tec: Option<u16>,
    /// Receive error counter now (`null`: not reported).
    pub rec: Option<u16>,
    /// Bus-off now (`null`: not reported).
    pub bus_off: Option<bool>,
    /// Bus-offs since the start or the last clear (`null`: not reported).
    pub bus_offs: Option<u64>,
    /// Bus load, 0.0-1.0: bits on the wire (stuff bits included) / (bit rate × time).
    pub load: f64,
    /// Frames seen.
    pub frames: u64,
}

/// Response times of a node, ms.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ResponseMs {
    /// Shortest.
    pub min: f64,
    /// Mean.
    pub avg: f64,
    /// Longest.
    pub max: f64,
    /// Responses measured.
    pub count: u64,
}

/// One node of the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeHealthReport {
    /// MAC ID.
    pub mac: u8,
    /// Frames from or to it.
    pub frames: u64,
    /// Its share of the bus traffic, % of the bits on the wire.
    pub traffic_pct: f64,
    /// Response times (`null` before the first).
    pub response_ms: Option<ResponseMs>,
    /// Drop-outs.
    pub dropouts: u64,
    /// Bus time of the last drop-out, s (`null`: none).
    pub last_dropout_s: Option<f64>,
    /// Mean time between its drop-outs, s (`null`: fewer than two).
    pub dropout_interval_s: Option<f64>,
    /// Disabled in the scan list (maintenance): drop-outs are not counted while it is.
    pub disabled: bool,
}

/// One incident of the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IncidentReport {
    /// Bus time, s.
    pub at_s: f64,
    /// A bus-off, or drop-outs of several nodes.
    pub cause: Cause,
    /// The node that went silent first (`null`: none dropped out).
    pub first: Option<u8>,
    /// Every node that dropped out, in the order they went silent.
    pub nodes: Vec<Dropped>,
}

/// The whole report (`GET /api/health`; `scanner --json`'s `bus` and the node fields).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HealthReport {
    /// Bus time the statistics start at, s.
    pub since_s: f64,
    /// Time they cover, s.
    pub duration_s: f64,
    /// The bus.
    pub bus: BusHealthReport,
    /// Every node of the scan list, in MAC order.
    pub nodes: Vec<NodeHealthReport>,
    /// Bus-offs and multi-node drop-outs, oldest first.
    pub incidents: Vec<IncidentReport>,
    /// 0-100 (module docs).
    pub score: u8,
    /// What cost points, in words, worst first.
    pub findings: Vec<String>,
}

fn secs(us: u64) -> f64 {
    us as f64 / 1e6
}

fn ms(us: f64) -> f64 {
    (us / 1000.0 * 1000.0).round() / 1000.0
}

/// The report of `h` at `now`.
pub(super) fn build(h: &Health, now: Instant) -> HealthReport {
    let since = h.since.unwrap_or(now);
    let end = now.max(h.last);
    let duration_us = (end - since).total_micros();
    let capacity = f64::from(h.bitrate.bits_per_second().max(1)) * secs(duration_us);
    let load = if capacity > 0.0 { h.bits as f64 / capacity } else { 0.0 };
    let bus = BusHealthReport {
        state: h.bus.map_or("unknown", |b| b.state.name()),
        error_frames: h.bus.map(|b| b.error_frames.saturating_sub(h.base.0)),
        tec: h.bus.and_then(|b| b.tec),
        rec: h.bus.and_then(|b| b.rec),
        bus_off: h.bus.map(|b| b.state == ErrorState::BusOff),
        bus_offs: h.bus.map(|b| b.bus_offs.saturating_sub(h.base.1)),
        load,
        frames: h.frames,
    };
    let nodes: Vec<NodeHealthReport> = h
        .nodes
        .iter()
        .map(|(&mac, n)| {
            let interval = match (n.drop_times.front(), n.drop_times.back()) {
                (Some(a), Some(b)) if n.drop_times.len() >= 2 => {
                    Some(secs((*b - *a).total_micros()) / (n.drop_times.len() - 1) as f64)
                }
                _ => None,
            };
            NodeHealthReport {
                mac,
                frames: n.frames,
                traffic_pct: if h.bits == 0 { 0.0 } else { n.bits as f64 * 100.0 / h.bits as f64 },
                response_ms: n.responses.mean_us().map(|avg| ResponseMs {
                    min: ms(n.responses.min_us as f64),
                    avg: ms(avg),
                    max: ms(n.responses.max_us as f64),
                    count: n.responses.count,
                }),
                dropouts: n.dropouts,
                last_dropout_s: n.drop_times.back().map(|t| secs(t.total_micros())),
                dropout_interval_s: interval,
                disabled: n.disabled,
            }
        })
        .collect();
    let incidents: Vec<IncidentReport> = h.incidents.iter().filter_map(incident).collect();
    let (score, findings) = judge(&bus, secs(duration_us), &nodes, &incidents);
    HealthReport {
        since_s: secs(since.total_micros()),
        duration_s: secs(duration_us),
        bus,
        nodes,
        incidents,
        score,
        findings,
    }
}

fn incident(i: &Incident) -> Option<IncidentReport> {
    Some(IncidentReport {
        at_s: secs(i.at.total_micros()),
        cause: i.cause()?,
        first: i.nodes.first().map(|d| d.mac),
        nodes: i.nodes.clone(),
    })
}

/// The score and the findings, worst first (each with the points it cost).
fn judge(
    bus: &BusHealthReport,
    duration_s: f64,
    nodes: &[NodeHealthReport],
    incidents: &[IncidentReport],
) -> (u8, Vec<String>) {
    let mut found: Vec<(u32, String)> = Vec::new();
    let counters = match (bus.tec, bus.rec) {
        (Some(t), Some(r)) => format!(" (TEC {t}, REC {r})"),
        _ => String::new(),
    };
    match bus.state {
        "bus_off" => found.push((50, format!("the scanner's CAN controller is bus-off{counters}"))),
        "passive" => found.push((25, format!("the scanner's CAN controller is error passive{counters}"))),
        "warning" => found.push((10, format!("the scanner's CAN controller is at error warning{counters}"))),
        _ => {}
    }
    if let Some(n) = bus.bus_offs.filter(|&n| n > 0) {
        let mut text = format!("the bus went bus-off {n} time(s)");
        if let Some(first) = incidents.iter().rev().find(|i| i.cause == Cause::BusOff).and_then(|i| i.first) {
            let _ = write!(text, "; MAC {first} dropped out first");
        }
        found.push(((n as u32).saturating_mul(10).min(30), text));
    }
    if let Some(e) = bus.error_frames.filter(|&e| e > 0) {
        let per_1000 = e as f64 * 1000.0 / bus.frames.max(1) as f64;
        found.push((
            ((per_1000 * 2.0).ceil() as u32).clamp(1, 20),
            format!("{e} error frame(s) in {} frames ({per_1000:.1} per 1000)", bus.frames),
        ));
    }
    // Over less than a second the load says little (the bring-up's bursts).
    if duration_s < 1.0 {
    } else if bus.load > 0.8 {
        found.push((20, format!("bus load {:.0} %: above 80 %, low-priority frames wait", bus.load * 100.0)));
    } else if bus.load > 0.6 {
        found.push((10, format!("bus load {:.0} %: above 60 %", bus.load * 100.0)));
    }
    for i in incidents.iter().filter(|i| i.cause == Cause::DropOuts) {
        let order: Vec<String> = i.nodes.iter().map(|d| format!("MAC {}", d.mac)).collect();
        found.push((
            0,
            format!(
                "at {:.1} s {} nodes dropped out together, in this order: {}",
                i.at_s,
                i.nodes.len(),
                order.join(", ")
            ),
        ));
    }
    let mut means: Vec<f64> = nodes.iter().filter_map(|n| n.response_ms.map(|r| r.avg)).collect();
    means.sort_by(f64::total_cmp);
    let median = means.get(means.len() / 2).copied();
    for n in nodes {
        let mut parts = Vec::new();
        let mut cost = 0u32;
        if n.dropouts > 0 {
            cost += (n.dropouts as u32).saturating_mul(5).min(30);
            parts.push(match (n.dropout_interval_s, n.last_dropout_s) {
                (Some(every), _) => format!("drops out every {every:.0} s ({} times)", n.dropouts),
                (None, Some(last)) => format!("dropped out once, at {last:.1} s"),
                _ => format!("dropped out {} times", n.dropouts),
            });
        }
        if let (Some(r), Some(median)) = (n.response_ms, median) {
            if r.avg > 2.0 && means.len() >= 2 && r.avg > 3.0 * median {
                cost += 5;
                parts.push(format!("its responses take {:.1} ms (the median node {median:.1} ms)", r.avg));
            }
        }
        if !parts.is_empty() {
            found.push((cost, format!("MAC {} {}", n.mac, parts.join("; "))));
        }
    }
    found.sort_by_key(|f| std::cmp::Reverse(f.0));
    let lost: u32 = found.iter().map(|f| f.0).sum();
    let score = 100u32.saturating_sub(lost) as u8;
    (score, found.into_iter().map(|f| f.1).collect())
}

impl HealthReport {
    /// The node table as CSV: a header, then one row per node (`mac`, `frames`, `traffic_pct`,
    /// `response_min_ms`, `response_avg_ms`, `response_max_ms`, `responses`, `dropouts`,
    /// `last_dropout_s`, `dropout_interval_s`); an empty field where a figure is `null`.
    pub fn csv(&self) -> String {
        let mut out = String::from(
            "mac,frames,traffic_pct,response_min_ms,response_avg_ms,response_max_ms,responses,dropouts,last_dropout_s,dropout_interval_s\n",
        );
        let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
        for n in &self.nodes {
            let r = n.response_ms;
            let _ = writeln!(
                out,
                "{},{},{:.3},{},{},{},{},{},{},{}",
                n.mac,
                n.frames,
                n.traffic_pct,
                opt(r.map(|r| r.min)),
                opt(r.map(|r| r.avg)),
                opt(r.map(|r| r.max)),
                r.map_or(0, |r| r.count),
                n.dropouts,
                opt(n.last_dropout_s),
                opt(n.dropout_interval_s),
            );
        }
        out
    }

    /// The figures of node `mac`, for `scanner --json`'s node objects.
    pub fn node(&self, mac: u8) -> Option<&NodeHealthReport> {
        self.nodes.iter().find(|n| n.mac == mac)
    }
}

/// Adds the report to `scanner --json`'s object `v`: `bus` (the [`BusHealthReport`]), the node
/// figures in each object of `nodes` (by `mac`: `response_ms`, `traffic_pct`, `dropouts`,
/// `last_dropout_s`, `dropout_interval_s`) and `health` (`score`, `findings`, `incidents`,
/// `since_s`, `duration_s`).
pub fn merge_json(v: &mut serde_json::Value, r: &HealthReport) {
    use serde_json::json;
    v["bus"] = json!(r.bus);
    if let Some(nodes) = v.get_mut("nodes").and_then(serde_json::Value::as_array_mut) {
        for n in nodes {
            let Some(h) =
                n.get("mac").and_then(serde_json::Value::as_u64).and_then(|m| r.node(u8::try_from(m).ok()?))
            else {
                continue;
            };
            n["response_ms"] = json!(h.response_ms);
            n["traffic_pct"] = json!(h.traffic_pct);
            n["dropouts"] = json!(h.dropouts);
            n["last_dropout_s"] = json!(h.last_dropout_s);
            n["dropout_interval_s"] = json!(h.dropout_interval_s);
        }
    }
    v["health"] = json!({
        "score": r.score,
        "findings": r.findings,
        "incidents": r.incidents,
        "since_s": r.since_s,
        "duration_s": r.duration_s,
    });
}
