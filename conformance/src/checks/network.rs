//! Network access: the bring-up of protocol §2, the device's own duplicate MAC ID check and its
//! answer to another node's (§7.1, §3.5), silence to UCMM (§3.4, §1.4), traffic to other MAC IDs
//! ignored (§8).

use super::super::runner::{g2, Check, Runner};
use super::super::{Basis, Category};
use can_io::bus::Origin;
use devicenet::explicit::BodyFormat;
use devicenet::id::Group3MessageId;
use devicenet::messages::{DuplicateMacCheck, GroupSelect, UcmmCloseRequest, UcmmOpenRequest};
use devicenet::objects::class;
use devicenet::{Duration, Group2Message, Identifier, Instant};
use harness_common::error::HarnessError;
use master_core::master::ConnectOptions;
use master_core::session::Verdict;

const NA: Category = Category::NetworkAccess;

pub(super) fn run(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run(
        "bring-up",
        "the bring-up (the reference start-up sequence), every frame checked",
        NA,
        "§2",
        bring_up,
    )?;
    // Nothing from the device during the whole bring-up (no duplicate MAC ID check, no answer to
    // the UCMM probes or to the Allocate through the Group 2 Only port, protocol §2, §3.4, §7.1):
    // nobody is there, and every other check would only time out.
    if !r.device_heard() {
        return Err(HarnessError::NoDevice {
            mac: r.dut(),
            detail: format!(
                "it sent no duplicate MAC ID check and did not answer the Allocate through the Group 2 Only port \
                 within {} (no other check was run)",
                r.m.config.response_timeout
            ),
        });
    }
    r.run(
        "dup-mac-startup",
        "its own duplicate MAC ID check: two requests 1 s apart, then on-line",
        NA,
        "§7.1 (1), §3.5",
        dup_mac_startup,
    )?;
    r.run(
        "dup-mac-answer",
        "a duplicate MAC ID request for its MAC is answered with a response",
        NA,
        "§7.1 (3), §3.5",
        dup_mac_answer,
    )?;
    r.run("ucmm-silent", "UCMM (Group 3) requests stay unanswered", NA, "§3.4, §1.4", ucmm_silent)?;
    r.run("other-macs-ignored", "traffic for another MAC ID is ignored", NA, "§8", other_macs)
}

fn bring_up(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let opts = ConnectOptions {
        target: r.dut(),
        epr_ms: r.opts.epr_ms,
        polls: 1,
        output: None,
        verify_state: false,
    };
    let start = r.mark();
    r.waiting("network access and the device's duplicate MAC ID check (2 s)");
    let summary = r.m.connect(&opts)?;
    let frames = r.mark() - start;
    r.note_identity(1, summary.vendor_id);
    r.note_identity(2, summary.device_type);
    r.note_identity(3, summary.product_code);
    r.facts.produced = summary.produced_size;
    r.facts.consumed = summary.consumed_size;
    r.facts.applied_epr = summary.expected_packet_rate_ms;
    if let Some(dup) = r.m.tracker.announced(r.dut().as_raw()) {
        r.facts.announced = Some((dup.vendor_id, dup.serial_number, dup.port));
    }
    c.measure("frames", frames as f64, "frames");
    c.firm(
        true,
        format!(
            "brought up in {frames} frames (the reference device takes 28): explicit and poll connections \
             established, EPR {} ms, {} / {} bytes produced / consumed",
            summary.expected_packet_rate_ms.unwrap_or(0),
            summary.produced_size.unwrap_or(0),
            summary.consumed_size.unwrap_or(0)
        ),
        None,
    );
    Ok(())
}

fn dup_mac_startup(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let id = g2(r.dut(), Group2Message::DuplicateMacCheck);
    let seen: Vec<(usize, Instant, DuplicateMacCheck)> =
        r.m.session
            .records()
            .iter()
            .filter(|rec| rec.origin == Origin::Remote && rec.frame.id() == id)
            .filter_map(|rec| DuplicateMacCheck::parse(rec.frame.data()).ok().map(|d| (rec.index, rec.at, d)))
            .filter(|(_, _, d)| !d.response)
            .collect();
    match seen.as_slice() {
        [] => c.advise(
            Basis::Normative,
            "not observed: the device was on-line before the suite started (power it on after starting the suite to see its check)",
        ),
        [(i, _, _)] => {
            c.firm(false, "only one duplicate MAC ID request; two are required, 1 s apart", Some(*i));
        }
        [(i0, t0, d0), (i1, t1, d1), rest @ ..] => {
            let gap = (*t1 - *t0).total_micros() as f64 / 1000.0;
            c.measure("interval between the two requests", gap, "ms");
            c.timed(
                Basis::Normative,
                (900.0..=1100.0).contains(&gap),
                format!("second request {gap:.1} ms after the first (1 s)"),
                Some(*i1),
            );
            c.firm(
                d0 == d1 && d0.port < 0x80,
                format!(
                    "both requests carry port {}, vendor 0x{:04X}, serial 0x{:08X}",
                    d0.port, d0.vendor_id, d0.serial_number
                ),
                Some(*i0),
            );
            c.firm(
                rest.is_empty(),
                format!("{} request(s) after the second: the check must not restart", rest.len()),
                rest.first().map(|x| x.0),
            );
        }
    }
    Ok(())
}

fn dup_mac_answer(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let id = g2(r.dut(), Group2Message::DuplicateMacCheck);
    // A newcomer with the device's MAC ID and its own vendor/serial.
    let newcomer = DuplicateMacCheck::request(0, 0x0FFF, 0xA5A5_0001);
    r.send(id, &newcomer.emit())?;
    let until = r.now() + Duration::from_secs(1);
    let got = r.collect(until)?;
    let mut answered = false;
    for i in got {
        let (at, f) = r.rec(i);
        let _ = at;
        match DuplicateMacCheck::parse(f.data()) {
            Ok(d) if f.id() == id && d.response && !answered => {
                answered = true;
                let mut fails = Vec::new();
                if let Some((vendor, serial, port)) = r.facts.announced {
                    if (d.vendor_id, d.serial_number, d.port) != (vendor, serial, port) {
                        fails.push(format!(
                            "answers with vendor 0x{:04X} serial 0x{:08X} port {}, but announced vendor 0x{vendor:04X} serial 0x{serial:08X} port {port}",
                            d.vendor_id, d.serial_number, d.port
                        ));
                    }
                }
                let ok = fails.is_empty();
                r.verdict(i, Verdict::Ok("duplicate MAC ID response".into()).with_failures(fails.clone()));
                c.firm(
                    ok,
                    if ok {
                        format!(
                            "answered with a response (R/R 1, port {}, vendor 0x{:04X}, serial 0x{:08X})",
                            d.port, d.vendor_id, d.serial_number
                        )
                    } else {
                        fails.join("; ")
                    },
                    Some(i),
                );
            }
            _ => {
                r.verdict(i, Verdict::fail("unexpected frame after a duplicate MAC ID request"));
                c.firm(false, format!("unexpected frame {f}"), Some(i));
            }
        }
    }
    if !answered {
        c.firm(false, "no duplicate MAC ID response within 1 s", None);
    }
    // A request (not a response) must not fault the device: it still serves explicit requests.
    r.fresh_explicit()?;
    let a = Runner::outcome(r.get(class::IDENTITY, 1, 1))?;
    r.expect_success(c, Basis::Normative, &a, "still on-line afterwards (Identity vendor ID read)");
    Ok(())
}

fn ucmm_silent(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let master = r.master_mac();
    let id = Identifier::Group3 { message: Group3MessageId::UNCONNECTED_REQUEST, source: master }.encode();
    let open = UcmmOpenRequest {
        xid: false,
        destination: r.dut(),
        body_format: BodyFormat::Class8Instance8,
        group_select: GroupSelect::Group3,
        source_message_id: 4,
    };
    r.send(id, &open.emit())?;
    r.expect_silence(c, Duration::from_secs(1), "a UCMM open explicit connection request")?;
    let open2 = UcmmOpenRequest { group_select: GroupSelect::Group2, source_message_id: 0, ..open };
    r.send(id, &open2.emit())?;
    r.expect_silence(c, Duration::from_millis(500), "a UCMM open for a Group 2 connection")?;
    let close = UcmmCloseRequest { xid: false, destination: r.dut(), connection_instance: 1 };
    r.send(id, &close.emit())?;
    r.expect_silence(c, Duration::from_millis(500), "a UCMM close request")?;
    Ok(())
}

fn other_macs(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let other = r.bystander;
    let master = r.master_mac();
    let hdr = master.as_raw();
    r.send(g2(other, Group2Message::UnconnectedExplicitRequest), &[hdr, 0x4B, 0x03, 0x01, 0x01, hdr])?;
    r.send(g2(other, Group2Message::ExplicitRequest), &[hdr, 0x0E, 0x01, 0x01, 0x01])?;
    r.send(g2(other, Group2Message::PollCommand), &[0; 8])?;
    r.send(
        g2(other, Group2Message::DuplicateMacCheck),
        &DuplicateMacCheck::request(0, 0x0FFF, 0xA5A5_0002).emit(),
    )?;
    r.expect_silence(
        c,
        Duration::from_millis(500),
        &format!("allocate, explicit, poll and duplicate MAC ID frames for MAC {other}"),
    )?;
    Ok(())
}
