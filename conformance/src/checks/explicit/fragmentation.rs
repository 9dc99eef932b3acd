//! The fragmentation checks of explicit messaging (§4.1): a fragmented response and request, a
//! missing acknowledgement, a duplicated fragment, an out-of-sequence fragment, an oversized
//! request.

use crate::runner::{parse_ack, Check, Runner};
use crate::Basis;
use devicenet::explicit::{Request, ServiceCode};
use devicenet::fragment::{FragmentByte, FragmentKind};
use devicenet::objects::class;
use devicenet::{CanFrame, Duration, Instant};
use harness_common::error::HarnessError;
use master_core::client::{Port, ReplyBody};
use master_core::decode::{self, hex};
use master_core::session::Verdict;

/// The requests that bring a fragmented response: Identity product name, else Get_Attributes_All.
fn fragmented_response_requests() -> [(ServiceCode, u16, u16, Vec<u8>); 2] {
    [
        (ServiceCode::GetAttributeSingle, class::IDENTITY, 1, vec![7]),
        (ServiceCode::GetAttributesAll, class::IDENTITY, 1, vec![]),
    ]
}

pub(super) fn fragmented_response(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    for (service, cls, inst, data) in fragmented_response_requests() {
        let start = r.mark();
        let a = Runner::outcome(r.request(Port::Explicit, service, cls, inst, &data))?;
        if let (Err(e), _) = &a {
            let text = crate::runner::client_error_text(e);
            c.firm(
                false,
                format!(
                    "{}: no complete answer ({text})",
                    decode::request_text(&Request { service, class: cls, instance: inst, data: &data })
                ),
                None,
            );
            return Ok(());
        }
        if let (Ok(reply), record) = &a {
            if reply.fragmented {
                let frags = r.m.session.records()[start..]
                    .iter()
                    .filter(|rec| {
                        rec.frame.id() == r.explicit_response_id()
                            && rec.frame.data().first().is_some_and(|h| h & 0x80 != 0)
                    })
                    .count();
                c.firm(
                    true,
                    format!(
                        "{} answered in {frags} fragments ({} bytes), every fragment checked and acknowledged",
                        decode::request_text(&Request { service, class: cls, instance: inst, data: &data }),
                        reply.message_len
                    ),
                    *record,
                );
                return Ok(());
            }
        }
    }
    c.advise(
        Basis::Normative,
        "not exercised: neither the product name nor Get_Attributes_All needs more than one frame",
    );
    Ok(())
}

/// A request long enough to be fragmented: the output assembly's data (success while no poll
/// connection owns it), else a product name write (refused, but fragmented all the same).
fn long_request(r: &Runner<'_, '_>) -> (u16, u16, Vec<u8>) {
    match (r.facts.output_assembly, r.facts.consumed) {
        (Some(asm), Some(n)) if n >= 4 => {
            let mut data = vec![3u8];
            data.extend(std::iter::repeat_n(0u8, usize::from(n)));
            (class::ASSEMBLY, asm, data)
        }
        _ => {
            let mut data = vec![7u8, 11];
            data.extend_from_slice(b"conformance");
            (class::IDENTITY, 1, data)
        }
    }
}

pub(super) fn fragmented_request(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let (cls, inst, data) = long_request(r);
    let start = r.mark();
    let a = Runner::outcome(r.request(Port::Explicit, ServiceCode::SetAttributeSingle, cls, inst, &data))?;
    let req_id = r.explicit_request_id();
    let sent = r.m.session.records()[start..]
        .iter()
        .filter(|rec| rec.frame.id() == req_id && rec.frame.data().first().is_some_and(|h| h & 0x80 != 0))
        .count();
    match &a.0 {
        Ok(reply) => {
            let answer = match &reply.body {
                ReplyBody::Success(_) => "success".to_string(),
                ReplyBody::Error { general, additional } => decode::error_text(*general, *additional),
            };
            c.firm(
                true,
                format!(
                    "request of {} bytes sent in {sent} fragments, each acknowledged; answered: {answer}",
                    5 + data.len()
                ),
                a.1,
            );
        }
        Err(e) => {
            c.firm(
                false,
                format!("fragmented request not completed: {}", crate::runner::client_error_text(e)),
                None,
            );
        }
    }
    Ok(())
}

/// Device frames of a raw exchange, waiting until `until` or until `done` says so.
fn await_device(
    r: &mut Runner<'_, '_>,
    until: Instant,
    mut done: impl FnMut(&CanFrame) -> bool,
) -> Result<Vec<usize>, HarnessError> {
    let dut = r.dut();
    let mut out = Vec::new();
    while let Some(i) = r.m.session.next(until)? {
        let rec = r.m.session.record(i);
        if rec.origin == can_io::bus::Origin::Local {
            continue;
        }
        if master_core::session::is_from_device(&rec.frame, dut) {
            let f = rec.frame;
            out.push(i);
            if done(&f) {
                break;
            }
        } else {
            r.verdict(i, Verdict::Info("other traffic".into()));
        }
    }
    Ok(out)
}

pub(super) fn missing_ack(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    // Find a request with a fragmented response (its first frame: first fragment, count 0).
    let rsp_id = r.explicit_response_id();
    for (service, cls, inst, data) in fragmented_response_requests() {
        let req = Request { service, class: cls, instance: inst, data: &data };
        let msg = r.message(&req);
        if msg.len() > 8 {
            continue;
        }
        let start_at = r.now();
        let got = r.send_collect(&msg, Duration::from_millis(3500))?;
        let frags: Vec<usize> = got.iter().copied().filter(|&i| r.rec(i).1.id() == rsp_id).collect();
        let Some(&first) = frags.first() else {
            c.firm(false, format!("no answer to {}", decode::request_text(&req)), None);
            return Ok(());
        };
        let (t0, f0) = r.rec(first);
        let is_first_fragment = f0.data().len() >= 2
            && f0.data()[0] & 0x80 != 0
            && FragmentByte::from_byte(f0.data()[1]).kind == FragmentKind::First;
        if !is_first_fragment {
            // Not fragmented after all: try the next request.
            r.verdict(first, Verdict::Ok("unfragmented response".into()));
            continue;
        }
        let _ = start_at;
        r.verdict(first, Verdict::Ok("first response fragment, deliberately not acknowledged".into()));
        match frags.get(1) {
            None => {
                c.advise(
                    Basis::Unconfirmed,
                    "the fragment was not re-sent within 3.5 s (JB re-sends it once after 1 s)",
                );
            }
            Some(&second) => {
                let (t1, f1) = r.rec(second);
                if f1.data() == f0.data() {
                    let gap = (t1 - t0).total_micros() as f64 / 1000.0;
                    c.measure("re-send after", gap, "ms");
                    r.verdict(second, Verdict::Ok(format!("the same fragment re-sent after {gap:.1} ms")));
                    c.timed(
                        Basis::Unconfirmed,
                        (800.0..=1200.0).contains(&gap),
                        format!("re-sent the unacknowledged fragment after {gap:.1} ms (JB: 1 s)"),
                        Some(second),
                    );
                    let more = frags.len() - 2;
                    if more == 0 {
                        c.expect(Basis::Unconfirmed, true, "then aborted: nothing more within 3.5 s", None);
                    } else {
                        for &k in &frags[2..] {
                            r.verdict(k, Verdict::Ok("re-sent again".into()));
                        }
                        c.expect(
                            Basis::Unconfirmed,
                            false,
                            format!("re-sent {more} more time(s) (JB: once, then abort)"),
                            frags.get(2).copied(),
                        );
                    }
                } else {
                    r.verdict(
                        second,
                        Verdict::fail("next fragment sent without the acknowledgement of the previous one"),
                    );
                    c.firm(
                        false,
                        "sent the next fragment although the previous one was not acknowledged",
                        Some(second),
                    );
                }
            }
        }
        for &i in got.iter().filter(|i| !frags.contains(i)) {
            r.verdict(i, Verdict::fail("unexpected frame"));
        }
        let a = Runner::outcome(r.get(class::IDENTITY, 1, 1))?;
        r.expect_success(c, Basis::Normative, &a, "serves the next request (Identity vendor ID)");
        return Ok(());
    }
    c.advise(Basis::Normative, "not exercised: no request with a fragmented response");
    Ok(())
}

/// What came back from a raw fragmented request.
struct RawExchange {
    /// The acknowledgements: record, count, status.
    acks: Vec<(usize, u8, u8)>,
    /// The response record.
    response: Option<usize>,
    /// Anything else the device sent.
    other: Vec<usize>,
}

/// Sends request fragments in the order given, waiting for each acknowledgement (1 s).
fn send_fragments(r: &mut Runner<'_, '_>, frames: &[Vec<u8>]) -> Result<RawExchange, HarnessError> {
    let req_id = r.explicit_request_id();
    let rsp_id = r.explicit_response_id();
    let mut acks = Vec::new();
    let mut response = None;
    let mut other = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        r.send(req_id, f)?;
        let count = FragmentByte::from_byte(f[1]).count;
        let last = k + 1 == frames.len();
        let until = r.now() + Duration::from_secs(1);
        let mut acked = false;
        let got = await_device(r, until, |fr| {
            if fr.id() != rsp_id {
                return false;
            }
            match parse_ack(fr.data()) {
                Some((n, _)) if n == count => {
                    acked = true;
                    !last
                }
                Some(_) => false,
                None => true,
            }
        })?;
        for i in got {
            let (_, fr) = r.rec(i);
            match parse_ack(fr.data()) {
                Some((n, s)) if fr.id() == rsp_id => {
                    r.verdict(i, Verdict::Ok(format!("acknowledge of fragment #{n}, status {s}")));
                    acks.push((i, n, s));
                }
                None if fr.id() == rsp_id && response.is_none() => {
                    response = Some(i);
                }
                _ => other.push(i),
            }
        }
        let _ = acked;
    }
    if response.is_none() {
        let until = r.now() + Duration::from_millis(500);
        for i in await_device(r, until, |fr| fr.id() == rsp_id && parse_ack(fr.data()).is_none())? {
            let (_, fr) = r.rec(i);
            if fr.id() == rsp_id && parse_ack(fr.data()).is_none() && response.is_none() {
                response = Some(i);
            } else {
                other.push(i);
            }
        }
    }
    if let Some(i) = response {
        r.verdict(i, Verdict::Ok("response".into()));
    }
    Ok(RawExchange { acks, response, other })
}

pub(super) fn duplicate_fragment(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let (cls, inst, data) = long_request(r);
    let req = Request { service: ServiceCode::SetAttributeSingle, class: cls, instance: inst, data: &data };
    let frames = Runner::fragments(&r.message(&req));
    if frames.len() < 2 {
        c.advise(Basis::Normative, "not exercised: the request fits one frame");
        return Ok(());
    }
    // A: as it should be.
    let ra = send_fragments(r, &frames)?.response;
    let Some(ra) = ra else {
        c.firm(false, "no response to the request sent in order", None);
        return Ok(());
    };
    let reference = r.rec(ra).1;
    // B: the first fragment twice (its ack "lost"), then the rest.
    let mut dup = vec![frames[0].clone()];
    dup.extend(frames.iter().cloned());
    let RawExchange { acks, response: rb, other } = send_fragments(r, &dup)?;
    let zeros = acks.iter().filter(|(_, n, s)| *n == 0 && *s == 0).count();
    c.firm(
        zeros == 2,
        format!("the repeated first fragment acknowledged again ({zeros} acks of #0)"),
        acks.get(1).map(|a| a.0),
    );
    match rb {
        Some(i) => {
            let same = r.rec(i).1.data() == reference.data();
            if !same {
                r.verdict(i, Verdict::fail("response differs from the one to the request sent once"));
            }
            c.firm(
                same,
                format!("same response as without the repeat ({})", hex(r.rec(i).1.data())),
                Some(i),
            );
        }
        None => {
            c.firm(false, "no response after the repeated fragment", None);
        }
    }
    for i in other {
        r.verdict(i, Verdict::fail("unexpected frame"));
        c.firm(false, "unexpected frame", Some(i));
    }
    // C: the last fragment again after the response (its ack "lost"): re-acknowledged, not served twice.
    let last = frames[frames.len() - 1].clone();
    let count = FragmentByte::from_byte(last[1]).count;
    let got = r.send_collect(&last, Duration::from_millis(700))?;
    let rsp_id = r.explicit_response_id();
    let mut reacked = false;
    for i in got {
        let (_, f) = r.rec(i);
        match parse_ack(f.data()) {
            Some((n, 0)) if f.id() == rsp_id && n == count => {
                reacked = true;
                r.verdict(i, Verdict::Ok(format!("repeated last fragment #{n} acknowledged again")));
            }
            _ => {
                r.verdict(i, Verdict::fail("served the request a second time"));
                c.firm(
                    false,
                    "answered the repeated last fragment with more than an acknowledgement",
                    Some(i),
                );
            }
        }
    }
    c.expect(
        Basis::Unconfirmed,
        reacked,
        if reacked {
            "the repeated last fragment acknowledged again, the request not served twice".to_string()
        } else {
            "the repeated last fragment was not acknowledged again (JB re-acknowledges a repeat of the last acknowledged fragment)".to_string()
        },
        None,
    );
    Ok(())
}

pub(super) fn out_of_sequence(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let (cls, inst, data) = long_request(r);
    let req = Request { service: ServiceCode::SetAttributeSingle, class: cls, instance: inst, data: &data };
    let frames = Runner::fragments(&r.message(&req));
    if frames.len() < 2 {
        c.advise(Basis::Normative, "not exercised: the request fits one frame");
        return Ok(());
    }
    let rsp_id = r.explicit_response_id();
    let got = r.send_collect(&frames[0], Duration::from_millis(500))?;
    let first_acked = got.iter().any(|&i| parse_ack(r.rec(i).1.data()) == Some((0, 0)));
    for &i in &got {
        r.verdict(i, Verdict::Ok("acknowledge of fragment #0".into()));
    }
    c.firm(first_acked, "first fragment acknowledged", got.first().copied());
    // The second fragment with count 2 instead of 1.
    let mut skipped = frames[1].clone();
    let fb = FragmentByte::from_byte(skipped[1]);
    skipped[1] = FragmentByte::new(fb.kind, 2).map_or(skipped[1], FragmentByte::to_byte);
    let got = r.send_collect(&skipped, Duration::from_millis(500))?;
    let mut silent = true;
    for i in got {
        let (_, f) = r.rec(i);
        silent = false;
        match (parse_ack(f.data()), f.id() == rsp_id) {
            (Some((_, 0)), true) => {
                r.verdict(i, Verdict::fail("out-of-sequence fragment acknowledged with success"));
                c.firm(false, "acknowledged the out-of-sequence fragment with success", Some(i));
            }
            _ => {
                r.verdict(i, Verdict::Ok("answer to the out-of-sequence fragment".into()));
                c.advise(
                    Basis::Unconfirmed,
                    format!("answered the out-of-sequence fragment with {f} (JB stays silent)"),
                );
            }
        }
    }
    if silent {
        c.firm(true, "out-of-sequence fragment (count 2 after 0) not acknowledged", None);
    }
    // The right second fragment now: reassembly was reset, so it has no first fragment.
    let got = r.send_collect(&frames[1], Duration::from_millis(500))?;
    for &i in &got {
        r.verdict(i, Verdict::Ok("answer after the reset".into()));
    }
    c.expect(
        Basis::Unconfirmed,
        got.is_empty(),
        if got.is_empty() {
            "reassembly was reset: the in-sequence fragment that followed was dropped".to_string()
        } else {
            "the in-sequence fragment after the bad one was still taken (JB resets reassembly)".to_string()
        },
        got.first().copied(),
    );
    let a = Runner::outcome(r.get(class::IDENTITY, 1, 1))?;
    r.expect_success(c, Basis::Normative, &a, "serves the next request (Identity vendor ID)");
    Ok(())
}

pub(super) fn oversized(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let limit = match r.facts.explicit_consumed {
        Some(l) => l,
        None => match r.read(c, Basis::Normative, class::CONNECTION, 1, 8)? {
            Some((v, _)) if v.len() == 2 => u16::from_le_bytes([v[0], v[1]]),
            _ => return Ok(()),
        },
    };
    if limit >= 900 {
        c.advise(Basis::Free, format!("not exercised: the device takes requests of {limit} bytes"));
        return Ok(());
    }
    let mut data = vec![7u8];
    data.extend(std::iter::repeat_n(b'x', usize::from(limit) + 12));
    let req = Request {
        service: ServiceCode::SetAttributeSingle,
        class: class::IDENTITY,
        instance: 1,
        data: &data,
    };
    let msg = r.message(&req);
    let frames = Runner::fragments(&msg);
    let req_id = r.explicit_request_id();
    let rsp_id = r.explicit_response_id();
    let mut sent_bytes = 1usize;
    let mut rejected = None;
    let mut response = None;
    'send: for f in &frames {
        r.send(req_id, f)?;
        sent_bytes += f.len() - 2;
        let count = FragmentByte::from_byte(f[1]).count;
        let until = r.now() + Duration::from_secs(1);
        let got = await_device(r, until, |fr| {
            fr.id() == rsp_id && parse_ack(fr.data()).is_none_or(|(n, _)| n == count)
        })?;
        if got.is_empty() {
            c.firm(false, format!("fragment #{count} not acknowledged within 1 s"), None);
            break;
        }
        for i in got {
            let (_, fr) = r.rec(i);
            match parse_ack(fr.data()) {
                Some((n, 1)) => {
                    r.verdict(i, Verdict::Ok(format!("acknowledge of fragment #{n}: too much data")));
                    rejected = Some((i, n, sent_bytes));
                    break 'send;
                }
                Some((n, s)) => {
                    r.verdict(i, Verdict::Ok(format!("acknowledge of fragment #{n}, status {s}")))
                }
                None => {
                    response = Some(i);
                    break 'send;
                }
            }
        }
    }
    match (rejected, response) {
        (Some((i, n, bytes)), _) => {
            c.measure("rejected after", bytes as f64, "bytes");
            c.firm(
                bytes <= usize::from(limit) + 6,
                format!("fragment #{n} refused with status 1 (too much data) after {bytes} bytes; the device takes {limit}"),
                Some(i),
            );
        }
        (None, Some(i)) => {
            let (_, f) = r.rec(i);
            let body = f.data().get(1..).unwrap_or(&[]);
            let refused = matches!(body, [0x94, 0x15 | 0x11, ..]);
            r.verdict(i, Verdict::Ok("response to the oversized request".into()));
            c.expect(
                if refused { Basis::Unconfirmed } else { Basis::Normative },
                false,
                format!(
                    "took the whole oversized request and answered {} instead of acknowledge status 1",
                    hex(f.data())
                ),
                Some(i),
            );
        }
        (None, None) => {}
    }
    let a = Runner::outcome(r.get(class::IDENTITY, 1, 1))?;
    r.expect_success(c, Basis::Normative, &a, "serves the next request (Identity vendor ID)");
    Ok(())
}
