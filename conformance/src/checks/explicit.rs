//! Explicit messaging: the Identity (§6.2, Get_Attributes_All included), DeviceNet (§6.1) and
//! Connection (§5.1) attributes, settable and not settable ones, errors for unknown targets and
//! services (§3.3), and the fragmentation protocol (§4.1): fragmented request and response, a
//! missing acknowledgement, a duplicated fragment, an out-of-sequence fragment, an oversized
//! request.

use super::super::runner::{parse_ack, Check, Runner, Value};
use super::super::{Basis, Category};
use devicenet::explicit::{GeneralStatus, Request, ServiceCode};
use devicenet::fragment::{FragmentByte, FragmentKind};
use devicenet::id::Group1MessageId;
use devicenet::objects::class;
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant};
use harness_common::error::HarnessError;
use master_core::client::{Port, Reply, ReplyBody};
use master_core::decode::{self, hex};
use master_core::session::Verdict;

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

/// Get_Attributes_All of Identity instance 1 (optional, notes §6.2): the attributes concatenated
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

/// The requests that bring a fragmented response: Identity product name, else Get_Attributes_All.
fn fragmented_response_requests() -> [(ServiceCode, u16, u16, Vec<u8>); 2] {
    [
        (ServiceCode::GetAttributeSingle, class::IDENTITY, 1, vec![7]),
        (ServiceCode::GetAttributesAll, class::IDENTITY, 1, vec![]),
    ]
}

fn fragmented_response(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    for (service, cls, inst, data) in fragmented_response_requests() {
        let start = r.mark();
        let a = Runner::outcome(r.request(Port::Explicit, service, cls, inst, &data))?;
        if let (Err(e), _) = &a {
            let text = super::super::runner::client_error_text(e);
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

fn fragmented_request(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
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
                format!("fragmented request not completed: {}", super::super::runner::client_error_text(e)),
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

fn missing_ack(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
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

fn duplicate_fragment(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
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

fn out_of_sequence(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
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

fn oversized(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
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
