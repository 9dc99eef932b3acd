//! I/O connections of issue 14 (protocol §II.1, §II.2, §II.5;
//! `docs/src/reference/io-connections.md`): bit-strobe,
//! change of state acknowledged and with acknowledge suppression, cyclic, the Acknowledge Handler
//! object and the device heartbeat. The exchanges run through the master's own I/O code
//! (`master_core::io`), which judges every frame; the checks add what only a test provokes (a
//! production left unacknowledged, a strobe with the bit clear, a short strobe).

use super::super::runner::{Check, Runner};
use super::super::{Basis, Category};
use devicenet::explicit::{GeneralStatus, ServiceCode};
use devicenet::fragment::IoReassembler;
use devicenet::id::Group1MessageId;
use devicenet::messages::{DeviceHeartbeat, DEVICE_HEARTBEAT};
use devicenet::objects::class;
use devicenet::{Duration, Identifier, Instant};
use harness_common::error::HarnessError;
use master_core::client::{Port, Reply, ReplyBody};
use master_core::decode::{self, hex};
use master_core::io::{IoConnection, IoKind, IoOptions, ACKNOWLEDGE_HANDLER, DEFAULT_ACK_TIMER_MS};
use master_core::session::Verdict;

const IO: Category = Category::IoConnections;

pub(super) fn run(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run(
        "bit-strobe",
        "bit-strobe: Connection 3's identifiers and sizes, every strobe answered, never fragmented",
        IO,
        "§II.1, §1.2, §1.3",
        bit_strobe,
    )?;
    r.run(
        "cos-acknowledged",
        "change of state, acknowledged: Connection 4 and 2 identifiers and sizes, productions reassembled and acknowledged, the master's data acknowledged",
        IO,
        "§II.2.1-§II.2.4, §4.2",
        cos_acknowledged,
    )?;
    r.run(
        "cos-suppressed",
        "change of state with acknowledge suppression: no acknowledgement either way",
        IO,
        "§II.2.1, §II.2.2, §II.2.5",
        cos_suppressed,
    )?;
    r.run("cyclic", "cyclic: a production every EPR", IO, "§II.2.3, §5.3", cyclic)?;
    r.run(
        "ack-handler",
        "the Acknowledge Handler object: its attributes, Get and Set, 0 refused; an unacknowledged production sent again after the timer, retry limit times",
        IO,
        "§II.2.4",
        ack_handler,
    )?;
    r.run(
        "heartbeat",
        "the device heartbeat: Identity attribute 10 = 1 s, heartbeats 1 s apart, off at 0",
        IO,
        "§II.5.1, §3.7",
        heartbeat,
    )
}

/// A fresh explicit connection and the I/O connection of `io` established through the master.
fn fresh_io(r: &mut Runner<'_, '_>, io: &IoOptions) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    r.io_allocated = true;
    let (dut, epr) = (r.dut(), r.opts.epr_ms);
    r.m.establish_io(dut, epr, io)?;
    Ok(())
}

/// The options for `kind` on this transport (timing judged where the timestamps allow).
fn options(r: &Runner<'_, '_>, kind: IoKind) -> IoOptions {
    IoOptions { judge_timing: r.timing_judged(), ..IoOptions::of(kind) }
}

/// Reads Connection `instance` attribute 3 (transport class and trigger) and expects `want`
/// (the RA tables; the encoding is UNCONFIRMED, §II.8 item 2).
fn transport_trigger(
    r: &mut Runner<'_, '_>,
    c: &mut Check,
    instance: u16,
    want: u8,
) -> Result<(), HarnessError> {
    if let Some((v, i)) = r.read(c, Basis::Unconfirmed, class::CONNECTION, instance, 3)? {
        c.expect(
            Basis::Unconfirmed,
            v == [want],
            format!(
                "Connection {instance} transport class and trigger {} (0x{want:02X} in the RA tables)",
                hex(&v)
            ),
            i,
        );
    }
    Ok(())
}

fn bit_strobe(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let io = options(r, IoKind::Strobe);
    fresh_io(r, &io)?;
    transport_trigger(r, c, 3, 0x82)?;
    for _ in 0..3 {
        let input = r.m.strobe()?;
        c.firm(
            input.len() <= 8,
            format!("strobe answered with {} bytes (at most 8, not fragmented)", input.len()),
            None,
        );
    }
    let dut = r.dut();
    let strobe_id = r.m.strobe_id();
    let response_id = Identifier::group1(Group1MessageId::BIT_STROBE_RESPONSE, dut);
    // Its bit clear: answered all the same (NI; UNCONFIRMED, DELTA differs, §II.1.3).
    r.send(strobe_id, &[0; 8])?;
    let until = r.now() + Duration::from_millis(100);
    let got = responses(r, until, response_id)?;
    c.expect(
        Basis::Unconfirmed,
        got == 1,
        format!("a strobe with its bit clear: {got} response(s) (every strobe is answered, NI)"),
        None,
    );
    // A strobe of 7 bytes: ignored (§II.1.2, "ignoring is the safe choice", UNCONFIRMED).
    let mut short = master_core::io::strobe_data(dut).to_vec();
    short.pop();
    r.send(strobe_id, &short)?;
    let until = r.now() + Duration::from_millis(100);
    let got = responses(r, until, response_id)?;
    c.expect(Basis::Unconfirmed, got == 0, format!("a strobe of 7 bytes: {got} response(s) (ignored)"), None);
    r.release_all()
}

/// Collects until `until` and counts the device's frames on `id` (judged ok); other frames of the
/// device fail.
fn responses(r: &mut Runner<'_, '_>, until: Instant, id: devicenet::CanId) -> Result<usize, HarnessError> {
    let mut n = 0;
    for i in r.collect(until)? {
        if r.rec(i).1.id() == id {
            n += 1;
            r.verdict(i, Verdict::Ok("bit-strobe response".into()));
        } else {
            r.verdict(i, Verdict::fail("unexpected frame from the device"));
        }
    }
    Ok(n)
}

/// Exchanges `cycles` productions and the master's data through the master.
fn exchange(r: &mut Runner<'_, '_>, c: &mut Check, cycles: u32) -> Result<(), HarnessError> {
    let consumed = r.m.io_connection().map_or(0, |k| k.consumed);
    let output = vec![0u8; usize::from(consumed)];
    for _ in 0..cycles {
        r.m.await_production()?;
        if consumed > 0 {
            r.m.send_output(&output)?;
        }
    }
    // No connection to judge is a failure, not a silent pass: nothing would have been compared.
    let Some(k) = r.m.io_connection() else {
        c.firm(false, "no I/O connection established: nothing exchanged", None);
        return Ok(());
    };
    let s = &k.summary;
    c.firm(
        s.productions >= cycles,
        format!(
            "{} production(s) of {} bytes reassembled, {} acknowledgement(s) sent; the master's data sent {} time(s), acknowledged {} time(s)",
            s.productions, k.produced, s.acks_sent, s.outputs_sent, s.outputs_acknowledged
        ),
        None,
    );
    if let (Some(lo), Some(hi)) = (s.interval_min_ms, s.interval_max_ms) {
        c.measure("production interval, shortest", lo, "ms");
        c.measure("production interval, longest", hi, "ms");
    }
    Ok(())
}

/// The series of productions among `frames` (complete I/O messages on 0x340 | MAC), with the
/// time of their first frame; `produced` is the connection's size.
fn series(r: &mut Runner<'_, '_>, frames: &[usize], produced: u16) -> Vec<(Instant, Vec<u8>)> {
    let id = Identifier::group1(Group1MessageId::COS_CYCLIC, r.dut());
    let mut rx: Box<IoReassembler<{ decode::MAX_IO_MESSAGE }>> = Box::new(IoReassembler::new());
    let mut out = Vec::new();
    let mut start = None;
    for &i in frames {
        let (at, f) = r.rec(i);
        if f.id() != id {
            r.verdict(i, Verdict::fail("unexpected frame from the device"));
            continue;
        }
        r.verdict(i, Verdict::Ok("production (not acknowledged on purpose)".into()));
        if produced <= 8 {
            out.push((at, f.data().to_vec()));
            continue;
        }
        if f.data().first().is_some_and(|b| b & 0xC0 == 0) {
            start = Some(at);
        }
        if let Ok(Some(whole)) = rx.receive(f.data()) {
            out.push((start.unwrap_or(at), whole.to_vec()));
        }
    }
    out
}

fn cos_acknowledged(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let io = options(r, IoKind::ChangeOfState);
    fresh_io(r, &io)?;
    transport_trigger(r, c, 4, 0x13)?;
    exchange(r, c, 3)?;
    r.release_all()
}

/// The production left unacknowledged on an acknowledged cyclic connection (no change of state
/// can trigger a production of its own in between): sent again after the acknowledge timer,
/// retry limit times, then nothing until the next EPR (§II.2.4; the whole series, UNCONFIRMED).
fn unacknowledged(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let Some(conn) = r.m.end_io() else {
        c.firm(false, "no I/O connection established: no production to leave unacknowledged", None);
        return Ok(());
    };
    let judged = leave_unacknowledged(r, c, &conn);
    // The device runs the connection until it has the Release: its frames are the master's again.
    r.m.resume_io(conn);
    judged
}

/// [`unacknowledged`] on `conn`, taken from the master: the frames of 2 x EPR judged here.
fn leave_unacknowledged(
    r: &mut Runner<'_, '_>,
    c: &mut Check,
    conn: &IoConnection,
) -> Result<(), HarnessError> {
    let timer = Duration::from_millis(u64::from(conn.summary.ack_timer_ms.unwrap_or(DEFAULT_ACK_TIMER_MS)));
    let retries = conn.summary.retry_limit.unwrap_or(1);
    let epr = Duration::from_millis(u64::from(conn.epr_ms));
    r.waiting("leaving a production unacknowledged");
    let until = r.now() + epr + epr;
    let frames = r.collect(until)?;
    let got = series(r, &frames, conn.produced);
    let Some((first, data)) = got.first().cloned() else {
        c.firm(false, format!("no production within 2 x EPR ({})", epr + epr), None);
        return Ok(());
    };
    let tol = master_core::io::timing_tolerance(epr);
    let again: Vec<Instant> =
        got.iter().skip(1).filter(|(t, d)| *d == data && *t - first + tol < epr).map(|(t, _)| *t).collect();
    c.firm(
        !again.is_empty(),
        format!(
            "a production left unacknowledged is sent again: {} time(s) before the next EPR",
            again.len()
        ),
        None,
    );
    let mut previous = first;
    for &t in &again {
        let after = t - previous;
        c.timed(
            Basis::Normative,
            after + Duration::from_millis(2) >= timer && after <= timer + Duration::from_millis(10),
            format!("sent again {after} after the previous one, the acknowledge timer is {timer}"),
            None,
        );
        previous = t;
    }
    c.expect(
        Basis::Unconfirmed,
        again.len() == usize::from(retries),
        format!("sent again {} time(s), the retry limit is {retries}", again.len()),
        None,
    );
    Ok(())
}

fn cos_suppressed(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let io = IoOptions { ack_suppression: true, ..options(r, IoKind::ChangeOfState) };
    fresh_io(r, &io)?;
    transport_trigger(r, c, 4, 0x10)?;
    if let Some((v, i)) = r.read(c, Basis::Unconfirmed, class::CONNECTION, 4, 6)? {
        c.expect(
            Basis::Unconfirmed,
            v == [0x0F],
            format!("initial comm characteristics {} (0x0F: consumes nothing)", hex(&v)),
            i,
        );
    }
    // Every acknowledgement of the master's data fails the frame (master_core::io).
    exchange(r, c, 3)?;
    let (sent, acks) =
        r.m.io_connection().map_or((0, 0), |k| (k.summary.outputs_sent, k.summary.outputs_acknowledged));
    if sent == 0 {
        // A device that consumes nothing gets no data: nothing to leave unacknowledged was compared.
        c.expect(
            Basis::Unconfirmed,
            false,
            "the device consumes nothing: no master data sent, its acknowledgements not compared".to_string(),
            None,
        );
    } else {
        c.firm(
            acks == 0,
            format!("the master's data sent {sent} time(s), acknowledged {acks} time(s) (never, under suppression)"),
            None,
        );
    }
    r.release_all()
}

fn cyclic(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let io = options(r, IoKind::Cyclic);
    fresh_io(r, &io)?;
    transport_trigger(r, c, 4, 0x03)?;
    // The intervals are judged frame by frame (master_core::io: every EPR, tolerance max(EPR/5, 20 ms)).
    exchange(r, c, 6)?;
    r.release_all()
}

fn ack_handler(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    const AH: u16 = ACKNOWLEDGE_HANDLER;
    for (inst, attr, want, basis, what) in [
        (0u16, 1u8, vec![1u8, 0], Basis::Unconfirmed, "class revision 1"),
        (0, 2, vec![1, 0], Basis::Unconfirmed, "class max instance 1"),
        (1, 1, vec![16, 0], Basis::Free, "acknowledge timer 16 ms by default (U3K, XM, TOSH)"),
        (1, 2, vec![1], Basis::Free, "retry limit 1 by default (U3K, XM)"),
        (1, 3, vec![4, 0], Basis::Normative, "COS producing connection instance 4"),
    ] {
        if let Some((v, i)) = r.read(c, Basis::Normative, AH, inst, attr)? {
            c.expect(basis, v == want, format!("{what}: read {}", hex(&v)), i);
        }
    }
    let set = |r: &mut Runner<'_, '_>,
               attr: u8,
               value: &[u8]|
     -> Result<super::super::runner::Outcome, HarnessError> {
        let mut data = vec![attr];
        data.extend_from_slice(value);
        Runner::outcome(r.request(Port::Explicit, ServiceCode::SetAttributeSingle, AH, 1, &data))
    };
    let o = set(r, 1, &[0, 0])?;
    let refused = match &o.0 {
        Ok(Reply { body: ReplyBody::Error { general, .. }, .. }) => {
            *general == GeneralStatus::InvalidAttributeValue
        }
        _ => false,
    };
    c.firm(refused, "acknowledge timer 0 refused with 0x09 (range 1-65535, U3K)", o.1);
    for (attr, value) in [(1u8, vec![40u8, 0]), (2, vec![2])] {
        let o = set(r, attr, &value)?;
        if r.expect_success(c, Basis::Normative, &o, &format!("Set attribute {attr} = {}", hex(&value)))
            .is_some()
        {
            if let Some((v, i)) = r.read(c, Basis::Normative, AH, 1, attr)? {
                c.firm(v == value, format!("attribute {attr} reads back {}", hex(&v)), i);
            }
        }
    }
    // The timer and the limit at work: a cyclic connection with 20 ms and 2 retries.
    let io = IoOptions { ack_timer_ms: Some(20), retry_limit: Some(2), ..options(r, IoKind::Cyclic) };
    fresh_io(r, &io)?;
    exchange(r, c, 2)?;
    unacknowledged(r, c)?;
    r.release_all()?;
    // Back to the defaults for the checks that follow.
    let _ = set(r, 1, &[16, 0])?;
    let _ = set(r, 2, &[1])?;
    Ok(())
}

fn heartbeat(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let dut = r.dut();
    let state = r.read_u8(class::IDENTITY, 1, 8)?;
    let o = Runner::outcome(r.set(class::IDENTITY, 1, 10, &[1]))?;
    if r.expect_success(c, Basis::Normative, &o, "Set Identity heartbeat interval (attribute 10) = 1 s")
        .is_none()
    {
        return Ok(());
    }
    let start = r.now();
    r.waiting("collecting heartbeats for 3.5 s");
    let frames = r.collect(start + Duration::from_millis(3500))?;
    let response_id = r.explicit_response_id();
    let mut beats: Vec<Instant> = Vec::new();
    for i in frames {
        let (at, f) = r.rec(i);
        if f.id() != response_id || f.data().get(1) != Some(&DEVICE_HEARTBEAT) {
            r.verdict(i, Verdict::fail("unexpected frame from the device"));
            continue;
        }
        let mut fails = Vec::new();
        match DeviceHeartbeat::parse(f.data()) {
            Ok(h) => {
                if h.mac != dut {
                    fails.push(format!(
                        "header MAC {}, a heartbeat carries the device's own MAC {dut}",
                        h.mac
                    ));
                }
                if h.identity_instance != 1 {
                    fails.push(format!("Identity instance {}", h.identity_instance));
                }
                if let Some(s) = state {
                    if u8::from(h.state) != s {
                        fails.push(format!("state {}, Identity attribute 8 reads {s}", u8::from(h.state)));
                    }
                }
            }
            Err(e) => fails.push(format!("not a heartbeat of 8 bytes: {e}")),
        }
        let ok = fails.is_empty();
        r.verdict(i, Verdict::Ok("device heartbeat".into()).with_failures(fails.clone()));
        c.firm(ok, if ok { format!("heartbeat {}", hex(f.data())) } else { fails.join("; ") }, Some(i));
        beats.push(at);
    }
    c.firm(beats.len() >= 3, format!("{} heartbeat(s) in 3.5 s at a 1 s interval", beats.len()), None);
    for w in beats.windows(2) {
        let gap = w[1] - w[0];
        let off = gap.total_micros().abs_diff(1_000_000);
        c.timed(Basis::Normative, off <= 100_000, format!("heartbeats {gap} apart (1 s)"), None);
    }
    let o = Runner::outcome(r.set(class::IDENTITY, 1, 10, &[0]))?;
    r.expect_success(c, Basis::Normative, &o, "Set the heartbeat interval = 0 (off)");
    let quiet = Duration::from_millis(1500);
    r.expect_silence(c, quiet, "with the heartbeat off")?;
    Ok(())
}
