//! The converter's two vendor-specific objects, described once: the attribute tables the node's
//! object handler serves from and the EDS generator (`eds::generate`) writes its `[Params]` from.
//!
//! | class | instance 1 attributes | table |
//! |---|---|---|
//! | [`SERIAL_LINK_CLASS`] 0x64 | statistics and link status, live values | [`LinkAttribute`] |
//! | [`SETTINGS_CLASS`] 0x65 | the configuration in force | [`SettingsAttribute`] |
//!
//! Each table is an enum with one variant per attribute, its discriminant the attribute id; what
//! an attribute is (name, units, CIP data type, access: [`LinkAttribute::spec`],
//! [`SettingsAttribute::spec`]) and how its value is read from the converter's state
//! ([`LinkAttribute::read`] from the profile's counters and [`LinkStatus`],
//! [`SettingsAttribute::read`] from [`SettingsValues`]) are `match`es on it, so adding an attribute
//! fails to compile until every side says what it is; only the link counters are read by index,
//! attribute id less one being the [`Counter`] (a test holds each to its statistic). The firmware calls only `from_id`,
//! `data_type` and `read`: the names stay out of its flash.
//!
//! Services (both classes): Get_Attribute_Single on instance 1 and on the class (attribute 1,
//! revision 1). Every instance attribute is read-only: the configuration comes from the
//! description and the non-volatile settings, so Set_Attribute_Single answers 0x0E attribute not
//! settable for a known attribute and 0x14 attribute not supported for an unknown one (error codes:
//! protocol §3.3).

use super::InputAssembly;
use crate::serial::modbus::{Framing, ModbusConfig};
use crate::serial::{
    Counter, FramedProfileConfig, HealthConfig, IdleAction, LinkState, LinkStatus, Parity, Profile,
    ProfileConfig, StalePolicy, StopBits,
};

/// Vendor-specific class of the serial link object: statistics and status, instance 1.
pub const SERIAL_LINK_CLASS: u16 = 0x64;
/// Vendor-specific class of the settings object: the configuration in force, instance 1.
pub const SETTINGS_CLASS: u16 = 0x65;

/// The CIP elementary data type an attribute is served as (little-endian on the wire).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AttributeType {
    /// USINT, one byte, unsigned.
    Usint,
    /// UDINT, four bytes, unsigned.
    Udint,
    /// BYTE, a one-byte bit string.
    Byte,
}

impl AttributeType {
    /// Bytes on the wire.
    pub const fn size(self) -> usize {
        match self {
            AttributeType::Usint | AttributeType::Byte => 1,
            AttributeType::Udint => 4,
        }
    }

    /// The CIP data type code (protocol §II.4.2: 0xC6 USINT, 0xC8 UDINT, 0xD1 BYTE).
    pub const fn cip_code(self) -> u8 {
        match self {
            AttributeType::Usint => 0xC6,
            AttributeType::Udint => 0xC8,
            AttributeType::Byte => 0xD1,
        }
    }
}

/// How an attribute may be accessed. Every vendor attribute is Get only; the difference is what
/// it shows (the EDS marks a live value as a monitor parameter).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Get only: configuration, constant while the converter runs.
    Get,
    /// Get only: a live value (a counter, the link status) that a tool should poll.
    GetMonitor,
}

/// What a tool needs to know about one attribute of instance 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AttributeSpec {
    /// The object class ([`SERIAL_LINK_CLASS`] or [`SETTINGS_CLASS`]).
    pub class: u16,
    /// The attribute id.
    pub id: u8,
    /// A short name (the EDS parameter name).
    pub name: &'static str,
    /// Units, empty when the value has none.
    pub units: &'static str,
    /// The data type it is served as.
    pub data_type: AttributeType,
    /// Its access.
    pub access: Access,
}

/// The attributes of the serial link object ([`SERIAL_LINK_CLASS`]), instance 1; the
/// discriminant is the attribute id. The counters wrap at 2^32.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum LinkAttribute {
    /// Good frames received from the instrument ([`Counter::FramesReceived`]).
    FramesReceived = 1,
    /// Frames discarded for a checksum or CRC mismatch ([`Counter::ChecksumErrors`]).
    ChecksumErrors = 2,
    /// Frames discarded for bad framing ([`Counter::FramingErrors`]).
    FramingErrors = 3,
    /// Expected answers that did not arrive in time ([`Counter::Timeouts`]).
    AnswerTimeouts = 4,
    /// Commands sent, first attempts ([`Counter::CommandsSent`]).
    CommandsSent = 5,
    /// Command retransmissions ([`Counter::CommandsRetried`]).
    CommandsRetried = 6,
    /// Commands given up after all retries ([`Counter::CommandsFailed`]).
    CommandsFailed = 7,
    /// Commands the instrument refused ([`Counter::CommandsRejected`]).
    CommandsRejected = 8,
    /// Modbus exception responses ([`Counter::ModbusExceptions`]).
    ModbusExceptions = 9,
    /// Frames written to the serial line ([`Counter::FramesSent`]).
    FramesSent = 10,
    /// Bytes skipped outside any frame ([`Counter::DiscardedBytes`]).
    DiscardedBytes = 11,
    /// Times the link went stale ([`Counter::LinkTimeouts`]).
    LinkTimeouts = 12,
    /// The status byte of input assembly 101 ([`LinkStatus::to_bytes`], byte 0).
    StatusByte = 13,
    /// The freshness counter ([`LinkStatus::freshness`]).
    Freshness = 14,
    /// The link state: 0 starting, 1 ok, 2 stale ([`LinkState`]).
    LinkState = 15,
}

impl LinkAttribute {
    /// Every attribute, in id order.
    pub const ALL: [LinkAttribute; 15] = [
        LinkAttribute::FramesReceived,
        LinkAttribute::ChecksumErrors,
        LinkAttribute::FramingErrors,
        LinkAttribute::AnswerTimeouts,
        LinkAttribute::CommandsSent,
        LinkAttribute::CommandsRetried,
        LinkAttribute::CommandsFailed,
        LinkAttribute::CommandsRejected,
        LinkAttribute::ModbusExceptions,
        LinkAttribute::FramesSent,
        LinkAttribute::DiscardedBytes,
        LinkAttribute::LinkTimeouts,
        LinkAttribute::StatusByte,
        LinkAttribute::Freshness,
        LinkAttribute::LinkState,
    ];

    /// The attribute with id `id`, if the object has one.
    pub const fn from_id(id: u8) -> Option<LinkAttribute> {
        use LinkAttribute as A;
        // The identity on 1..=15: compiled to a range check (tested against `ALL`).
        Some(match id {
            1 => A::FramesReceived,
            2 => A::ChecksumErrors,
            3 => A::FramingErrors,
            4 => A::AnswerTimeouts,
            5 => A::CommandsSent,
            6 => A::CommandsRetried,
            7 => A::CommandsFailed,
            8 => A::CommandsRejected,
            9 => A::ModbusExceptions,
            10 => A::FramesSent,
            11 => A::DiscardedBytes,
            12 => A::LinkTimeouts,
            13 => A::StatusByte,
            14 => A::Freshness,
            15 => A::LinkState,
            _ => return None,
        })
    }

    /// The attribute id.
    pub const fn id(self) -> u8 {
        self as u8
    }

    /// The data type it is served as.
    pub const fn data_type(self) -> AttributeType {
        match self {
            LinkAttribute::StatusByte => AttributeType::Byte,
            LinkAttribute::Freshness | LinkAttribute::LinkState => AttributeType::Usint,
            _ => AttributeType::Udint,
        }
    }

    /// Name, units, type and access.
    pub const fn spec(self) -> AttributeSpec {
        use LinkAttribute as A;
        let (name, units) = match self {
            A::FramesReceived => ("Frames received", "frames"),
            A::ChecksumErrors => ("Checksum errors", "frames"),
            A::FramingErrors => ("Framing errors", "frames"),
            A::AnswerTimeouts => ("Answer timeouts", ""),
            A::CommandsSent => ("Commands sent", ""),
            A::CommandsRetried => ("Commands retried", ""),
            A::CommandsFailed => ("Commands failed", ""),
            A::CommandsRejected => ("Commands rejected", ""),
            A::ModbusExceptions => ("Modbus exceptions", ""),
            A::FramesSent => ("Frames sent", "frames"),
            A::DiscardedBytes => ("Discarded bytes", "bytes"),
            A::LinkTimeouts => ("Link timeouts", ""),
            A::StatusByte => ("Link status byte", ""),
            A::Freshness => ("Freshness counter", ""),
            A::LinkState => ("Link state", ""),
        };
        AttributeSpec {
            class: SERIAL_LINK_CLASS,
            id: self.id(),
            name,
            units,
            data_type: self.data_type(),
            access: Access::GetMonitor,
        }
    }

    /// The value served, from the profile's statistics (a table indexed by [`Counter`]) and
    /// status.
    pub fn read(self, counts: &[u32; Counter::COUNT], status: &LinkStatus) -> u32 {
        use LinkAttribute as A;
        match self {
            A::StatusByte => status.to_bytes()[0].into(),
            A::Freshness => status.freshness.into(),
            A::LinkState => match status.state {
                LinkState::Starting => 0,
                LinkState::Ok => 1,
                LinkState::Timeout => 2,
            },
            // Attributes 1–12 are the counters in table order (Counter): read by index, not a
            // match over the fields (firmware size budget).
            _ => counts.get(usize::from(self.id()).wrapping_sub(1)).copied().unwrap_or(0),
        }
    }
}

/// The attributes of the settings object ([`SETTINGS_CLASS`]), instance 1: the configuration in
/// force; the discriminant is the attribute id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum SettingsAttribute {
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
    /// The idle action: 0 nothing, 1 send the configured frame.
    IdleAction = 9,
    /// The fault action: 0 nothing, 1 send the configured frame.
    FaultAction = 10,
    /// The serial profile: 0 framed serial, 1 Modbus master (its framing: attribute 12).
    SerialProfile = 11,
    /// The Modbus framing: 0 RTU, 1 ASCII, 2 TCP (MBAP); 0 for a framed instrument.
    ModbusFraming = 12,
}

impl SettingsAttribute {
    /// Every attribute, in id order.
    pub const ALL: [SettingsAttribute; 12] = [
        SettingsAttribute::SerialBaud,
        SettingsAttribute::SerialParity,
        SettingsAttribute::SerialStopBits,
        SettingsAttribute::StaleTimeout,
        SettingsAttribute::StalePolicy,
        SettingsAttribute::InputAssembly,
        SettingsAttribute::ResponseTimeout,
        SettingsAttribute::Retries,
        SettingsAttribute::IdleAction,
        SettingsAttribute::FaultAction,
        SettingsAttribute::SerialProfile,
        SettingsAttribute::ModbusFraming,
    ];

    /// The attribute with id `id`, if the object has one.
    pub const fn from_id(id: u8) -> Option<SettingsAttribute> {
        use SettingsAttribute as A;
        // The identity on 1..=12: compiled to a range check (tested against `ALL`).
        Some(match id {
            1 => A::SerialBaud,
            2 => A::SerialParity,
            3 => A::SerialStopBits,
            4 => A::StaleTimeout,
            5 => A::StalePolicy,
            6 => A::InputAssembly,
            7 => A::ResponseTimeout,
            8 => A::Retries,
            9 => A::IdleAction,
            10 => A::FaultAction,
            11 => A::SerialProfile,
            12 => A::ModbusFraming,
            _ => return None,
        })
    }

    /// The attribute id.
    pub const fn id(self) -> u8 {
        self as u8
    }

    /// The data type it is served as.
    pub const fn data_type(self) -> AttributeType {
        match self {
            SettingsAttribute::SerialBaud
            | SettingsAttribute::StaleTimeout
            | SettingsAttribute::ResponseTimeout => AttributeType::Udint,
            _ => AttributeType::Usint,
        }
    }

    /// Name, units, type and access.
    pub const fn spec(self) -> AttributeSpec {
        use SettingsAttribute as A;
        let (name, units) = match self {
            A::SerialBaud => ("Serial baud rate", "baud"),
            A::SerialParity => ("Serial parity", ""),
            A::SerialStopBits => ("Serial stop bits", ""),
            A::StaleTimeout => ("Stale timeout", "ms"),
            A::StalePolicy => ("Stale policy", ""),
            A::InputAssembly => ("Input assembly", ""),
            A::ResponseTimeout => ("Response timeout", "ms"),
            A::Retries => ("Retries", ""),
            A::IdleAction => ("Idle action", ""),
            A::FaultAction => ("Fault action", ""),
            A::SerialProfile => ("Serial profile", ""),
            A::ModbusFraming => ("Modbus framing", ""),
        };
        AttributeSpec {
            class: SETTINGS_CLASS,
            id: self.id(),
            name,
            units,
            data_type: self.data_type(),
            access: Access::Get,
        }
    }

    /// The value served, from the configuration in force.
    pub fn read(self, s: &SettingsValues) -> u32 {
        use SettingsAttribute as A;
        match self {
            A::SerialBaud => s.baud,
            A::SerialParity => match s.parity {
                Parity::None => 0,
                Parity::Odd => 1,
                Parity::Even => 2,
            },
            A::SerialStopBits => match s.stop_bits {
                StopBits::One => 1,
                StopBits::Two => 2,
            },
            A::StaleTimeout => s.health.stale_timeout_ms,
            A::StalePolicy => match s.health.stale_policy {
                StalePolicy::HoldLastValue => 0,
                StalePolicy::Clear => 1,
            },
            A::InputAssembly => s.input.instance().into(),
            A::ResponseTimeout => s.response_timeout_ms,
            A::Retries => s.retries.into(),
            A::IdleAction => s.idle_frame.into(),
            A::FaultAction => s.fault_frame.into(),
            A::SerialProfile => s.modbus.into(),
            A::ModbusFraming => match s.framing {
                Framing::Rtu => 0,
                Framing::Ascii => 1,
                Framing::Tcp => 2,
            },
        }
    }
}

/// The configuration the settings object reports, gathered from either profile: from a running
/// [`Profile`] ([`SettingsValues::of_profile`], the device) or from a [`ProfileConfig`]
/// ([`SettingsValues::of_config`], the EDS generator's defaults), so both read the same values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SettingsValues {
    /// Serial bit rate.
    pub baud: u32,
    /// Serial parity.
    pub parity: Parity,
    /// Serial stop bits.
    pub stop_bits: StopBits,
    /// Stale timeout and policy.
    pub health: HealthConfig,
    /// The produced input assembly.
    pub input: InputAssembly,
    /// The response timeout, ms.
    pub response_timeout_ms: u32,
    /// Retries after a timeout.
    pub retries: u8,
    /// Whether an idle poll sends a frame.
    pub idle_frame: bool,
    /// Whether a poll connection fault sends a frame.
    pub fault_frame: bool,
    /// `true` for the Modbus master, `false` for a framed instrument.
    pub modbus: bool,
    /// The Modbus framing ([`Framing::Rtu`] for a framed instrument).
    pub framing: Framing,
}

impl SettingsValues {
    /// The values of a configuration.
    pub fn of_config(profile: &ProfileConfig, input: InputAssembly) -> SettingsValues {
        SettingsValues::of(
            match profile {
                ProfileConfig::Framed(c) => ConfigRef::Framed(c),
                ProfileConfig::Modbus(c) => ConfigRef::Modbus(c),
            },
            input,
        )
    }

    /// The values a running profile was configured with.
    pub fn of_profile(profile: &Profile, input: InputAssembly) -> SettingsValues {
        SettingsValues::of(
            match profile {
                Profile::Framed(p) => ConfigRef::Framed(p.config()),
                Profile::Modbus(p) => ConfigRef::Modbus(p.config()),
            },
            input,
        )
    }

    /// The values of either profile's configuration: one body for both, the profile's parts
    /// picked by one match (firmware size budget).
    fn of(config: ConfigRef<'_>, input: InputAssembly) -> SettingsValues {
        let (serial, health, response_timeout_ms, retries, [on_idle, on_fault], framing) = match config {
            ConfigRef::Framed(c) => {
                let s = &c.sequencer;
                (&c.serial, c.health, s.response_timeout_ms, s.retries, [&s.on_idle, &s.on_fault], None)
            }
            ConfigRef::Modbus(c) => (
                &c.serial,
                c.health,
                c.response_timeout_ms,
                c.retries,
                [&c.on_idle, &c.on_fault],
                Some(c.framing),
            ),
        };
        SettingsValues {
            baud: serial.baud,
            parity: serial.parity,
            stop_bits: serial.stop_bits,
            health,
            input,
            response_timeout_ms,
            retries,
            idle_frame: sends(on_idle),
            fault_frame: sends(on_fault),
            modbus: framing.is_some(),
            framing: framing.unwrap_or_default(),
        }
    }
}

/// A profile's configuration, of either kind, as [`SettingsValues::of`] reads it.
#[derive(Clone, Copy)]
enum ConfigRef<'a> {
    Framed(&'a FramedProfileConfig),
    Modbus(&'a ModbusConfig),
}

fn sends(action: &IdleAction) -> bool {
    matches!(action, IdleAction::Send(_))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::converter::ConverterConfig;

    #[test]
    fn ids_are_dense_and_from_id_inverts_id() {
        for (n, a) in LinkAttribute::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(a.id()), n + 1);
            assert_eq!(LinkAttribute::from_id(a.id()), Some(a));
            assert_eq!(a.spec().id, a.id());
        }
        for (n, a) in SettingsAttribute::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(a.id()), n + 1);
            assert_eq!(SettingsAttribute::from_id(a.id()), Some(a));
            assert_eq!(a.spec().id, a.id());
        }
        assert_eq!(LinkAttribute::from_id(0), None);
        assert_eq!(LinkAttribute::from_id(16), None);
        assert_eq!(SettingsAttribute::from_id(0), None);
        assert_eq!(SettingsAttribute::from_id(13), None);
    }

    #[test]
    fn counter_attributes_read_their_statistic() {
        // Distinct values, so each attribute shows which counter it read.
        let mut counts = [0; Counter::COUNT];
        for (i, c) in counts.iter_mut().enumerate() {
            *c = 1000 + i as u32;
        }
        let s = crate::serial::Stats::from_counts(&counts);
        let status = LinkStatus {
            state: LinkState::Ok,
            frame_errors: false,
            exception: false,
            request_timeout: false,
            command: crate::serial::CommandOutcome::None,
            freshness: 7,
        };
        use LinkAttribute as A;
        let expected = [
            (A::FramesReceived, s.frames_received),
            (A::ChecksumErrors, s.checksum_errors),
            (A::FramingErrors, s.framing_errors),
            (A::AnswerTimeouts, s.timeouts),
            (A::CommandsSent, s.commands_sent),
            (A::CommandsRetried, s.commands_retried),
            (A::CommandsFailed, s.commands_failed),
            (A::CommandsRejected, s.commands_rejected),
            (A::ModbusExceptions, s.modbus_exceptions),
            (A::FramesSent, s.frames_sent),
            (A::DiscardedBytes, s.discarded_bytes),
            (A::LinkTimeouts, s.link_timeouts),
            (A::StatusByte, 0x01),
            (A::Freshness, 7),
            (A::LinkState, 1),
        ];
        for (a, v) in expected {
            assert_eq!(a.read(&counts, &status), v, "{a:?}");
        }
        assert_eq!(s.unexpected_frames, 1012);
    }

    #[test]
    fn one_byte_values_fit_their_type() {
        let config = ConverterConfig::breaker_reference();
        let values = SettingsValues::of_config(&config.profile, config.input);
        for a in SettingsAttribute::ALL {
            if a.data_type().size() == 1 {
                assert!(a.read(&values) <= 0xFF, "{a:?}");
            }
        }
    }

    #[test]
    fn running_profile_and_configuration_report_the_same_settings() {
        let config = ConverterConfig::breaker_reference();
        let profile = Profile::new(config.profile.clone(), devicenet::Instant::ZERO).unwrap();
        assert_eq!(
            SettingsValues::of_profile(&profile, config.input),
            SettingsValues::of_config(&config.profile, config.input)
        );
    }
}
