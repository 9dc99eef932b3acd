//! Explicit messaging: the Identity (§6.2, Get_Attributes_All included), DeviceNet (§6.1) and
//! Connection (§5.1) attributes, settable and not settable ones, errors for unknown targets and
//! services (§3.3), and the fragmentation protocol (§4.1): fragmented request and response, a
//! missing acknowledgement, a duplicated fragment, an out-of-sequence fragment, an oversized
//! request.

use super::super::runner::{Check, Runner, Value};
use super::super::{Basis, Category};
use devicenet::explicit::{GeneralStatus, ServiceCode};
use devicenet::id::Group1MessageId;
use devicenet::objects::class;
use devicenet::{Group2Message, Identifier};
use harness_common::error::HarnessError;
use master_core::client::{Port, Reply, ReplyBody};
use master_core::decode::{self, hex};

mod fragmentation;

use fragmentation::{
    duplicate_fragment, fragmented_request, fragmented_response, missing_ack, out_of_sequence, oversized,
};

const EX: Category = Category::Explicit;

pub(super) fn run(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run("identity-attributes", "Identity attributes 1-8 readable, sizes and values", EX, "§6.2", identity)?;
    r.run(
        "devicenet-attributes",
        "DeviceNet object attributes readable, sizes and values",
        EX,
        "§6.1",
        devicenet_object,
    )?;
    r.run(
        "connection-attributes",
        "Connection instances 1 and 2: attributes 1-9 and 12-17, sizes and values",
        EX,
        "§5.1",
        connection_attributes,
    )?;
    r.run(
        "settable-attributes",
        "settable attributes accept a value, the others answer 0x0E; illegal values 0x09",
        EX,
        "§5.1, §5.4, §6.1, §6.2",
        settable,
    )?;
    r.run(
        "unknown-targets",
        "unknown class and instance: 0x16; unknown attribute: 0x14",
        EX,
        "§3.3",
        unknown_targets,
    )?;
    r.run("unsupported-service", "a service the object lacks: 0x08", EX, "§3.3", unsupported_service)?;
    r.run(
        "fragmented-response",
        "a fragmented response, each fragment acknowledged",
        EX,
        "§4.1",
        fragmented_response,
    )?;
    r.run(
        "fragmented-request",
        "a fragmented request, each fragment acknowledged",
        EX,
        "§4.1",
        fragmented_request,
    )?;
    r.run(
        "missing-ack",
        "an unacknowledged response fragment is re-sent once after ~1 s, then the transfer aborts",
        EX,
        "§4.1, §9.4",
        missing_ack,
    )?;
    r.run(
        "duplicate-fragment",
        "a repeated request fragment is re-acknowledged, not appended twice",
        EX,
        "§4.1",
        duplicate_fragment,
    )?;
    r.run(
        "out-of-sequence-fragment",
        "an out-of-sequence request fragment is not acknowledged and resets reassembly",
        EX,
        "§4.1",
        out_of_sequence,
    )?;
    r.run(
        "oversized-request",
        "a request longer than the device takes: acknowledge status 1 (too much data)",
        EX,
        "§4.1, §5.1 attr 8",
        oversized,
    )
}

fn le(data: &[u8]) -> u64 {
    data.iter().rev().fold(0, |acc, &b| acc << 8 | u64::from(b))
}

/// Reads `attr` and checks its size; returns the value.
fn sized(
    r: &mut Runner<'_, '_>,
    c: &mut Check,
    basis: Basis,
    (class_id, instance, attr): (u16, u16, u8),
    len: usize,
) -> Result<Value, HarnessError> {
    let name = decode::attribute_text(class_id, instance, attr);
    let Some((data, i)) = r.read(c, basis, class_id, instance, attr)? else { return Ok(None) };
    let ok = data.len() == len;
    c.expect(basis, ok, format!("{name} = {} ({} bytes, {len} expected)", hex(&data), data.len()), i);
    Ok(ok.then_some((data, i)))
}

fn identity(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let id = class::IDENTITY;
    let announced = r.facts.announced;
    // Attributes 1-7 as read, for Get_Attributes_All.
    let mut parts: Vec<Option<Vec<u8>>> = Vec::new();
    let v1 = sized(r, c, Basis::Normative, (id, 1, 1), 2)?;
    if let (Some((v, i)), Some((vendor, _, _))) = (&v1, announced) {
        c.firm(
            le(v) == u64::from(vendor),
            format!("vendor ID equals the duplicate MAC ID check's 0x{vendor:04X}"),
            *i,
        );
    }
    parts.push(v1.map(|v| v.0));
    parts.push(sized(r, c, Basis::Normative, (id, 1, 2), 2)?.map(|v| v.0));
    parts.push(sized(r, c, Basis::Normative, (id, 1, 3), 2)?.map(|v| v.0));
    let v4 = sized(r, c, Basis::Normative, (id, 1, 4), 2)?;
    if let Some((v, i)) = &v4 {
        c.firm((1..=127).contains(&v[0]), format!("major revision {} in 1..127", v[0]), *i);
    }
    parts.push(v4.map(|v| v.0));
    parts.push(sized(r, c, Basis::Normative, (id, 1, 5), 2)?.map(|v| v.0));
    let v6 = sized(r, c, Basis::Normative, (id, 1, 6), 4)?;
    if let (Some((v, i)), Some((_, serial, _))) = (&v6, announced) {
        c.firm(
            le(v) == u64::from(serial),
            format!("serial number equals the duplicate MAC ID check's 0x{serial:08X}"),
            *i,
        );
    }
    parts.push(v6.map(|v| v.0));
    let v7 = r.read(c, Basis::Normative, id, 1, 7)?;
    if let Some((v, i)) = &v7 {
        let ok = decode::short_string(v).is_some() && v.len() == 1 + usize::from(v[0]);
        c.firm(
            ok,
            format!(
                "product name {:?} is a SHORT_STRING ({} bytes)",
                decode::short_string(v).unwrap_or_default(),
                v.len()
            ),
            *i,
        );
    }
    parts.push(v7.map(|v| v.0));
    if let Some((v, i)) = sized(r, c, Basis::Normative, (id, 1, 8), 1)? {
        c.firm(v[0] <= 5, format!("state {} in 0..5", v[0]), i);
    }
    // Optional attributes and the class revision: reported, not required.
    for (attr, len) in [(9u8, 2usize), (10, 1)] {
        let a = Runner::outcome(r.get(id, 1, attr))?;
        let name = decode::attribute_text(id, 1, attr);
        match &a.0 {
            Ok(Reply { body: ReplyBody::Success(d), .. }) => {
                c.firm(d.len() == len, format!("optional {name} = {} ({len} bytes expected)", hex(d)), a.1);
            }
            Ok(Reply {
                body: ReplyBody::Error { general: GeneralStatus::AttributeNotSupported, .. },
                ..
            }) => {
                c.firm(true, format!("optional {name}: not supported (0x14)"), a.1);
            }
            _ => {
                r.expect_error(
                    c,
                    Basis::Normative,
                    &a,
                    GeneralStatus::AttributeNotSupported,
                    0xFF,
                    &format!("optional {name}"),
                );
            }
        }
    }
    sized(r, c, Basis::Unconfirmed, (id, 0, 1), 2)?;
    if let Some(parts) = parts.into_iter().collect::<Option<Vec<_>>>() {
        attributes_all(r, c, &parts)?;
    }
    Ok(())
}

/// Get_Attributes_All of Identity instance 1 (optional, protocol §6.2): the attributes concatenated
/// in order, each whole; `parts` are attributes 1-7 as read with Get_Attribute_Single.
fn attributes_all(r: &mut Runner<'_, '_>, c: &mut Check, parts: &[Vec<u8>]) -> Result<(), HarnessError> {
    let a =
        Runner::outcome(r.request(Port::Explicit, ServiceCode::GetAttributesAll, class::IDENTITY, 1, &[]))?;
    let data = match &a.0 {
        Ok(Reply { body: ReplyBody::Success(d), .. }) => d.clone(),
        Ok(Reply { body: ReplyBody::Error { general: GeneralStatus::ServiceNotSupported, .. }, .. }) => {
            c.firm(true, "optional Get_Attributes_All: not supported (0x08)", a.1);
            return Ok(());
        }
        _ => {
            r.expect_error(
                c,
                Basis::Normative,
                &a,
                GeneralStatus::ServiceNotSupported,
                0xFF,
                "optional Get_Attributes_All",
            );
            return Ok(());
        }
    };
    let whole: Vec<u8> = parts.concat();
    // Where each attribute ends in the concatenation: a reply must end on one of these.
    let ends: Vec<usize> = parts
        .iter()
        .scan(0, |end, p| {
            *end += p.len();
            Some(*end)
        })
        .collect();
    let n = data.len();
    if n >= whole.len() {
        c.firm(
            data.starts_with(&whole),
            format!(
                "Get_Attributes_All: {n} bytes, beginning with attributes 1-7 as read one by one ({} bytes){}",
                whole.len(),
                if data.starts_with(&whole) { String::new() } else { format!(": {} differs", hex(&data)) }
            ),
            a.1,
        );
    } else if whole.starts_with(&data) && ends.contains(&n) {
        let k = ends.iter().position(|&e| e == n).map_or(0, |p| p + 1);
        c.advise(
            Basis::Unconfirmed,
            format!(
                "Get_Attributes_All: {n} bytes, attributes 1-{k} only (the CIP Identity object returns 1-7)"
            ),
        );
    } else {
        let inside = ends.iter().position(|&e| e > n).map_or(parts.len(), |p| p + 1);
        c.firm(
            false,
            format!(
                "Get_Attributes_All: {n} bytes ({}) {}",
                hex(&data),
                if whole.starts_with(&data) {
                    format!("end inside attribute {inside}: a reply is whole attributes in order")
                } else {
                    "differ from attributes 1-7 as read one by one".to_string()
                }
            ),
            a.1,
        );
    }
    Ok(())
}

fn devicenet_object(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let dn = class::DEVICENET;
    let (dut, me) = (r.dut(), r.master_mac());
    if let Some((v, i)) = sized(r, c, Basis::Normative, (dn, 1, 1), 1)? {
        c.firm(v[0] == dut.as_raw(), format!("MAC ID {} is the device's", v[0]), i);
    }
    if let Some((v, i)) = sized(r, c, Basis::Normative, (dn, 1, 2), 1)? {
        c.firm(v[0] <= 2, format!("baud rate {} in 0..2", v[0]), i);
    }
    if let Some((v, i)) = sized(r, c, Basis::Normative, (dn, 1, 3), 1)? {
        c.firm(v[0] <= 1, format!("bus-off interrupt {} is a BOOL", v[0]), i);
    }
    sized(r, c, Basis::Normative, (dn, 1, 4), 1)?;
    if let Some((v, i)) = sized(r, c, Basis::Normative, (dn, 1, 5), 2)? {
        c.firm(
            v == [0x01, me.as_raw()],
            format!("allocation information {} = explicit, master {me}", hex(&v)),
            i,
        );
    }
    for attr in 6..=9u8 {
        let a = Runner::outcome(r.get(dn, 1, attr))?;
        let name = decode::attribute_text(dn, 1, attr);
        match &a.0 {
            Ok(Reply { body: ReplyBody::Success(d), .. }) => {
                c.firm(d.len() == 1, format!("{name} = {} (1 byte expected)", hex(d)), a.1);
            }
            Ok(Reply {
                body: ReplyBody::Error { general: GeneralStatus::AttributeNotSupported, .. },
                ..
            }) => {
                c.firm(true, format!("{name}: not supported (0x14; optional, e.g. no switches)"), a.1);
            }
            _ => {
                r.expect_error(c, Basis::Normative, &a, GeneralStatus::AttributeNotSupported, 0xFF, &name);
            }
        }
    }
    sized(r, c, Basis::Unconfirmed, (dn, 0, 1), 2)?;
    Ok(())
}

/// Attributes of one Connection instance with their expected values.
type AttributeTable = Vec<(u8, Want, Basis)>;

/// An expected value of a Connection attribute.
enum Want {
    U8(u8),
    U16(u16),
    /// A UINT of any value (FREE).
    AnyU16,
    Bytes(Vec<u8>),
    /// An EPATH `20 04 24 xx 30 03` (assembly instance xx).
    AssemblyPath,
}

fn connection_attributes(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let epr = r.opts.epr_ms;
    let applied = r.fresh_poll(epr, None)?;
    let dut = r.dut();
    let explicit_rsp = Identifier::group2(dut, Group2Message::ExplicitResponse).as_raw();
    let explicit_req = Identifier::group2(dut, Group2Message::ExplicitRequest).as_raw();
    let poll_rsp = Identifier::group1(Group1MessageId::POLL_RESPONSE, dut).as_raw();
    let poll_cmd = Identifier::group2(dut, Group2Message::PollCommand).as_raw();
    let (produced, consumed) = (r.facts.produced.unwrap_or(0), r.facts.consumed.unwrap_or(0));
    let table: [(u16, AttributeTable); 2] = [
        (
            1,
            vec![
                (1, Want::U8(3), Basis::Normative),
                (2, Want::U8(0), Basis::Normative),
                (3, Want::U8(0x83), Basis::Normative),
                (4, Want::U16(explicit_rsp), Basis::Normative),
                (5, Want::U16(explicit_req), Basis::Normative),
                (6, Want::U8(0x21), Basis::Normative),
                (7, Want::AnyU16, Basis::Free),
                (8, Want::AnyU16, Basis::Free),
                (9, Want::U16(2500), Basis::Normative),
                (12, Want::U8(1), Basis::Normative),
                (13, Want::U16(0), Basis::Normative),
                (14, Want::Bytes(Vec::new()), Basis::Normative),
                (15, Want::U16(0), Basis::Normative),
                (16, Want::Bytes(Vec::new()), Basis::Normative),
                (17, Want::AnyU16, Basis::Free),
            ],
        ),
        (
            2,
            vec![
                (1, Want::U8(3), Basis::Normative),
                (2, Want::U8(1), Basis::Normative),
                (3, Want::U8(0x82), Basis::Unconfirmed),
                (4, Want::U16(poll_rsp), Basis::Normative),
                (5, Want::U16(poll_cmd), Basis::Normative),
                (6, Want::U8(0x01), Basis::Normative),
                (7, Want::U16(produced), Basis::Normative),
                (8, Want::U16(consumed), Basis::Normative),
                (9, Want::U16(applied), Basis::Normative),
                (12, Want::U8(0), Basis::Normative),
                (13, Want::U16(6), Basis::Normative),
                (14, Want::AssemblyPath, Basis::Normative),
                (15, Want::U16(6), Basis::Normative),
                (16, Want::AssemblyPath, Basis::Normative),
                (17, Want::AnyU16, Basis::Free),
            ],
        ),
    ];
    for (inst, attrs) in table {
        for (attr, want, basis) in attrs {
            let name = format!("inst {inst} {}", decode::attribute_text(class::CONNECTION, inst, attr));
            let Some((v, i)) = r.read(c, Basis::Normative, class::CONNECTION, inst, attr)? else { continue };
            let shown = decode::value_text(class::CONNECTION, inst, attr, &v);
            let (size_ok, value_ok, expected) = match &want {
                Want::U8(x) => (v.len() == 1, v.first() == Some(x), format!("{x} (0x{x:02X})")),
                Want::U16(x) => (v.len() == 2, le(&v) == u64::from(*x), format!("{x} (0x{x:04X})")),
                Want::AnyU16 => (v.len() == 2, true, "a UINT".into()),
                Want::Bytes(b) => (true, &v == b, if b.is_empty() { "empty".into() } else { hex(b) }),
                Want::AssemblyPath => (
                    true,
                    matches!(v.as_slice(), [0x20, 0x04, 0x24, _, 0x30, 0x03]),
                    "20 04 24 <assembly> 30 03".into(),
                ),
            };
            c.firm(size_ok, format!("{name}: {} bytes", v.len()), i);
            if size_ok {
                c.expect(basis, value_ok, format!("{name} = {shown} (expected {expected})"), i);
            }
            if inst == 1 && attr == 8 && v.len() == 2 {
                r.facts.explicit_consumed = Some(le(&v) as u16);
            }
            if inst == 2 && attr == 16 {
                if let [0x20, 0x04, 0x24, asm, 0x30, 0x03] = v.as_slice() {
                    r.facts.output_assembly = Some(u16::from(*asm));
                }
            }
        }
    }
    Ok(())
}

fn settable(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let epr = r.opts.epr_ms;
    r.fresh_poll(epr, None)?;
    let not_settable = |r: &mut Runner<'_, '_>,
                        c: &mut Check,
                        cls: u16,
                        inst: u16,
                        attr: u8,
                        value: &[u8],
                        basis: Basis|
     -> Result<(), HarnessError> {
        let o = Runner::outcome(r.set(cls, inst, attr, value))?;
        let what = format!(
            "Set {} inst {inst} {}",
            decode::class_text(cls),
            decode::attribute_text(cls, inst, attr)
        );
        r.expect_error(c, basis, &o, GeneralStatus::AttributeNotSettable, 0xFF, &what);
        Ok(())
    };
    let settable = |r: &mut Runner<'_, '_>,
                    c: &mut Check,
                    cls: u16,
                    inst: u16,
                    attr: u8,
                    value: &[u8],
                    basis: Basis|
     -> Result<(), HarnessError> {
        let o = Runner::outcome(r.set(cls, inst, attr, value))?;
        let what = format!(
            "Set {} inst {inst} {} = {}",
            decode::class_text(cls),
            decode::attribute_text(cls, inst, attr),
            hex(value)
        );
        r.expect_success(c, basis, &o, &what);
        Ok(())
    };
    let invalid = |r: &mut Runner<'_, '_>,
                   c: &mut Check,
                   cls: u16,
                   inst: u16,
                   attr: u8,
                   value: &[u8],
                   basis: Basis|
     -> Result<(), HarnessError> {
        let o = Runner::outcome(r.set(cls, inst, attr, value))?;
        let what = format!(
            "Set {} inst {inst} {} = {} (illegal)",
            decode::class_text(cls),
            decode::attribute_text(cls, inst, attr),
            hex(value)
        );
        r.expect_error(c, basis, &o, GeneralStatus::InvalidAttributeValue, 0xFF, &what);
        Ok(())
    };
    // Identity: nothing settable among 1-8 (§6.2).
    for (attr, value) in [
        (1u8, vec![0, 0]),
        (2, vec![0, 0]),
        (3, vec![0, 0]),
        (4, vec![1, 0]),
        (5, vec![0, 0]),
        (6, vec![0; 4]),
        (7, vec![0]),
        (8, vec![3]),
    ] {
        not_settable(r, c, class::IDENTITY, 1, attr, &value, Basis::Normative)?;
    }
    // DeviceNet: 5-9 get only; 3 (BOI) settable, written with its own value; 4 only to 0.
    for attr in 5..=9u8 {
        let value: &[u8] = if attr == 5 { &[0, 0] } else { &[0] };
        not_settable(r, c, class::DEVICENET, 1, attr, value, Basis::Normative)?;
    }
    if let Some(boi) = r.read_u8(class::DEVICENET, 1, 3)? {
        settable(r, c, class::DEVICENET, 1, 3, &[boi], Basis::Normative)?;
    }
    settable(r, c, class::DEVICENET, 1, 4, &[0], Basis::Unconfirmed)?;
    invalid(r, c, class::DEVICENET, 1, 4, &[1], Basis::Unconfirmed)?;
    // Connections: only 9 and 12 settable (JB); watchdog actions per kind (§5.4).
    for inst in [1u16, 2] {
        for attr in (1..=8u8).chain(13..=17) {
            let value: &[u8] = match attr {
                1..=3 | 6 => &[0],
                14 | 16 => &[0x20, 0x04],
                _ => &[0, 0],
            };
            not_settable(r, c, class::CONNECTION, inst, attr, value, Basis::Normative)?;
        }
    }
    let Some(explicit_epr) = r.read(c, Basis::Normative, class::CONNECTION, 1, 9)?.map(|v| v.0) else {
        return Ok(());
    };
    settable(r, c, class::CONNECTION, 1, 9, &explicit_epr, Basis::Normative)?;
    settable(r, c, class::CONNECTION, 1, 12, &[3], Basis::Normative)?;
    settable(r, c, class::CONNECTION, 1, 12, &[1], Basis::Normative)?;
    invalid(r, c, class::CONNECTION, 1, 12, &[0], Basis::Normative)?;
    invalid(r, c, class::CONNECTION, 1, 12, &[2], Basis::Normative)?;
    for action in [0u8, 1, 2] {
        // JB makes it read-only on the poll connection: stricter than required, so advisory.
        let o = Runner::outcome(r.set(class::CONNECTION, 2, 12, &[action]))?;
        r.expect_success(
            c,
            Basis::Unconfirmed,
            &o,
            &format!("Set Connection inst 2 watchdog timeout action = {action}"),
        );
    }
    invalid(r, c, class::CONNECTION, 2, 12, &[3], Basis::Normative)?;
    Ok(())
}

fn unknown_targets(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    // Class 0xC8 is in the reserved range: no device implements it.
    for (cls, inst, attr, general, what) in [
        (0xC8u16, 1u16, 1u8, GeneralStatus::ObjectDoesNotExist, "reserved class 0xC8"),
        (class::IDENTITY, 7, 1, GeneralStatus::ObjectDoesNotExist, "Identity instance 7"),
        (
            class::CONNECTION,
            3,
            1,
            GeneralStatus::ObjectDoesNotExist,
            "Connection instance 3 (bit-strobe, not allocated)",
        ),
        (class::IDENTITY, 1, 0x63, GeneralStatus::AttributeNotSupported, "Identity attribute 99"),
        (class::DEVICENET, 1, 0x63, GeneralStatus::AttributeNotSupported, "DeviceNet attribute 99"),
    ] {
        let o = Runner::outcome(r.get(cls, inst, attr))?;
        match &o.0 {
            Ok(Reply {
                body:
                    ReplyBody::Error {
                        general: g @ (GeneralStatus::PathDestinationUnknown | GeneralStatus::PathSegmentError),
                        additional,
                    },
                ..
            }) if general == GeneralStatus::ObjectDoesNotExist => {
                c.advise(
                    Basis::Unconfirmed,
                    format!(
                        "Get {what}: {} (JB answers 0x16 object does not exist)",
                        decode::error_text(*g, *additional)
                    ),
                );
            }
            _ => {
                r.expect_error(c, Basis::Normative, &o, general, 0xFF, &format!("Get {what}"));
            }
        }
    }
    Ok(())
}

fn unsupported_service(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    for (service, cls, inst, what) in [
        (ServiceCode::from(0x06), class::IDENTITY, 1u16, "Start (0x06) on Identity"),
        (ServiceCode::from(0x02), class::CONNECTION, 1, "Set_Attributes_All (0x02) on Connection inst 1"),
        (ServiceCode::from(0x07), class::DEVICENET, 1, "Stop (0x07) on DeviceNet"),
    ] {
        let o = Runner::outcome(r.request(Port::Explicit, service, cls, inst, &[]))?;
        r.expect_error(c, Basis::Normative, &o, GeneralStatus::ServiceNotSupported, 0xFF, what);
    }
    Ok(())
}
