//! The Parameter object, class [`PARAMETER_CLASS`] 0x0F (protocol §II.4): the settings a
//! commissioning tool edits one by one, each an instance, described once in [`PARAMETERS`] for the
//! object handler and the EDS generator (`eds::generate`, whose `ParamN` is instance N).
//!
//! | instance | name | type | range | units |
//! |---|---|---|---|---|
//! | 1 | Serial baud rate | UDINT | 300..=4 000 000 | baud |
//! | 2 | Serial parity | USINT | 0 none, 1 odd, 2 even | |
//! | 3 | Serial stop bits | USINT | 1, 2 | |
//! | 4 | Stale timeout | UDINT | 1..=3 600 000 | ms |
//! | 5 | Stale policy | USINT | 0 hold last value, 1 clear to zero | |
//! | 6 | Input assembly | USINT | 100, 101 | |
//! | 7 | Response timeout | UDINT | 1..=60 000 | ms |
//! | 8 | Retries | USINT | 0..=10 | |
//! | 9 | Poll period | UDINT | 0..=3 600 000 (Modbus; read-only 0 for a framed instrument) | ms |
//!
//! The Modbus poll period is present whatever the profile, so the instance numbers (and the EDS
//! parameter numbers) do not move with it; for a framed instrument it is read-only (descriptor
//! bit 4) with the value 0, and a Set answers 0x0E.
//!
//! ## Attributes (§II.4.1, §II.4.2)
//!
//! Class (instance 0): 1 revision (UINT 1), 2 max instance (UINT 9), 8 class descriptor (WORD
//! 0x0B: parameter instances, full attributes, stored in non-volatile memory; no Save service is
//! needed, bit 2 clear), 9 configuration assembly (UINT 0, none), 10 native language (USINT 0,
//! English). Instances: 1 value, 2 link path size (0), 3 link path (empty: the value lives here),
//! 4 descriptor (0, or 0x10 read-only), 5 data type (0xC6 USINT, 0xC8 UDINT), 6 data size,
//! 7 name (≤ 16 characters), 8 units (≤ 4), 9 help (≤ [`MAX_HELP`], so that the reply fits one
//! explicit message), 10 minimum, 11 maximum, 12 default. Enumerated strings (descriptor bit 1,
//! Get_Enum_String) are not served: the EDS carries them.
//!
//! ## Which configuration a value is
//!
//! Nothing applies at once. A Set changes the **pending** configuration: the image a download or
//! an earlier Set left for the next reset, or else the image in force. The new value is written
//! into its bytes ([`Parameter::patch`]), the image is decoded and checked again as a download is
//! ([`image::decode`], [`ConverterConfig::check`], the platform's check) and handed to the
//! application exactly as an accepted download is
//! ([`Converter::poll_new_image`](super::Converter::poll_new_image), configuration object state 2
//! "pending"); it is in force from the next reset. So attribute 1 (value) answers the pending
//! value, what a tool just wrote and what the device will run with; attribute 12 (default) is the
//! value in force since start (the description's value until a download), which the settings
//! object (class 0x65) also shows.
//!
//! ## Services and errors (§II.4.3, protocol §3.3)
//!
//! Get_Attribute_Single (class and instances) and Set_Attribute_Single (instance attribute 1);
//! every error has no additional code (0xFF):
//!
//! | reply | when |
//! |---|---|
//! | 0x08 service not supported | any other service, or a Set on the class |
//! | 0x09 invalid attribute value | a value outside minimum..=maximum, or one the whole configuration refuses |
//! | 0x0C object state conflict | a Set while an I/O connection is established; a Get or Set of the value after a new download began when the pending image had already been handed over (its bytes are gone, it still applies at the reset) |
//! | 0x0E attribute not settable | a Set of attributes 2–12, or of a read-only parameter |
//! | 0x13 / 0x15 not enough / too much data | a Set whose value is not the parameter's size, a Get without or with more than the attribute id |
//! | 0x14 attribute not supported | an unknown attribute |
//! | 0x16 object does not exist | instance 0 for a Set, or an instance above 9 |

use super::config_object::ConfigObject;
use super::image::{self, Layout, MAX_IMAGE};
use super::objects::{AttributeType, SettingsAttribute, SettingsValues};
use super::{ConverterConfig, InputAssembly};
use crate::serial::{HealthConfig, Parity, ProfileConfig, SequencerConfig, SerialSettings, StopBits};
use devicenet::explicit::{Request, ServiceCode};
use devicenet::slave::config::MAX_EXPLICIT_SIZE;
use devicenet::slave::{Reply, ServiceError};
use heapless::Vec;

/// The Parameter object class (protocol §II.4).
pub const PARAMETER_CLASS: u16 = 0x0F;
/// Class attribute 8, the parameter class descriptor: bit 0 parameter instances, bit 1 full
/// attributes, bit 3 stored in non-volatile memory (§II.4.1).
pub const CLASS_DESCRIPTOR: u16 = 0x0B;
/// Instance attribute 4 bit 4: read only (§II.4.2).
pub const READ_ONLY: u16 = 0x10;
/// The longest help string (attribute 9): header, service, length byte and the text within one
/// explicit message.
pub const MAX_HELP: usize = MAX_EXPLICIT_SIZE - 4;

/// The parameters; the discriminant is the instance number.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Parameter {
    /// The serial bit rate, baud.
    SerialBaud = 1,
    /// The serial parity: 0 none, 1 odd, 2 even.
    SerialParity = 2,
    /// Stop bits: 1 or 2.
    SerialStopBits = 3,
    /// The stale timeout, ms.
    StaleTimeout = 4,
    /// The stale policy: 0 hold last value, 1 clear to zero.
    StalePolicy = 5,
    /// The produced input assembly instance (100 or 101).
    InputAssembly = 6,
    /// The response timeout, ms.
    ResponseTimeout = 7,
    /// Retries after a timeout.
    Retries = 8,
    /// The Modbus poll period, ms (read-only 0 for a framed instrument).
    PollPeriod = 9,
}

/// One parameter: what attributes 5–11 say about it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ParameterDef {
    /// The parameter (its instance number).
    pub parameter: Parameter,
    /// Attribute 7, ≤ 16 characters.
    pub name: &'static str,
    /// Attribute 8, ≤ 4 characters, empty when the value has none.
    pub units: &'static str,
    /// Attribute 9, ≤ [`MAX_HELP`] characters.
    pub help: &'static str,
    /// Attributes 5 and 6.
    pub data_type: AttributeType,
    /// Attribute 10.
    pub min: u32,
    /// Attribute 11.
    pub max: u32,
}

const fn def(
    parameter: Parameter,
    name: &'static str,
    units: &'static str,
    help: &'static str,
    data_type: AttributeType,
    min: u32,
    max: u32,
) -> ParameterDef {
    ParameterDef { parameter, name, units, help, data_type, min, max }
}

/// Every parameter; instance N is `PARAMETERS[N - 1]`. The ranges are those
/// [`ConverterConfig::check`] accepts (Modbus and framed limits are the same).
pub const PARAMETERS: [ParameterDef; 9] = {
    use AttributeType::{Udint, Usint};
    use Parameter as P;
    [
        def(
            P::SerialBaud,
            "Serial baud rate",
            "baud",
            "Bit rate of the serial line to the instrument",
            Udint,
            SerialSettings::MIN_BAUD,
            SerialSettings::MAX_BAUD,
        ),
        def(P::SerialParity, "Serial parity", "", "Parity bit: 0 none, 1 odd, 2 even", Usint, 0, 2),
        def(P::SerialStopBits, "Serial stop bits", "", "Stop bits per character: 1 or 2", Usint, 1, 2),
        def(
            P::StaleTimeout,
            "Stale timeout",
            "ms",
            "Time without a good answer before the link is stale",
            Udint,
            1,
            HealthConfig::MAX_STALE_TIMEOUT_MS,
        ),
        def(
            P::StalePolicy,
            "Stale policy",
            "",
            "Inputs while stale: 0 hold last value, 1 clear",
            Usint,
            0,
            1,
        ),
        def(
            P::InputAssembly,
            "Input assembly",
            "",
            "Poll produces 100 data, or 101 data and link status",
            Usint,
            super::PLAIN_INPUT_ASSEMBLY as u32,
            super::STATUS_INPUT_ASSEMBLY as u32,
        ),
        def(
            P::ResponseTimeout,
            "Response timeout",
            "ms",
            "Wait for an answer, from the end of the request",
            Udint,
            1,
            SequencerConfig::MAX_RESPONSE_TIMEOUT_MS,
        ),
        def(
            P::Retries,
            "Retries",
            "",
            "Repetitions of a request after a timeout",
            Usint,
            0,
            SequencerConfig::MAX_RETRIES as u32,
        ),
        def(
            P::PollPeriod,
            "Poll period",
            "ms",
            "Modbus scan cycle period; read-only for framed serial",
            Udint,
            0,
            crate::serial::modbus::ModbusConfig::MAX_POLL_PERIOD_MS,
        ),
    ]
};

// The limits of §II.4.2 and of one explicit message, and instance N at index N - 1, checked at
// compile time (indexing in a const block fails the build, never the device).
#[allow(clippy::indexing_slicing)]
const _: () = {
    let mut i = 0;
    while i < PARAMETERS.len() {
        let d = &PARAMETERS[i];
        assert!(d.parameter as usize == i + 1);
        assert!(d.name.len() <= 16 && d.units.len() <= 4 && d.help.len() <= MAX_HELP);
        i += 1;
    }
};

impl Parameter {
    /// The instance number.
    pub const fn instance(self) -> u8 {
        self as u8
    }

    /// Its definition.
    #[allow(clippy::indexing_slicing)] // The discriminants are 1..=9, checked at compile time above.
    pub const fn def(self) -> &'static ParameterDef {
        &PARAMETERS[self as usize - 1]
    }

    /// Whether the parameter can be set in `config` (the poll period only for Modbus).
    pub fn settable(self, config: &ConverterConfig) -> bool {
        self != Parameter::PollPeriod || matches!(config.profile, ProfileConfig::Modbus(_))
    }

    /// Attribute 4: 0, or [`READ_ONLY`] when it cannot be set in `config`.
    pub fn descriptor(self, config: &ConverterConfig) -> u16 {
        if self.settable(config) {
            0
        } else {
            READ_ONLY
        }
    }

    /// Its value in `config`.
    pub fn read(self, config: &ConverterConfig) -> u32 {
        match (self, &config.profile) {
            (Parameter::PollPeriod, ProfileConfig::Modbus(m)) => m.poll_period_ms,
            (Parameter::PollPeriod, ProfileConfig::Framed(_)) => 0,
            // Instances 1-8 are the settings object's attributes 1-8 (tested).
            _ => SettingsAttribute::from_id(self.instance())
                .map_or(0, |a| a.read(&SettingsValues::of_config(&config.profile, config.input))),
        }
    }

    /// Writes `value`, already within the definition's range and [settable](Parameter::settable),
    /// into `image`, the image of `current`, at its place in `layout`
    /// ([`image::decode_with_layout`]), coded as the image codes it ([`image::serial_format`],
    /// [`image::input_code`]). The caller [`image::reseal`]s the image and decodes it again: the
    /// device changes a setting without an encoder of the whole configuration.
    pub fn patch(self, image: &mut [u8], layout: &Layout, current: &ConverterConfig, value: u32) {
        // Where the value lies and how many bytes it takes; then what those bytes are. One write
        // for every parameter (firmware size).
        let (at, len) = match self {
            Parameter::SerialBaud => (layout.serial, 4),
            Parameter::SerialParity | Parameter::SerialStopBits => (layout.serial + 4, 1),
            Parameter::StaleTimeout => (layout.health, 4),
            Parameter::StalePolicy => (layout.health + 4, 1),
            Parameter::InputAssembly => (layout.input, 1),
            Parameter::ResponseTimeout => (layout.timing, 4),
            Parameter::Retries => (layout.timing + 4, 1),
            Parameter::PollPeriod => (layout.timing + 5, 4),
        };
        let value = match self {
            Parameter::SerialParity | Parameter::SerialStopBits => {
                let mut serial = *current.profile.serial();
                if self == Parameter::SerialParity {
                    serial.parity = match value {
                        0 => Parity::None,
                        1 => Parity::Odd,
                        _ => Parity::Even,
                    };
                } else {
                    serial.stop_bits = if value == 2 { StopBits::Two } else { StopBits::One };
                }
                u32::from(image::serial_format(&serial))
            }
            Parameter::InputAssembly => {
                u32::from(image::input_code(if value == u32::from(super::PLAIN_INPUT_ASSEMBLY) {
                    InputAssembly::Plain
                } else {
                    InputAssembly::WithStatus
                }))
            }
            _ => value,
        };
        let at = usize::from(at);
        if let (Some(dst), Some(src)) = (image.get_mut(at..at + len), value.to_le_bytes().get(..len)) {
            dst.copy_from_slice(src);
        }
    }

    /// Writes `value`, already within the definition's range, into `config`; `false` when it
    /// cannot be set there (the poll period of a framed instrument). The tests' oracle for
    /// [`Parameter::patch`].
    #[cfg(test)]
    pub fn write(self, config: &mut ConverterConfig, value: u32) -> bool {
        use crate::serial::StalePolicy;
        let (serial, health, timeout, retries, period) = match &mut config.profile {
            ProfileConfig::Framed(f) => {
                let s = &mut f.sequencer;
                (&mut f.serial, &mut f.health, &mut s.response_timeout_ms, &mut s.retries, None)
            }
            ProfileConfig::Modbus(m) => (
                &mut m.serial,
                &mut m.health,
                &mut m.response_timeout_ms,
                &mut m.retries,
                Some(&mut m.poll_period_ms),
            ),
        };
        match self {
            Parameter::SerialBaud => serial.baud = value,
            Parameter::SerialParity => {
                serial.parity = match value {
                    0 => Parity::None,
                    1 => Parity::Odd,
                    _ => Parity::Even,
                }
            }
            Parameter::SerialStopBits => {
                serial.stop_bits = if value == 1 { StopBits::One } else { StopBits::Two }
            }
            Parameter::StaleTimeout => health.stale_timeout_ms = value,
            Parameter::StalePolicy => {
                health.stale_policy = if value == 0 { StalePolicy::HoldLastValue } else { StalePolicy::Clear }
            }
            Parameter::InputAssembly => {
                config.input = if value == u32::from(super::PLAIN_INPUT_ASSEMBLY) {
                    InputAssembly::Plain
                } else {
                    InputAssembly::WithStatus
                }
            }
            Parameter::ResponseTimeout => *timeout = value,
            Parameter::Retries => *retries = value as u8,
            Parameter::PollPeriod => match period {
                Some(p) => *p = value,
                None => return false,
            },
        }
        true
    }
}

/// Serves a request to [`PARAMETER_CLASS`]; `io_established` says whether an I/O (poll)
/// connection is established. See the [module docs](self).
pub(super) fn handle(
    config: &mut ConfigObject,
    req: &Request<'_>,
    reply: &mut Reply<'_>,
    io_established: bool,
) -> Result<(), ServiceError> {
    let get = req.service == ServiceCode::GetAttributeSingle;
    if req.instance == 0 && get {
        let &[attr] = req.data else {
            return Err(ServiceError::wrong_length(req.data, 1));
        };
        return match attr {
            1 => reply.u16(1),
            2 => reply.u16(PARAMETERS.len() as u16),
            8 => reply.u16(CLASS_DESCRIPTOR),
            9 => reply.u16(0),
            10 => reply.u8(0),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        };
    }
    let def = match usize::from(req.instance).checked_sub(1).and_then(|i| PARAMETERS.get(i)) {
        Some(def) if get || req.service == ServiceCode::SetAttributeSingle => def,
        Some(_) => return Err(ServiceError::SERVICE_NOT_SUPPORTED),
        None if req.instance == 0 => return Err(ServiceError::SERVICE_NOT_SUPPORTED),
        None => return Err(ServiceError::OBJECT_DOES_NOT_EXIST),
    };
    let p = def.parameter;
    let t = def.data_type;
    let (attr, data) = if get {
        let &[attr] = req.data else {
            return Err(ServiceError::wrong_length(req.data, 1));
        };
        match attr {
            1 | 4 | 12 => {}
            2 => return reply.u8(0),
            3 => return Ok(()),
            5 => return reply.u8(t.cip_code()),
            6 => return reply.u8(t.size() as u8),
            7 => return reply.short_string(def.name),
            8 => return reply.short_string(def.units),
            9 => return reply.short_string(def.help),
            10 => return put(reply, t, def.min),
            11 => return put(reply, t, def.max),
            _ => return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
        (attr, &[][..])
    } else {
        let Some((&attr, data)) = req.data.split_first() else {
            return Err(ServiceError::NOT_ENOUGH_DATA);
        };
        match attr {
            1 => {}
            2..=12 => return Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            _ => return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
        (attr, data)
    };
    // One decode for every request that needs the configuration (one call site: the configuration
    // is large): the default (attribute 12) is the image in force, everything else the pending
    // image. `None` (the pending image is gone) is an object state conflict, and so would be an
    // image that does not decode (the image in force always does).
    let bytes = if attr == 12 { Some(config.in_force()) } else { config.base() };
    let Some(bytes) = bytes else {
        return Err(ServiceError::OBJECT_STATE_CONFLICT);
    };
    // Read through a reference: the decoded configuration stays where `decode_with_layout` wrote
    // it, not moved out of its `Result` (firmware size).
    let decoded = image::decode_with_layout(bytes);
    let Ok((current, layout)) = &decoded else {
        return Err(ServiceError::OBJECT_STATE_CONFLICT);
    };
    if get {
        return match attr {
            4 => reply.u16(p.descriptor(current)),
            _ => put(reply, t, p.read(current)),
        };
    }
    let mut patched: Vec<u8, MAX_IMAGE> = Vec::new();
    // The bytes decoded, so they fit.
    let _ = patched.extend_from_slice(bytes);
    if !p.settable(current) {
        return Err(ServiceError::ATTRIBUTE_NOT_SETTABLE);
    }
    let value = match t {
        AttributeType::Udint => match *data {
            [a, b, c, d] => u32::from_le_bytes([a, b, c, d]),
            _ => return Err(ServiceError::wrong_length(data, 4)),
        },
        AttributeType::Usint | AttributeType::Byte => match *data {
            [v] => v.into(),
            _ => return Err(ServiceError::wrong_length(data, 1)),
        },
    };
    // A tool commissioning over a running poll connection is refused, as a download is
    // (§II.4.3: "object state conflict" while the I/O connection is established).
    if io_established {
        return Err(ServiceError::OBJECT_STATE_CONFLICT);
    }
    if value < def.min || value > def.max {
        return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
    }
    // The whole configuration is checked again, as a download is (the platform's check too).
    p.patch(&mut patched, layout, current, value);
    image::reseal(&mut patched);
    if config.check(&patched).is_err() {
        return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
    }
    config.stage(&patched);
    Ok(())
}

/// A value of type `t`.
fn put(reply: &mut Reply<'_>, t: AttributeType, value: u32) -> Result<(), ServiceError> {
    match t {
        AttributeType::Udint => reply.u32(value),
        // One-byte types: the value is within the definition's range (tested).
        AttributeType::Usint | AttributeType::Byte => reply.u8(value as u8),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::converter::{ConfigOrigin, ConfigState, ConverterConfig};
    use crate::serial::modbus::{Function, ModbusConfig, ScanEntry};
    use rstest::rstest;
    use std::vec::Vec;

    fn image_of(config: &ConverterConfig) -> Vec<u8> {
        image::encode_to_vec(config).unwrap()
    }

    #[test]
    fn patch_writes_what_write_writes_for_every_value_of_every_parameter() {
        for config in [ConverterConfig::breaker_reference(), modbus()] {
            let base = image_of(&config);
            let (_, layout) = image::decode_with_layout(&base).unwrap();
            for d in PARAMETERS.iter().filter(|d| d.parameter.settable(&config)) {
                let values = [d.min, d.max, (d.min + d.max) / 2, d.min + 1, d.max.saturating_sub(1)];
                for v in values {
                    let mut expected = config.clone();
                    assert!(d.parameter.write(&mut expected, v));
                    let mut patched = base.clone();
                    d.parameter.patch(&mut patched, &layout, &config, v);
                    image::reseal(&mut patched);
                    match expected.check() {
                        Ok(()) => {
                            expected.device = expected.device_config();
                            assert_eq!(image::decode(&patched), Ok(expected), "{:?} = {v}", d.parameter);
                        }
                        Err(e) => {
                            assert_eq!(image::decode(&patched), Err(e.into()), "{:?} = {v}", d.parameter)
                        }
                    }
                }
            }
        }
    }

    fn object_for(config: &ConverterConfig) -> ConfigObject {
        ConfigObject::new(&image_of(config), ConfigOrigin::FactoryDefault)
    }

    fn object() -> ConfigObject {
        object_for(&ConverterConfig::breaker_reference())
    }

    fn modbus() -> ConverterConfig {
        let scan = heapless::Vec::from_iter([ScanEntry {
            unit: 1,
            function: Function::ReadInputRegisters,
            address: 0,
            count: 2,
            offset: 0,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        }]);
        let mut m = ModbusConfig::new(scan);
        m.input_len = 4;
        ConverterConfig { profile: ProfileConfig::Modbus(m), ..ConverterConfig::breaker_reference() }
    }

    /// Runs one request: `Ok(reply bytes)` or `Err((general status, additional code))`.
    fn call(
        o: &mut ConfigObject,
        instance: u16,
        service: u8,
        data: &[u8],
        io: bool,
    ) -> Result<Vec<u8>, (u8, u8)> {
        let req = Request { service: ServiceCode::from(service), class: PARAMETER_CLASS, instance, data };
        let mut buf = [0u8; MAX_EXPLICIT_SIZE];
        let mut reply = Reply::new(&mut buf);
        match handle(o, &req, &mut reply, io) {
            Ok(()) => {
                let n = reply.len();
                Ok(buf[..n].to_vec())
            }
            Err(e) => Err((e.general.as_raw(), e.additional)),
        }
    }

    fn get(o: &mut ConfigObject, instance: u16, attr: u8) -> Result<Vec<u8>, (u8, u8)> {
        call(o, instance, 0x0E, &[attr], false)
    }

    fn set(o: &mut ConfigObject, instance: u16, value: &[u8], io: bool) -> Result<Vec<u8>, (u8, u8)> {
        let mut data = std::vec![1];
        data.extend_from_slice(value);
        call(o, instance, 0x10, &data, io)
    }

    fn string(s: &str) -> Vec<u8> {
        let mut v = std::vec![s.len() as u8];
        v.extend_from_slice(s.as_bytes());
        v
    }

    #[rstest]
    #[case::revision(1, Ok(std::vec![1, 0]))]
    #[case::max_instance(2, Ok(std::vec![9, 0]))]
    #[case::class_descriptor(8, Ok(std::vec![0x0B, 0]))]
    #[case::config_assembly(9, Ok(std::vec![0, 0]))]
    #[case::native_language(10, Ok(std::vec![0]))]
    #[case::unknown(3, Err((0x14, 0xFF)))]
    fn class_attributes(#[case] attr: u8, #[case] expected: Result<Vec<u8>, (u8, u8)>) {
        assert_eq!(get(&mut object(), 0, attr), expected);
    }

    // Instance 4, the stale timeout of the breaker (3000 ms).
    #[rstest]
    #[case::value(1, Ok(3000u32.to_le_bytes().to_vec()))]
    #[case::link_path_size(2, Ok(std::vec![0]))]
    #[case::link_path(3, Ok(Vec::new()))]
    #[case::descriptor(4, Ok(std::vec![0, 0]))]
    #[case::data_type(5, Ok(std::vec![0xC8]))]
    #[case::data_size(6, Ok(std::vec![4]))]
    #[case::name(7, Ok(string("Stale timeout")))]
    #[case::units(8, Ok(string("ms")))]
    #[case::help(9, Ok(string("Time without a good answer before the link is stale")))]
    #[case::min(10, Ok(1u32.to_le_bytes().to_vec()))]
    #[case::max(11, Ok(3_600_000u32.to_le_bytes().to_vec()))]
    #[case::default(12, Ok(3000u32.to_le_bytes().to_vec()))]
    #[case::unknown(13, Err((0x14, 0xFF)))]
    fn instance_attributes(#[case] attr: u8, #[case] expected: Result<Vec<u8>, (u8, u8)>) {
        assert_eq!(get(&mut object(), 4, attr), expected);
    }

    #[rstest]
    #[case::get_without_attribute(4, 0x0E, &[], Err((0x13, 0xFF)))]
    #[case::get_two_bytes(4, 0x0E, &[1, 1], Err((0x15, 0xFF)))]
    #[case::set_without_attribute(4, 0x10, &[], Err((0x13, 0xFF)))]
    #[case::set_short(4, 0x10, &[1, 0xB8, 0x0B], Err((0x13, 0xFF)))]
    #[case::set_long(4, 0x10, &[1, 0xB8, 0x0B, 0, 0, 0], Err((0x15, 0xFF)))]
    #[case::set_usint_long(2, 0x10, &[1, 1, 0], Err((0x15, 0xFF)))]
    #[case::set_usint_none(2, 0x10, &[1], Err((0x13, 0xFF)))]
    #[case::set_name(4, 0x10, &[7, 1, b'x'], Err((0x0E, 0xFF)))]
    #[case::set_default(4, 0x10, &[12, 1, 0, 0, 0], Err((0x0E, 0xFF)))]
    #[case::set_unknown(4, 0x10, &[13, 1], Err((0x14, 0xFF)))]
    #[case::set_below_min(4, 0x10, &[1, 0, 0, 0, 0], Err((0x09, 0xFF)))]
    #[case::set_above_max(3, 0x10, &[1, 3], Err((0x09, 0xFF)))]
    #[case::set_between_assemblies(6, 0x10, &[1, 102], Err((0x09, 0xFF)))]
    #[case::set_retries_above_max(8, 0x10, &[1, 11], Err((0x09, 0xFF)))]
    #[case::set_poll_period_framed(9, 0x10, &[1, 100, 0, 0, 0], Err((0x0E, 0xFF)))]
    #[case::set_class(0, 0x10, &[2, 1, 0], Err((0x08, 0xFF)))]
    #[case::other_service(4, 0x01, &[], Err((0x08, 0xFF)))]
    #[case::instance_beyond_max(10, 0x0E, &[1], Err((0x16, 0xFF)))]
    #[case::set_beyond_max(10, 0x10, &[1, 1], Err((0x16, 0xFF)))]
    fn refusals_change_nothing(
        #[case] instance: u16,
        #[case] service: u8,
        #[case] data: &[u8],
        #[case] expected: Result<Vec<u8>, (u8, u8)>,
    ) {
        let mut o = object();
        assert_eq!(call(&mut o, instance, service, data, false), expected);
        assert_eq!(o.take_new_image(), None);
        assert_eq!(o.state(), ConfigState::FactoryDefault);
        assert_eq!(o.pending(), None);
    }

    #[test]
    fn set_while_an_io_connection_is_established_is_an_object_state_conflict() {
        let mut o = object();
        assert_eq!(set(&mut o, 4, &5000u32.to_le_bytes(), true), Err((0x0C, 0xFF)));
        assert_eq!(o.take_new_image(), None);
        assert_eq!(o.state(), ConfigState::FactoryDefault);
    }

    #[test]
    fn set_hands_over_the_pending_image_and_get_answers_the_pending_value() {
        let mut o = object();
        assert_eq!(set(&mut o, 4, &5000u32.to_le_bytes(), false), Ok(Vec::new()));
        assert_eq!(o.state(), ConfigState::Pending);
        let taken = o.take_new_image().unwrap().to_vec();
        let config = image::decode(&taken).unwrap();
        assert_eq!(Parameter::StaleTimeout.read(&config), 5000);
        assert_eq!(get(&mut o, 4, 1), Ok(5000u32.to_le_bytes().to_vec()), "value: pending");
        assert_eq!(get(&mut o, 4, 12), Ok(3000u32.to_le_bytes().to_vec()), "default: in force");
        // The next Set starts from the pending image: both changes are in the next one.
        assert_eq!(set(&mut o, 2, &[2], false), Ok(Vec::new()));
        let config = image::decode(o.take_new_image().unwrap()).unwrap();
        assert_eq!(Parameter::StaleTimeout.read(&config), 5000);
        assert_eq!(config.profile.serial().parity, Parity::Even);
        // Nothing else changed.
        let mut expected = ConverterConfig::breaker_reference();
        assert!(Parameter::StaleTimeout.write(&mut expected, 5000));
        assert!(Parameter::SerialParity.write(&mut expected, 2));
        assert_eq!(config, expected);
        assert_eq!(o.in_force(), image_of(&ConverterConfig::breaker_reference()).as_slice());
    }

    #[test]
    fn every_parameter_takes_its_limits_and_refuses_beyond_them() {
        for config in [ConverterConfig::breaker_reference(), modbus()] {
            for d in PARAMETERS {
                let p = d.parameter;
                let bytes = |v: u32| v.to_le_bytes()[..d.data_type.size()].to_vec();
                if !p.settable(&config) {
                    let mut o = object_for(&config);
                    assert_eq!(get(&mut o, p.instance().into(), 4), Ok(std::vec![0x10, 0]));
                    assert_eq!(set(&mut o, p.instance().into(), &bytes(d.min), false), Err((0x0E, 0xFF)));
                    continue;
                }
                for v in [d.min, d.max] {
                    let mut o = object_for(&config);
                    assert_eq!(
                        set(&mut o, p.instance().into(), &bytes(v), false),
                        Ok(Vec::new()),
                        "{p:?} = {v}"
                    );
                    assert_eq!(p.read(&image::decode(o.take_new_image().unwrap()).unwrap()), v, "{p:?}");
                    assert_eq!(get(&mut o, p.instance().into(), 1), Ok(bytes(v)));
                }
                let beyond = [
                    d.min.checked_sub(1),
                    d.max.checked_add(1).filter(|v| *v <= 0xFF || d.data_type.size() == 4),
                ];
                for v in beyond.into_iter().flatten() {
                    let mut o = object_for(&config);
                    assert_eq!(
                        set(&mut o, p.instance().into(), &bytes(v), false),
                        Err((0x09, 0xFF)),
                        "{p:?} = {v}"
                    );
                }
                // The value in force is within the range, and one-byte values fit their type.
                assert!((d.min..=d.max).contains(&p.read(&config)), "{p:?}");
                assert!(d.data_type.size() == 4 || d.max <= 0xFF, "{p:?}");
            }
        }
    }

    #[test]
    fn the_ranges_are_the_same_for_both_profiles() {
        assert_eq!(SequencerConfig::MAX_RESPONSE_TIMEOUT_MS, ModbusConfig::MAX_RESPONSE_TIMEOUT_MS);
        assert_eq!(SequencerConfig::MAX_RETRIES, ModbusConfig::MAX_RETRIES);
    }

    #[test]
    fn instances_1_to_8_are_the_settings_attributes() {
        let config = modbus();
        let values = SettingsValues::of_config(&config.profile, config.input);
        for d in &PARAMETERS[..8] {
            let a = SettingsAttribute::from_id(d.parameter.instance()).unwrap();
            assert_eq!((a.spec().name, a.spec().units, a.data_type()), (d.name, d.units, d.data_type));
            assert_eq!(a.read(&values), d.parameter.read(&config));
        }
        assert_eq!(Parameter::PollPeriod.read(&config), 100);
        assert_eq!(Parameter::PollPeriod.def().name, "Poll period");
    }

    #[test]
    fn a_refused_set_leaves_the_value() {
        let mut o = object();
        assert_eq!(set(&mut o, 1, &299u32.to_le_bytes(), false), Err((0x09, 0xFF)));
        assert_eq!(get(&mut o, 1, 1), Ok(9600u32.to_le_bytes().to_vec()));
    }

    #[test]
    fn a_new_download_drops_an_image_not_yet_taken_and_the_state_follows() {
        let mut o = object();
        set(&mut o, 4, &5000u32.to_le_bytes(), false).unwrap();
        assert_eq!(o.state(), ConfigState::Pending);
        // Begin_Download before the application took the image: it is gone.
        let req = Request {
            service: ServiceCode::from(super::super::config_object::BEGIN_DOWNLOAD),
            class: super::super::CONFIG_CLASS,
            instance: 1,
            data: &[10, 0],
        };
        let mut buf = [0u8; MAX_EXPLICIT_SIZE];
        o.handle(&req, &mut Reply::new(&mut buf), false).unwrap();
        assert_eq!(o.state(), ConfigState::FactoryDefault);
        assert_eq!(o.take_new_image(), None);
        assert_eq!(get(&mut o, 4, 1), Ok(3000u32.to_le_bytes().to_vec()));
        // Taken (stored) and then dropped by a download: still pending, its value unknown here.
        set(&mut o, 4, &5000u32.to_le_bytes(), false).unwrap();
        assert!(o.take_new_image().is_some());
        o.handle(&req, &mut Reply::new(&mut buf), false).unwrap();
        assert_eq!(o.state(), ConfigState::Pending);
        assert_eq!(get(&mut o, 4, 1), Err((0x0C, 0xFF)));
        assert_eq!(set(&mut o, 4, &6000u32.to_le_bytes(), false), Err((0x0C, 0xFF)));
    }

    #[test]
    fn help_fits_one_explicit_message() {
        for d in PARAMETERS {
            let mut o = object();
            let reply = get(&mut o, d.parameter.instance().into(), 9).unwrap();
            assert!(reply.len() + 2 <= MAX_EXPLICIT_SIZE, "{:?}", d.parameter);
        }
    }
}
