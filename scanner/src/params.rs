//! `params --mac N [--eds FILE] [--set NAME=VALUE ...]`: every parameter of a device read, and
//! written, as a commissioning tool does.
//!
//! Without `--eds` the device's Parameter object (class 0x0F, protocol §II.4) is enumerated: class
//! attribute 2 gives the number of instances; each instance's value (attribute 1), descriptor
//! (4), data type (5), size (6), name (7), units (8), minimum, maximum and default (10–12). With
//! `--eds` the EDS `[Params]` are the list: each parameter is read through its link path (notes
//! §II.4.4: `20 0F 24 NN 30 01` is Parameter instance NN's value), with the EDS's name, units and
//! limits.
//!
//! `--set NAME=VALUE` (names compared without regard to case) writes the value, sized by the
//! parameter's data type, with Set_Attribute_Single through the same path, after the sets the
//! parameters are read again. A refusal (0x09 out of range, 0x0E read-only, 0x0C while an I/O
//! connection is established) is an error naming the parameter and the device's answer.

use devicenet::MacId;
use eds::model::Param;
use eds::value::LinkPath;
use harness_common::error::HarnessError;
use master_core::decode::short_string;
use master_core::error::MasterError;
use master_core::master::Master;

/// The Parameter object.
pub const PARAMETER_CLASS: u16 = 0x0F;

/// One parameter as read.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ParamRow {
    /// Parameter instance, or EDS `ParamN` number.
    pub number: u32,
    /// Name.
    pub name: String,
    /// Where the value lives: class, instance, attribute.
    pub path: (u16, u16, u8),
    /// The value, decoded by its data type.
    pub value: Option<i64>,
    /// Raw value bytes, hex.
    pub raw: String,
    /// Units.
    pub units: String,
    /// Minimum, maximum, default.
    pub min: Option<i64>,
    /// Maximum.
    pub max: Option<i64>,
    /// Default.
    pub default: Option<i64>,
    /// CIP data type code (0xC6 USINT, 0xC7 UINT, 0xC8 UDINT ...).
    pub data_type: u8,
    /// Value size in bytes.
    pub size: u8,
    /// Descriptor bit 4.
    pub read_only: bool,
}

/// Whether a CIP data type code is signed.
fn signed(data_type: u8) -> bool {
    matches!(data_type, 0xC2..=0xC5)
}

/// The value of little-endian `bytes` of `data_type`.
#[must_use]
pub fn decode_value(data_type: u8, bytes: &[u8]) -> Option<i64> {
    if bytes.is_empty() || bytes.len() > 8 {
        return None;
    }
    let mut b = [0u8; 8];
    b.get_mut(..bytes.len())?.copy_from_slice(bytes);
    let unsigned = u64::from_le_bytes(b);
    if signed(data_type) {
        let shift = 64 - 8 * bytes.len() as u32;
        Some(((unsigned << shift) as i64) >> shift)
    } else {
        i64::try_from(unsigned).ok()
    }
}

/// `value` as `size` little-endian bytes, or why it does not fit.
pub fn encode_value(value: i64, size: u8, data_type: u8) -> Result<Vec<u8>, String> {
    let bits = 8 * u32::from(size);
    if !(1..=8).contains(&size) {
        return Err(format!("a {size}-byte value cannot be written"));
    }
    let fits = if signed(data_type) {
        bits >= 64 || (-(1i128 << (bits - 1))..(1i128 << (bits - 1))).contains(&i128::from(value))
    } else {
        value >= 0 && (bits >= 64 || (value as u128) < (1u128 << bits))
    };
    if !fits {
        return Err(format!("{value} does not fit in {size} byte(s) of type 0x{data_type:02X}"));
    }
    Ok(value.to_le_bytes().get(..usize::from(size)).unwrap_or_default().to_vec())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// Reads every parameter of the device's Parameter object.
pub fn read_device(master: &mut Master<'_, '_>, mac: MacId) -> Result<Vec<ParamRow>, HarnessError> {
    let count = master.get_u16(mac, PARAMETER_CLASS, 0, 2)?.unwrap_or(0);
    let mut rows = Vec::new();
    for instance in 1..=count {
        let mut get = |attr: u8| -> Result<Vec<u8>, MasterError> {
            Ok(master.get(mac, PARAMETER_CLASS, instance, attr)?.0)
        };
        let descriptor = get(4)?;
        let data_type = get(5)?.first().copied().unwrap_or(0);
        let size = get(6)?.first().copied().unwrap_or(0);
        let name = short_string(&get(7)?).unwrap_or_default();
        let units = short_string(&get(8)?).unwrap_or_default();
        let value = get(1)?;
        let min = decode_value(data_type, &get(10)?);
        let max = decode_value(data_type, &get(11)?);
        let default = decode_value(data_type, &get(12)?);
        rows.push(ParamRow {
            number: u32::from(instance),
            name,
            path: (PARAMETER_CLASS, instance, 1),
            value: decode_value(data_type, &value),
            raw: hex(&value),
            units,
            min,
            max,
            default,
            data_type,
            size,
            read_only: descriptor.first().is_some_and(|d| d & 0x10 != 0),
        });
    }
    Ok(rows)
}

fn eds_number(v: Option<&eds::value::Value>) -> Option<i64> {
    v.and_then(eds::value::Value::as_int).and_then(|v| i64::try_from(v).ok())
}

/// Reads every EDS parameter through its link path.
pub fn read_eds(
    master: &mut Master<'_, '_>,
    mac: MacId,
    params: &[(u32, Param)],
) -> Result<Vec<ParamRow>, HarnessError> {
    let mut rows = Vec::new();
    for (n, p) in params {
        let Some(address) = p.link_path.as_ref().and_then(LinkPath::attribute) else {
            return Err(HarnessError::ParamWithoutAttribute { number: *n, name: p.name.clone() });
        };
        // A path to a Parameter instance without an attribute means its value, attribute 1.
        let attribute = address.attribute.and_then(|a| u8::try_from(a).ok()).unwrap_or(1);
        let (value, _) = master.get(mac, address.class, address.instance, attribute)?;
        let data_type = p.data_type.and_then(|t| u8::try_from(t.code()).ok()).unwrap_or(0);
        rows.push(ParamRow {
            number: *n,
            name: p.name.clone(),
            path: (address.class, address.instance, attribute),
            value: decode_value(data_type, &value),
            raw: hex(&value),
            units: p.units.clone(),
            min: eds_number(p.min.as_ref()),
            max: eds_number(p.max.as_ref()),
            default: eds_number(p.default.as_ref()),
            data_type,
            size: p
                .data_size
                .and_then(|s| u8::try_from(s).ok())
                .unwrap_or(u8::try_from(value.len()).unwrap_or(0)),
            read_only: p.descriptor.is_some_and(|d| d.0 & 0x10 != 0),
        });
    }
    Ok(rows)
}

/// Parses `NAME=VALUE`.
pub fn parse_assignment(text: &str) -> Result<(String, i64), String> {
    let (name, value) = text.split_once('=').ok_or_else(|| format!("'{text}': expected NAME=VALUE"))?;
    let v = value.trim();
    let parsed = match v.strip_prefix("0x").or_else(|| v.strip_prefix("0X")) {
        Some(h) => i64::from_str_radix(h, 16).ok(),
        None => v.parse::<i64>().ok(),
    };
    let value = parsed.ok_or_else(|| format!("'{text}': '{v}' is not a number"))?;
    Ok((name.trim().to_string(), value))
}

/// Writes `value` to the parameter named `name` among `rows`.
pub fn set(
    master: &mut Master<'_, '_>,
    mac: MacId,
    rows: &[ParamRow],
    name: &str,
    value: i64,
) -> Result<(), HarnessError> {
    let row = rows.iter().find(|r| r.name.eq_ignore_ascii_case(name)).ok_or_else(|| {
        HarnessError::UnknownParameter {
            name: name.to_string(),
            known: rows.iter().map(|r| r.name.clone()).collect(),
        }
    })?;
    let bytes = encode_value(value, row.size, row.data_type)
        .map_err(|e| HarnessError::ParamValue { detail: format!("{name}: {e}") })?;
    let (class_id, instance, attribute) = row.path;
    master.set(mac, class_id, instance, attribute, &bytes).map_err(|e| match e {
        MasterError::ErrorResponse { text, .. } => {
            HarnessError::ParameterRefused { mac, name: row.name.clone(), value, response: text }
        }
        other => other.into(),
    })?;
    Ok(())
}

/// The rows as a table.
#[must_use]
pub fn table(rows: &[ParamRow]) -> String {
    let opt = |v: Option<i64>| v.map_or_else(|| "-".into(), |v| v.to_string());
    let mut text = format!(
        "{:>3}  {:<24} {:>10} {:<6} {:>10} {:>10} {:>10}  {:<14} access\n",
        "#", "name", "value", "units", "min", "max", "default", "path"
    );
    for r in rows {
        text.push_str(&format!(
            "{:>3}  {:<24} {:>10} {:<6} {:>10} {:>10} {:>10}  {:<14} {}\n",
            r.number,
            r.name,
            r.value.map_or_else(|| r.raw.clone(), |v| v.to_string()),
            r.units,
            opt(r.min),
            opt(r.max),
            opt(r.default),
            format!("0x{:02X}/{}/{}", r.path.0, r.path.1, r.path.2),
            if r.read_only { "read-only" } else { "read/write" }
        ));
    }
    text.push_str(&format!("{} parameter(s)", rows.len()));
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_by_type() {
        assert_eq!(decode_value(0xC7, &[0xF4, 0x01]), Some(500));
        assert_eq!(decode_value(0xC3, &[0xFF, 0xFF]), Some(-1));
        assert_eq!(decode_value(0xC8, &[0x80, 0x25, 0, 0]), Some(9600));
        assert_eq!(decode_value(0xC6, &[]), None);
        assert_eq!(encode_value(9600, 4, 0xC8), Ok(vec![0x80, 0x25, 0, 0]));
        assert_eq!(encode_value(-2, 2, 0xC3), Ok(vec![0xFE, 0xFF]));
        assert!(encode_value(256, 1, 0xC6).unwrap_err().contains("does not fit"));
        assert!(encode_value(-1, 2, 0xC7).is_err());
    }

    #[test]
    fn assignments() {
        assert_eq!(parse_assignment("Serial baud=19200"), Ok(("Serial baud".into(), 19200)));
        assert_eq!(parse_assignment("x = 0x10"), Ok(("x".into(), 16)));
        assert!(parse_assignment("x").unwrap_err().contains("NAME=VALUE"));
        assert!(parse_assignment("x=fast").unwrap_err().contains("not a number"));
    }
}
