//! The scanner's events ([`crate::events`]: automatic device replacement steps, scan-list changes)
//! as a node-level Sparkplug metric (guide: docs/src/plant/mqtt.md, "ADR events on Sparkplug B").
//!
//! [`LAST_EVENT`] (`ADR/Last Event`, String) is in NBIRTH with the newest event so far (null before
//! the first); each new event is one NDATA with that metric, its value the event as JSON (the
//! same object `PREFIX/events` carries: `seq`, `time_us`, `mac`, `kind`, `detail`) and its
//! timestamp the wall-clock time the edge node took it from the scanner. One NDATA per event, in
//! order: a host that keeps the last value of a metric misses none of them as long as it reads
//! every message.
//!
//! Events that happen while the broker is away are not stored (the store holds DDATA only): the
//! NBIRTH of the next connection carries the newest; the whole log is on `GET /api/events`.

use super::edge::{MetricDef, MetricValue};
use super::proto::{DataType, Payload};
use super::{EdgeNode, Job, Outbox};
use crate::events::ScanEvent;
use std::sync::atomic::Ordering;

/// The node-level metric of the newest event.
pub const LAST_EVENT: &str = "ADR/Last Event";

/// The newest event the edge node took, as JSON, with its wall-clock time (ms).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LastEvent(Option<(String, u64)>);

impl LastEvent {
    /// Takes `event` at `unix_ms`; the metric as NDATA sends it.
    pub fn take(&mut self, event: &ScanEvent, unix_ms: u64) -> MetricDef {
        // A ScanEvent always serializes (plain fields, string keys).
        let json = serde_json::to_string(event).unwrap_or_default();
        self.0 = Some((json.clone(), unix_ms));
        metric(MetricValue::Text(json))
    }

    /// The metric for NBIRTH at `unix_ms`: the newest event with its own time, null before one.
    #[must_use]
    pub fn birth(&self, unix_ms: u64) -> super::proto::Metric {
        match &self.0 {
            Some((json, at)) => metric(MetricValue::Text(json.clone())).to_proto(*at, true),
            None => metric(MetricValue::Null(DataType::String)).to_proto(unix_ms, true),
        }
    }
}

fn metric(value: MetricValue) -> MetricDef {
    MetricDef { name: LAST_EVENT.into(), value, unit: None, writable: false }
}

/// NDATA of one event's metric at `unix_ms`.
#[must_use]
pub fn ndata(metric: &MetricDef, unix_ms: u64, seq: u8) -> Payload {
    Payload {
        timestamp: Some(unix_ms),
        metrics: vec![metric.to_proto(unix_ms, false)],
        seq: Some(u64::from(seq)),
        ..Payload::default()
    }
}

impl EdgeNode {
    /// Takes the scanner's new events (oldest first): one NDATA each. Never blocks on the network.
    pub fn publish_events(&self, events: &[ScanEvent]) {
        if events.is_empty() {
            return;
        }
        if self.shared.queued.load(Ordering::Relaxed) >= super::JOB_QUEUE {
            self.shared.dropped.fetch_add(events.len() as u64, Ordering::Relaxed);
            return;
        }
        self.shared.queued.fetch_add(1, Ordering::Relaxed);
        let _ = self.jobs.send(Job::Events(events.to_vec()));
    }
}

impl Outbox {
    /// Publishes one NDATA per event while connected; remembers the newest for NBIRTH either way.
    pub(super) fn events(&mut self, events: Vec<ScanEvent>) {
        self.shared.queued.fetch_sub(1, Ordering::Relaxed);
        let now = Self::now();
        for e in &events {
            let metric = self.last_event.take(e, now);
            if self.client.is_some() {
                let seq = self.next_seq();
                let topic = self.topics.node("NDATA");
                self.publish(topic, &ndata(&metric, now, seq));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::EventKind;
    use crate::sparkplug::proto::Value;

    fn event(seq: u64) -> ScanEvent {
        ScanEvent { seq, time_us: 5_000_000, mac: 5, kind: EventKind::Replaced, detail: "in I/O".into() }
    }

    #[test]
    fn the_birth_metric_is_null_before_an_event_then_the_newest_with_its_time() {
        let mut last = LastEvent::default();
        let b = last.birth(1_000);
        assert_eq!((b.name.as_deref(), b.is_null, b.datatype), (Some(LAST_EVENT), Some(true), Some(12)));
        let m = last.take(&event(7), 2_000);
        let p = ndata(&m, 2_000, 3);
        assert_eq!((p.seq, p.timestamp, p.metrics[0].timestamp), (Some(3), Some(2_000), Some(2_000)));
        let Some(Value::StringValue(json)) = &p.metrics[0].value else { panic!("{p:?}") };
        let back: ScanEvent = serde_json::from_str(json).unwrap();
        assert_eq!(back, event(7));
        let b = last.birth(9_000);
        assert_eq!(
            (b.timestamp, b.is_null, b.value),
            (Some(2_000), None, Some(Value::StringValue(json.clone())))
        );
    }
}
