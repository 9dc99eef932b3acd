//! The Offline Connection Set (protocol §7.1 rule 3, §7.4, §3.8, §II.6;
//! `docs/src/reference/io-connections.md`):
//! the device is made Communication Faulted the one way a master can, a duplicate MAC ID
//! response for its MAC, then found with Who, identified, asked for offline ownership and given
//! its own MAC again with Change MAC ID, after which it must run its duplicate MAC ID check and
//! come back on-line. It runs last: a device that does not come back loses no other check.
//!
//! A device that does not go Communication Faulted fails §7.1 rule 3, and the Offline Connection
//! Set is then reported as not run (advisory), never as passed.

use super::super::runner::{g2, Check, Runner};
use super::super::{Basis, Category};
use can_io::bus::Origin;
use devicenet::id::Group4MessageId;
use devicenet::messages::{AllocationChoice, DeviceKey, DuplicateMacCheck, FaultedSelector, OfflineMessage};
use devicenet::{Duration, Group2Message, Identifier, Instant, MacId};
use harness_common::error::HarnessError;
use master_core::client::{Port, Reply, ReplyBody};
use master_core::session::Verdict;

const OFF: Category = Category::OfflineSet;

pub(super) fn run(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run(
        "offline-recovery",
        "Communication Faulted by a duplicate MAC ID response, then Who, Identify, ownership and Change MAC ID bring it back",
        OFF,
        "§7.1 (3), §7.4, §3.8, §II.6",
        offline_recovery,
    )
}

/// Every frame of another node until `until` (Group 4 frames carry no MAC).
fn collect_all(r: &mut Runner<'_, '_>, until: Instant) -> Result<Vec<usize>, HarnessError> {
    let mut out = Vec::new();
    while let Some(i) = r.m.session.next(until)? {
        if r.m.session.record(i).origin == Origin::Remote {
            out.push(i);
        }
    }
    Ok(out)
}

fn send(r: &mut Runner<'_, '_>, msg: &OfflineMessage) -> Result<(), HarnessError> {
    let mut buf = [0u8; OfflineMessage::MAX_LEN];
    let n = msg.emit(&mut buf).map_err(HarnessError::Message)?;
    r.send(Identifier::Group4 { message: msg.message_id() }.encode(), &buf[..n])
}

/// The Offline Connection Set message among `frames` on `message`; the others judged.
fn answers(
    r: &mut Runner<'_, '_>,
    frames: &[usize],
    message: Group4MessageId,
) -> Vec<(usize, OfflineMessage)> {
    let mut out = Vec::new();
    for &i in frames {
        let f = r.rec(i).1;
        match Identifier::decode(f.id()) {
            Identifier::Group4 { message: m } if m == message => match OfflineMessage::parse(m, f.data()) {
                Ok(msg) => out.push((i, msg)),
                Err(e) => r.verdict(i, Verdict::fail(format!("malformed: {e}"))),
            },
            _ => r.verdict(i, Verdict::fail("unexpected frame while the device is Communication Faulted")),
        }
    }
    out
}

/// The device as the offline checks address it: its MAC, the master's, its vendor, serial number
/// and port as it announced them.
#[derive(Clone, Copy)]
struct Faulted {
    dut: MacId,
    me: MacId,
    key: DeviceKey,
    vendor: u16,
    serial: u32,
    port: u8,
}

fn offline_recovery(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.release_all()?;
    let dut = r.dut();
    let me = r.master_mac();
    let Some((vendor, serial, port)) = r.facts.announced else {
        c.advise(
            Basis::Normative,
            "not run: the device's vendor and serial number were not seen (no duplicate MAC ID check)",
        );
        return Ok(());
    };
    let key = DeviceKey { vendor_id: vendor, serial_number: serial };
    let device = Faulted { dut, me, key, vendor, serial, port };
    // §7.1 rule 3: a duplicate MAC ID response for its MAC while on-line faults it.
    let response = DuplicateMacCheck::response(0, 0x0FFF, 0xA5A5_0002);
    r.send(g2(dut, Group2Message::DuplicateMacCheck), &response.emit())?;
    let until = r.now() + Duration::from_millis(100);
    let got = r.collect(until)?;
    for &i in &got {
        r.verdict(i, Verdict::fail("the device answered a duplicate MAC ID response"));
    }
    let o = r.allocate_as(me, Port::Group2Only, AllocationChoice::EXPLICIT)?;
    let answered = o.0.is_ok();
    c.firm(
        !answered && got.is_empty(),
        if answered {
            "still answers (Allocate explicit) after a duplicate MAC ID response for its MAC: not Communication Faulted".to_string()
        } else {
            "silent after a duplicate MAC ID response for its MAC: Communication Faulted".to_string()
        },
        o.1,
    );
    if answered {
        if let Some(i) = o.1 {
            r.verdict(i, Verdict::fail("answered while it should be Communication Faulted"));
        }
        c.advise(
            Basis::Normative,
            "not run: the Offline Connection Set (Who, Identify, ownership, Change MAC ID) is answered only in Communication Faulted",
        );
        return r.release_all();
    }
    who(r, c, &device)?;
    identify_and_ownership(r, c, &device)?;
    change_mac_id(r, c, &device)
}

/// Who for exactly its MAC: one answer, its own, after the delay its time-delay byte says.
fn who(r: &mut Runner<'_, '_>, c: &mut Check, device: &Faulted) -> Result<(), HarnessError> {
    let Faulted { dut, key, vendor, serial, port, .. } = *device;
    // Who, for exactly its MAC.
    let offset = 3u8;
    let who = OfflineMessage::WhoRequest {
        selector: FaultedSelector { match_flag: true, value: dut.as_raw() },
        time_delay_offset: offset,
    };
    send(r, &who)?;
    let sent = r.now();
    let frames = collect_all(r, sent + Duration::from_millis(500))?;
    let got = answers(r, &frames, Group4MessageId::COMM_FAULTED_RESPONSE);
    let mine: Vec<&(usize, OfflineMessage)> = got
        .iter()
        .filter(|(_, m)| matches!(m, OfflineMessage::WhoResponse { device, .. } if *device == key))
        .collect();
    for (i, m) in &got {
        let ok = matches!(m, OfflineMessage::WhoResponse { port: p, device } if *device == key && *p == port);
        r.verdict(
            *i,
            if ok {
                Verdict::Ok("Who answer".into())
            } else {
                Verdict::fail(format!("not its Who answer: {m:?}"))
            },
        );
        c.firm(
            ok,
            match m {
                OfflineMessage::WhoResponse { port: p, device } => format!(
                    "Who answered: port {p}, vendor 0x{:04X}, serial 0x{:08X} (announced port {port}, vendor 0x{vendor:04X}, serial 0x{serial:08X})",
                    device.vendor_id, device.serial_number
                ),
                other => format!("answered Who with {other:?}"),
            },
            Some(*i),
        );
    }
    c.firm(
        mine.len() == 1,
        format!("{} answer(s) to Who for MAC {dut} within 500 ms (one)", mine.len()),
        None,
    );
    if let Some((i, _)) = mine.first() {
        let delay = r.rec(*i).0 - sent;
        let byte = r.rec(*i).1.data().get(usize::from(offset)).copied().unwrap_or(0);
        c.measure("Who answer after", delay.total_micros() as f64 / 1000.0, "ms");
        c.timed(
            Basis::Unconfirmed,
            delay.total_micros().abs_diff(u64::from(byte) * 1000) <= 5_000,
            format!("Who answered after {delay}; the time-delay byte {offset} of the answer is {byte} (ms, the inference of §II.6)"),
            Some(*i),
        );
    }
    Ok(())
}

/// The long Identify answered 3F CC; offline ownership answered with the request echoed.
fn identify_and_ownership(
    r: &mut Runner<'_, '_>,
    c: &mut Check,
    device: &Faulted,
) -> Result<(), HarnessError> {
    let Faulted { me, key, .. } = *device;
    // Identify, long form.
    let all = FaultedSelector { match_flag: false, value: 0x3F };
    send(r, &OfflineMessage::IdentifyRequest { selector: all, device: Some(key) })?;
    let until = r.now() + Duration::from_millis(300);
    let frames = collect_all(r, until)?;
    let got = answers(r, &frames, Group4MessageId::COMM_FAULTED_RESPONSE);
    let identified = got.iter().any(|(_, m)| *m == OfflineMessage::IdentifyResponse { selector: all });
    for (i, m) in &got {
        let ok = *m == OfflineMessage::IdentifyResponse { selector: all };
        r.verdict(
            *i,
            if ok {
                Verdict::Ok("Identify answer".into())
            } else {
                Verdict::fail("not the Identify answer 3F CC")
            },
        );
    }
    c.firm(identified, format!("the long Identify answered 3F CC ({} answer(s))", got.len()), None);
    // Offline ownership: the request echoed (UNCONFIRMED who answers, §II.6).
    let tool = DeviceKey { vendor_id: r.m.config.vendor_id, serial_number: r.m.config.serial_number };
    send(r, &OfflineMessage::OwnershipRequest { client: me, device: tool })?;
    let until = r.now() + Duration::from_millis(300);
    let frames = collect_all(r, until)?;
    let got = answers(r, &frames, Group4MessageId::OFFLINE_OWNERSHIP_RESPONSE);
    let echoed =
        got.iter().any(|(_, m)| *m == OfflineMessage::OwnershipResponse { client: me, device: tool });
    for (i, _) in &got {
        r.verdict(*i, Verdict::Ok("offline ownership answer".into()));
    }
    c.expect(
        Basis::Unconfirmed,
        echoed,
        format!("offline ownership answered with the request echoed ({} answer(s))", got.len()),
        None,
    );
    Ok(())
}

/// Change MAC ID to its own MAC: two duplicate MAC ID requests 1 s apart, then on-line again.
fn change_mac_id(r: &mut Runner<'_, '_>, c: &mut Check, device: &Faulted) -> Result<(), HarnessError> {
    let Faulted { dut, me, key, vendor, serial, .. } = *device;
    // Change MAC ID to its own MAC: it runs its duplicate MAC ID check again and comes on-line.
    r.waiting("Change MAC ID: watching its duplicate MAC ID check (2 s)");
    send(r, &OfflineMessage::ChangeMacIdRequest { new_mac: dut, device: key })?;
    let changed = r.now();
    let frames = collect_all(r, changed + Duration::from_millis(2100))?;
    let dup_id = g2(dut, Group2Message::DuplicateMacCheck);
    let mut requests = Vec::new();
    for i in frames {
        let (at, f) = r.rec(i);
        match DuplicateMacCheck::parse(f.data()) {
            Ok(d)
                if f.id() == dup_id && !d.response && d.vendor_id == vendor && d.serial_number == serial =>
            {
                r.verdict(i, Verdict::Ok("duplicate MAC ID request after Change MAC ID".into()));
                requests.push(at);
            }
            _ => r.verdict(i, Verdict::fail("unexpected frame during the duplicate MAC ID check")),
        }
    }
    c.firm(
        requests.len() == 2,
        format!("{} duplicate MAC ID request(s) after Change MAC ID (two, protocol §7.1)", requests.len()),
        None,
    );
    if let [a, b] = requests[..] {
        let gap = b - a;
        c.timed(
            Basis::Normative,
            gap.total_micros().abs_diff(1_000_000) <= 100_000,
            format!("the requests {gap} apart (1 s)"),
            None,
        );
    }
    if let Some(&last) = requests.last() {
        r.m.idle_until(last + Duration::from_millis(1050))?;
    }
    let o = r.allocate_as(me, Port::Group2Only, AllocationChoice::EXPLICIT)?;
    let back = matches!(o.0, Ok(Reply { body: ReplyBody::Success(_), .. }));
    c.firm(back, "on-line again: Allocate explicit answered with success", o.1);
    if !back {
        if let Ok(Reply { body: ReplyBody::Error { general, additional }, .. }) = &o.0 {
            c.firm(
                false,
                format!("Allocate explicit: {}", master_core::decode::error_text(*general, *additional)),
                o.1,
            );
        }
    }
    r.release_all()
}
