//! The Predefined Master/Slave Connection Set (protocol §3.4): every row of the validation table,
//! allocation through the Group 2 Only port and through the explicit connection, ownership, release
//! and re-allocation.

use super::super::runner::{Check, Runner};
use super::super::{Basis, Category};
use devicenet::explicit::{additional, GeneralStatus, Request, ServiceCode};
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use harness_common::error::HarnessError;
use master_core::client::{Port, Reply, ReplyBody};
use master_core::decode;

const CS: Category = Category::ConnectionSet;

/// Runs the category's checks.
pub(super) fn run(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    allocation_rows(r)?;
    ownership_and_release(r)?;
    ports_and_combinations(r)
}

/// The allocation rows of the validation table of §3.4: what a device refuses and how.
fn allocation_rows(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run(
        "alloc-explicit-not-requested",
        "allocating poll while explicit is neither requested nor allocated: 0x09/0x02",
        CS,
        "§3.4 row 5",
        |r, c| {
            r.release_all()?;
            let o = r.allocate_as(r.master_mac(), Port::Group2Only, AllocationChoice::POLL)?;
            r.expect_error(
                c,
                Basis::Normative,
                &o,
                GeneralStatus::InvalidAttributeValue,
                additional::INVALID_CHOICE,
                "Allocate poll only",
            );
            Ok(())
        },
    )?;
    r.run(
        "release-nonexistent",
        "releasing a connection that does not exist: 0x0B/0x02",
        CS,
        "§3.4 row 9",
        |r, c| {
            let o = r.release_as(r.master_mac(), Port::Group2Only, AllocationChoice::POLL)?;
            r.expect_error(
                c,
                Basis::Normative,
                &o,
                GeneralStatus::AlreadyInRequestedState,
                additional::INVALID_CHOICE,
                "Release poll (not allocated)",
            );
            Ok(())
        },
    )?;
    r.run("alloc-choice-zero", "allocation choice 0: 0x09/0x02", CS, "§3.4 row 2", |r, c| {
        let o = r.allocate_as(r.master_mac(), Port::Group2Only, AllocationChoice::empty())?;
        r.expect_error(
            c,
            Basis::Normative,
            &o,
            GeneralStatus::InvalidAttributeValue,
            additional::INVALID_CHOICE,
            "Allocate choice 0x00",
        );
        Ok(())
    })?;
    r.run(
        "alloc-ack-suppression",
        "acknowledge suppression without change of state or cyclic: 0x09/0x02",
        CS,
        "§3.4 row 3",
        |r, c| {
            let choice = AllocationChoice::EXPLICIT | AllocationChoice::ACK_SUPPRESSION;
            let o = r.allocate_as(r.master_mac(), Port::Group2Only, choice)?;
            r.expect_error(
                c,
                Basis::Normative,
                &o,
                GeneralStatus::InvalidAttributeValue,
                additional::INVALID_CHOICE,
                "Allocate choice 0x41",
            );
            Ok(())
        },
    )?;
    r.run(
        "alloc-lacking-type",
        "a connection type the device lacks: 0x02/0x02",
        CS,
        "§3.4 row 4",
        alloc_lacking,
    )?;
    r.run(
        "alloc-group2-only-port",
        "allocation of the explicit connection through the Group 2 Only port",
        CS,
        "§3.4, §2 frames 6-7",
        |r, c| {
            let o = r.allocate_as(r.master_mac(), Port::Group2Only, AllocationChoice::EXPLICIT)?;
            if let Some(data) =
                r.expect_success(c, Basis::Normative, &o, "Allocate explicit (Group 2 Only port)")
            {
                c.firm(
                    data.len() == 1 && data[0] <= 3,
                    format!(
                        "response data {} is the one-byte body format of the explicit connection",
                        decode::hex(&data)
                    ),
                    o.1,
                );
            }
            Ok(())
        },
    )?;
    Ok(())
}

/// Allocating twice, another master's allocation, releasing what is not held (§3.4).
fn ownership_and_release(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run(
        "alloc-double",
        "allocating a connection already allocated: 0x0B/0x02",
        CS,
        "§3.4 row 6",
        |r, c| {
            let o = r.allocate_as(r.master_mac(), Port::Group2Only, AllocationChoice::EXPLICIT)?;
            r.expect_error(
                c,
                Basis::Normative,
                &o,
                GeneralStatus::AlreadyInRequestedState,
                additional::INVALID_CHOICE,
                "Allocate explicit again",
            );
            Ok(())
        },
    )?;
    r.run(
        "alloc-conflict",
        "allocation by a second master while owned: 0x0C/0x01",
        CS,
        "§3.4 row 1",
        |r, c| {
            let second = r.second;
            let o = r.allocate_as(second, Port::Group2Only, AllocationChoice::EXPLICIT)?;
            r.expect_error(
                c,
                Basis::Normative,
                &o,
                GeneralStatus::ObjectStateConflict,
                additional::ALLOCATION_CONFLICT,
                &format!("Allocate explicit from master MAC {second}"),
            );
            let o = r.release_as(second, Port::Group2Only, AllocationChoice::EXPLICIT)?;
            r.expect_error(
                c,
                Basis::Unconfirmed,
                &o,
                GeneralStatus::ObjectStateConflict,
                additional::ALLOCATION_CONFLICT,
                &format!("Release explicit from master MAC {second} (JB)"),
            );
            Ok(())
        },
    )?;
    r.run("release-choice-zero", "release choice 0: 0x09/0x02", CS, "§3.4 row 7", |r, c| {
        let o = r.release_as(r.master_mac(), Port::Group2Only, AllocationChoice::empty())?;
        r.expect_error(
            c,
            Basis::Normative,
            &o,
            GeneralStatus::InvalidAttributeValue,
            additional::INVALID_CHOICE,
            "Release choice 0x00",
        );
        let bad = AllocationChoice::EXPLICIT | AllocationChoice::ACK_SUPPRESSION;
        let o = r.release_as(r.master_mac(), Port::Group2Only, bad)?;
        r.expect_error(
            c,
            Basis::Unconfirmed,
            &o,
            GeneralStatus::InvalidAttributeValue,
            additional::INVALID_CHOICE,
            "Release choice 0x41 (AN: bit 6 must be 0)",
        );
        Ok(())
    })?;
    r.run(
        "release-lacking-type",
        "releasing a connection type the device lacks: 0x02/0x02",
        CS,
        "§3.4 row 8",
        |r, c| {
            match r.facts.lacking {
                Some(t) => {
                    let o = r.release_as(r.master_mac(), Port::Group2Only, t)?;
                    r.expect_error(
                        c,
                        Basis::Normative,
                        &o,
                        GeneralStatus::ResourceUnavailable,
                        additional::INVALID_CHOICE,
                        &format!("Release {t}"),
                    );
                }
                None => c.advise(Basis::Normative, "not exercised: the device offers every connection type"),
            }
            Ok(())
        },
    )?;
    Ok(())
}

/// The Group 2 Only port's services, the explicit path, re-allocation and the I/O combinations of §II.2.5.
fn ports_and_combinations(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run(
        "group2-only-invalid-service",
        "any other service on the Group 2 Only port: 0x02/0x03",
        CS,
        "§3.4 row 10, §9.6",
        group2_only_service,
    )?;
    r.run(
        "alloc-explicit-path",
        "allocation of the poll connection through the explicit connection; ownership shown",
        CS,
        "§3.4, §2 frames 16-17, §6.1 attr 5, §6.2 attr 5",
        |r, c| {
            let o = r.allocate_as(r.master_mac(), Port::Explicit, AllocationChoice::POLL)?;
            if let Some(data) =
                r.expect_success(c, Basis::Normative, &o, "Allocate poll (explicit connection)")
            {
                c.firm(
                    data.len() == 1,
                    format!(
                        "response data {} is the one-byte body format (also through the explicit connection)",
                        decode::hex(&data)
                    ),
                    o.1,
                );
            }
            ownership(r, c, AllocationChoice::EXPLICIT | AllocationChoice::POLL)?;
            Ok(())
        },
    )?;
    r.run(
        "release-reallocate",
        "release through the explicit connection, ownership dropped, re-allocation",
        CS,
        "§3.4 (release semantics)",
        release_reallocate,
    )?;
    r.run(
        "alloc-io-combinations",
        "every allocation of bit-strobe, COS and cyclic, with and without poll and acknowledge suppression",
        CS,
        "§3.4, §II.2.5",
        io_combinations,
    )?;
    r.run(
        "alloc-cos-with-cyclic",
        "change of state and cyclic together, in one request or one after the other: refused (0x09/0x02)",
        CS,
        "§3.4, §II.0, §II.2.5",
        cos_with_cyclic,
    )?;
    r.run(
        "release-ack-suppression",
        "a release naming acknowledge suppression: 0x09/0x02, the connection kept",
        CS,
        "§3.4 (AN)",
        release_ack_suppression,
    )
}

/// The valid combinations of issue 14 (§II.2.5), each allocated through the Group 2 Only port,
/// shown in DeviceNet attribute 5, and released.
fn io_combinations(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.release_all()?;
    let me = r.master_mac();
    for bits in [0x05u8, 0x11, 0x21, 0x51, 0x61, 0x13, 0x23, 0x53, 0x07] {
        let choice = AllocationChoice::from_bits(bits);
        let o = r.allocate_as(me, Port::Group2Only, choice)?;
        if r.expect_success(c, Basis::Normative, &o, &format!("Allocate 0x{bits:02X} ({choice})")).is_none() {
            continue;
        }
        if let Some((data, i)) = r.read(c, Basis::Normative, class::DEVICENET, 1, 5)? {
            c.expect(
                Basis::Unconfirmed,
                data.as_slice() == [bits, me.as_raw()],
                format!(
                    "DeviceNet allocation information {} shows the choice as requested, 0x{bits:02X}",
                    decode::hex(&data)
                ),
                i,
            );
        }
        let release = choice.difference(AllocationChoice::ACK_SUPPRESSION);
        let o = r.release_as(me, Port::Group2Only, release)?;
        r.expect_success(c, Basis::Normative, &o, &format!("Release 0x{:02X}", release.bits()));
    }
    Ok(())
}

fn cos_with_cyclic(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.release_all()?;
    let me = r.master_mac();
    // Refused at all: NI and OMR (normative); the code by analogy with JB's invalid choice
    // (UNCONFIRMED, §II.0).
    let refused = |r: &mut Runner<'_, '_>, c: &mut Check, o: &super::super::runner::Outcome, what: &str| {
        let accepted = matches!(o.0, Ok(Reply { body: ReplyBody::Success(_), .. }));
        c.firm(!accepted, format!("{what}: {}", if accepted { "accepted" } else { "refused" }), o.1);
        if !accepted {
            r.expect_error(
                c,
                Basis::Unconfirmed,
                o,
                GeneralStatus::InvalidAttributeValue,
                additional::INVALID_CHOICE,
                what,
            );
        }
        accepted
    };
    let o = r.allocate_as(me, Port::Group2Only, AllocationChoice::from_bits(0x31))?;
    if refused(r, c, &o, "Allocate 0x31 (explicit, COS and cyclic)") {
        r.release_all()?;
    }
    let o = r.allocate_as(me, Port::Group2Only, AllocationChoice::from_bits(0x21))?;
    r.expect_success(c, Basis::Normative, &o, "Allocate 0x21 (explicit and cyclic)");
    let o = r.allocate_as(me, Port::Explicit, AllocationChoice::CHANGE_OF_STATE)?;
    refused(r, c, &o, "Allocate COS while cyclic is allocated");
    r.release_all()
}

fn release_ack_suppression(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.release_all()?;
    let me = r.master_mac();
    let o = r.allocate_as(me, Port::Group2Only, AllocationChoice::from_bits(0x51))?;
    if r.expect_success(c, Basis::Normative, &o, "Allocate 0x51 (explicit, COS, acknowledge suppression)")
        .is_none()
    {
        return Ok(());
    }
    let o = r.release_as(me, Port::Explicit, AllocationChoice::ACK_SUPPRESSION)?;
    r.expect_error(
        c,
        Basis::Normative,
        &o,
        GeneralStatus::InvalidAttributeValue,
        additional::INVALID_CHOICE,
        "Release 0x40 (acknowledge suppression alone)",
    );
    if let Some((data, i)) = r.read(c, Basis::Normative, class::DEVICENET, 1, 5)? {
        c.firm(
            data.first().is_some_and(|b| b & 0x10 != 0),
            format!("after it the allocation information {} still has COS", decode::hex(&data)),
            i,
        );
    }
    r.release_all()
}

/// Tries each connection type the device may lack (with explicit, so row 5 does not apply).
fn alloc_lacking(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let me = r.master_mac();
    let mut supported = Vec::new();
    for t in [
        AllocationChoice::BIT_STROBE,
        AllocationChoice::MULTICAST_POLL,
        AllocationChoice::CHANGE_OF_STATE,
        AllocationChoice::CYCLIC,
    ] {
        let choice = AllocationChoice::EXPLICIT | t;
        let o = r.allocate_as(me, Port::Group2Only, choice)?;
        match &o.0 {
            Ok(Reply { body: ReplyBody::Success(_), .. }) => {
                supported.push(t);
                let _ = r.release_as(me, Port::Group2Only, choice)?;
            }
            _ => {
                if r.expect_error(
                    c,
                    Basis::Normative,
                    &o,
                    GeneralStatus::ResourceUnavailable,
                    additional::INVALID_CHOICE,
                    &format!("Allocate {choice}"),
                ) && r.facts.lacking.is_none()
                {
                    r.facts.lacking = Some(t);
                }
            }
        }
    }
    if !supported.is_empty() {
        let names: Vec<String> = supported.iter().map(|t| t.to_string()).collect();
        c.firm(true, format!("offers {} (allocated, then released)", names.join(", ")), None);
    }
    if r.facts.lacking.is_none() {
        c.advise(Basis::Normative, "not exercised: the device offers every connection type");
    }
    Ok(())
}

fn group2_only_service(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let req =
        Request { service: ServiceCode::GetAttributeSingle, class: class::IDENTITY, instance: 1, data: &[1] };
    let o = r.request_as(r.master_mac(), Port::Group2Only, &req)?;
    match &o.0 {
        Ok(Reply {
            body: ReplyBody::Error { general: GeneralStatus::ServiceNotSupported, additional: a },
            ..
        }) if *a == additional::INVALID_GROUP2_ONLY_REQUEST => {
            c.advise(
                Basis::Unconfirmed,
                "Get_Attribute_Single on the Group 2 Only port: 0x08/0x03 (JB uses general status 0x02; protocol §9.6)",
            );
        }
        _ => {
            r.expect_error(
                c,
                Basis::Normative,
                &o,
                GeneralStatus::ResourceUnavailable,
                additional::INVALID_GROUP2_ONLY_REQUEST,
                "Get_Attribute_Single on the Group 2 Only port",
            );
        }
    }
    Ok(())
}

/// DeviceNet attribute 5 shows `choice` and the master; Identity status bit 0 (owned) is set.
fn ownership(r: &mut Runner<'_, '_>, c: &mut Check, choice: AllocationChoice) -> Result<(), HarnessError> {
    let me = r.master_mac();
    if let Some((data, i)) = r.read(c, Basis::Normative, class::DEVICENET, 1, 5)? {
        c.firm(
            data.as_slice() == [choice.bits(), me.as_raw()],
            format!(
                "DeviceNet allocation information {} (expected choice 0x{:02X}, master MAC {me})",
                decode::hex(&data),
                choice.bits()
            ),
            i,
        );
    }
    if let Some((data, i)) = r.read(c, Basis::Normative, class::IDENTITY, 1, 5)? {
        let owned = data.first().is_some_and(|b| b & 1 == 1);
        c.firm(
            owned && data.len() == 2,
            format!("Identity status {} has bit 0 (owned) set", decode::hex(&data)),
            i,
        );
    }
    Ok(())
}

fn release_reallocate(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let me = r.master_mac();
    let second = r.second;
    let o = r.release_as(me, Port::Explicit, AllocationChoice::POLL)?;
    if let Some(d) = r.expect_success(c, Basis::Normative, &o, "Release poll (explicit connection)") {
        c.firm(d.is_empty(), format!("release response without data ({})", decode::hex(&d)), o.1);
    }
    ownership(r, c, AllocationChoice::EXPLICIT)?;
    let o = r.release_as(me, Port::Explicit, AllocationChoice::EXPLICIT)?;
    r.expect_success(c, Basis::Normative, &o, "Release explicit (explicit connection)");
    // Nothing left: ownership dropped, so another master may allocate.
    let o = r.allocate_as(second, Port::Group2Only, AllocationChoice::EXPLICIT)?;
    r.expect_success(
        c,
        Basis::Normative,
        &o,
        &format!("Allocate explicit from master MAC {second} once released"),
    );
    let o = r.release_as(second, Port::Group2Only, AllocationChoice::EXPLICIT)?;
    r.expect_success(
        c,
        Basis::Unconfirmed,
        &o,
        &format!("Release explicit by master MAC {second} (Group 2 Only port)"),
    );
    let o = r.allocate_as(me, Port::Group2Only, AllocationChoice::EXPLICIT)?;
    r.expect_success(c, Basis::Normative, &o, "Allocate explicit again");
    ownership(r, c, AllocationChoice::EXPLICIT)
}
