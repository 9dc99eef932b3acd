//! A scripted device for the unit tests: it answers hand-built frames with hand-built frames, and
//! can produce a series of frames periodically once a trigger frame arrived. Nothing of the real
//! slave: the master's checks are tried against exactly the bytes a test writes.

use can_io::sim::SimDevice;
use devicenet::{CanFrame, Duration, Instant, MacId};

/// One scripted answer: when `(id, data)` arrives, send `replies`, each after its delay.
struct Rule {
    id: u16,
    data: Vec<u8>,
    replies: Vec<(u64, u16, Vec<u8>)>,
}

/// Frames sent every `period` after a trigger, optionally sent again `resend` later.
struct Producer {
    trigger: (u16, Vec<u8>),
    first: Duration,
    period: Duration,
    frames: Vec<(u16, Vec<u8>)>,
    resend: Option<Duration>,
    next: Option<Instant>,
}

/// The scripted device. See the [module docs](self).
pub(crate) struct Scripted {
    mac: MacId,
    rules: Vec<Rule>,
    producer: Option<Producer>,
    timed: Vec<(Instant, CanFrame)>,
    now: Instant,
    /// After this frame the device ignores every other frame for the duration (a node still in
    /// its duplicate MAC ID check drops requests).
    deaf_after: Option<((u16, Vec<u8>), Duration)>,
    deaf_until: Option<Instant>,
}

impl Scripted {
    pub(crate) fn new(mac: u8) -> Scripted {
        Scripted {
            mac: MacId::from_low_bits(mac),
            rules: Vec::new(),
            producer: None,
            timed: Vec::new(),
            now: Instant::ZERO,
            deaf_after: None,
            deaf_until: None,
        }
    }

    /// Once `trigger` arrives, every other frame is ignored for `ms` (0: never deaf).
    pub(crate) fn deaf_after(mut self, trigger: (u16, &[u8]), ms: u64) -> Scripted {
        if ms > 0 {
            self.deaf_after = Some(((trigger.0, trigger.1.to_vec()), Duration::from_millis(ms)));
        }
        self
    }

    /// When `(id, data)` arrives, answer `replies` (`(delay ms, id, data)`).
    pub(crate) fn on(mut self, id: u16, data: &[u8], replies: &[(u64, u16, &[u8])]) -> Scripted {
        let replies = replies.iter().map(|(d, i, b)| (*d, *i, b.to_vec())).collect();
        self.rules.push(Rule { id, data: data.to_vec(), replies });
        self
    }

    /// Explicit request `request` on Group 2 message 4 of the device answered by `response` on
    /// message 3 (header byte included in both).
    pub(crate) fn explicit(self, request: &[u8], response: &[u8]) -> Scripted {
        let mac = u16::from(self.mac.as_raw());
        self.on(0x400 | mac << 3 | 4, request, &[(0, 0x400 | mac << 3 | 3, response)])
    }

    /// Once `trigger` arrives, `frames` go out `first` later and every `period` after; each series
    /// again `resend` after it when given.
    pub(crate) fn produce(
        mut self,
        trigger: (u16, &[u8]),
        first_ms: u64,
        period_ms: u64,
        frames: Vec<(u16, Vec<u8>)>,
        resend_ms: Option<u64>,
    ) -> Scripted {
        self.producer = Some(Producer {
            trigger: (trigger.0, trigger.1.to_vec()),
            first: Duration::from_millis(first_ms),
            period: Duration::from_millis(period_ms),
            frames,
            resend: resend_ms.map(Duration::from_millis),
            next: None,
        });
        self
    }

    fn send_at(&mut self, at: Instant, id: u16, data: &[u8]) {
        if let Ok(f) = CanFrame::from_raw(id, data) {
            self.timed.push((at, f));
        }
    }
}

impl SimDevice for Scripted {
    fn mac(&self) -> MacId {
        self.mac
    }

    fn power_on(&mut self, now: Instant) {
        self.now = now;
    }

    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.now = now;
        let (id, data) = (frame.id().as_raw(), frame.data().to_vec());
        if let Some((trigger, ms)) = &self.deaf_after {
            if *trigger == (id, data.clone()) {
                self.deaf_until = Some(now + *ms);
            } else if self.deaf_until.is_some_and(|until| now < until) {
                return;
            }
        }
        let replies: Vec<(u64, u16, Vec<u8>)> = self
            .rules
            .iter()
            .filter(|r| r.id == id && r.data == data)
            .flat_map(|r| r.replies.clone())
            .collect();
        for (delay, rid, rdata) in replies {
            self.send_at(now + Duration::from_millis(delay), rid, &rdata);
        }
        if let Some(p) = &mut self.producer {
            if p.trigger == (id, data) && p.next.is_none() {
                p.next = Some(now + p.first);
            }
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        let due = self.producer.as_ref().and_then(|p| p.next).filter(|at| *at <= now);
        if let (Some(_), Some(p)) = (due, self.producer.as_mut()) {
            p.next = Some(now + p.period);
            let frames = p.frames.clone();
            let resend = p.resend;
            for (id, data) in &frames {
                self.send_at(now, *id, data);
            }
            if let Some(r) = resend {
                for (id, data) in &frames {
                    self.send_at(now + r, *id, data);
                }
            }
        }
    }

    fn poll_transmit(&mut self) -> Option<CanFrame> {
        let now = self.now;
        let k = self.timed.iter().position(|(at, _)| *at <= now)?;
        Some(self.timed.remove(k).1)
    }

    fn poll_at(&self) -> Option<Instant> {
        let timed = self.timed.iter().map(|(at, _)| *at).min();
        let next = self.producer.as_ref().and_then(|p| p.next);
        [timed, next].into_iter().flatten().min()
    }
}

/// The frames of `session` that failed their checks, one line each (`#index frame: verdict`).
pub(crate) fn failed_frames(session: &crate::session::Session<'_>) -> Vec<String> {
    session
        .records()
        .iter()
        .filter(|r| r.verdict.is_failure())
        .map(|r| format!("#{} {}: {}", r.index, r.frame, r.verdict.label()))
        .collect()
}
