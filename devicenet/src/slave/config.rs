//! What the application tells the node about the device: identity, address, baud rate, I/O sizes
//! and assembly instances. Nothing device-specific is hard-coded in the core (style.md practice 9);
//! the firmware, the soft slave and the EDS generator all build this from one description.

use crate::id::MacId;
use crate::text::{self, TextSink};
use core::fmt;

/// Largest I/O assembly (produced or consumed size) the node holds, in bytes.
pub const MAX_IO_SIZE: usize = 128;
/// Largest explicit message (header + body) the node reassembles or sends: a firmware update's
/// Transfer request (header, service, class, instance, chunk number and a 128-byte chunk: 136
/// bytes; docs/src/development/firmware-update.md) with 4 bytes to spare. The Connection object's
/// explicit messaging instance reports it as its produced and consumed sizes.
pub const MAX_EXPLICIT_SIZE: usize = 140;
/// The most input data a bit-strobe response carries: a strobe response is never fragmented
/// (protocol §II.1.3), so a device with a larger input image answers a strobe with the first
/// `STROBE_MAX_SIZE` bytes of it (docs/src/reference/io-connections.md).
pub const STROBE_MAX_SIZE: u16 = 8;

/// The size of the bit-strobe response of a device that produces `produced` bytes.
pub const fn strobe_produced_size(produced: u16) -> u16 {
    if produced < STROBE_MAX_SIZE {
        produced
    } else {
        STROBE_MAX_SIZE
    }
}
/// Longest product name (Identity attribute 7, SHORT_STRING).
pub const MAX_PRODUCT_NAME: usize = 32;

/// DeviceNet data rates (DeviceNet object attribute 2, protocol §6.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BaudRate {
    /// 125 kbit/s, attribute value 0.
    Kbps125,
    /// 250 kbit/s, attribute value 1.
    Kbps250,
    /// 500 kbit/s, attribute value 2.
    Kbps500,
}

impl BaudRate {
    /// The DeviceNet object attribute value.
    pub const fn attribute_value(self) -> u8 {
        match self {
            BaudRate::Kbps125 => 0,
            BaudRate::Kbps250 => 1,
            BaudRate::Kbps500 => 2,
        }
    }

    /// The rate for an attribute value 0–2.
    pub const fn from_attribute_value(v: u8) -> Option<BaudRate> {
        match v {
            0 => Some(BaudRate::Kbps125),
            1 => Some(BaudRate::Kbps250),
            2 => Some(BaudRate::Kbps500),
            _ => None,
        }
    }

    /// Bits per second.
    pub const fn bits_per_second(self) -> u32 {
        match self {
            BaudRate::Kbps125 => 125_000,
            BaudRate::Kbps250 => 250_000,
            BaudRate::Kbps500 => 500_000,
        }
    }
}

/// Identity object values (class 1, protocol §6.2).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Identity {
    /// Attribute 1; also sent in duplicate MAC ID checks.
    pub vendor_id: u16,
    /// Attribute 2 (0x000C communications adapter).
    pub device_type: u16,
    /// Attribute 3.
    pub product_code: u16,
    /// Attribute 4, major revision (1..=127).
    pub major_revision: u8,
    /// Attribute 4, minor revision.
    pub minor_revision: u8,
    /// Attribute 6; also sent in duplicate MAC ID checks.
    pub serial_number: u32,
    /// Attribute 7, ASCII, at most [`MAX_PRODUCT_NAME`] characters.
    pub product_name: heapless::String<MAX_PRODUCT_NAME>,
}

/// What the MAC ID and baud rate switches said at reset (DeviceNet object attributes 6–9).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Switches {
    /// Attribute 8: the MAC ID switch value (`None` when the device has no switch).
    pub mac_id: Option<u8>,
    /// Attribute 9: the baud rate switch value.
    pub baud_rate: Option<u8>,
    /// Attribute 6: the MAC switch changed since the values in use were taken.
    pub mac_id_changed: bool,
    /// Attribute 7: the baud switch changed since the values in use were taken.
    pub baud_rate_changed: bool,
    /// The switches are in the "program" position: MAC ID and baud rate are settable over the
    /// network (otherwise attributes 1 and 2 answer "attribute not settable").
    pub programmable: bool,
}

/// The whole configuration of a slave node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceConfig {
    /// Identity object values.
    pub identity: Identity,
    /// This node's MAC ID.
    pub mac_id: MacId,
    /// The data rate in use (reported by DeviceNet object attribute 2).
    pub baud_rate: BaudRate,
    /// The physical port number sent in duplicate MAC ID checks (0 for single-port devices).
    pub port: u8,
    /// The bus-off interrupt setting (DeviceNet object attribute 3): `true` resets the CAN
    /// controller and continues after bus-off.
    pub bus_off_interrupt: bool,
    /// Switch values and whether MAC/baud are settable over the network.
    pub switches: Switches,
    /// Produced (input) assembly instance of the poll connection.
    pub input_assembly: u8,
    /// Consumed (output) assembly instance of the poll connection.
    pub output_assembly: u8,
    /// Poll response size in bytes (Connection 2 attribute 7).
    pub produced_size: u16,
    /// Poll command size in bytes (Connection 2 attribute 8).
    pub consumed_size: u16,
    /// Expected-packet-rate timer resolution in ms (written values are rounded up to it).
    pub epr_resolution_ms: u16,
}

/// Why a [`DeviceConfig`] was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// Produced or consumed size exceeds [`MAX_IO_SIZE`].
    IoSizeTooLarge {
        /// The size asked for.
        size: u16,
    },
    /// Input and output assembly instances are the same.
    SameAssemblyInstance,
    /// Assembly instance 0 addresses the class, not an instance.
    AssemblyInstanceZero,
    /// Port number above 127.
    PortOutOfRange,
    /// EPR resolution of 0 ms.
    ZeroEprResolution,
    /// Product name is not printable ASCII.
    ProductNameNotAscii,
    /// Major revision 0 or above 127.
    MajorRevisionOutOfRange,
}

impl ConfigError {
    /// Writes the message (the `Display` text) without `core::fmt` ([`crate::text`]).
    pub fn write_text(&self, out: &mut impl TextSink) {
        match self {
            ConfigError::IoSizeTooLarge { size } => {
                out.text("I/O size ");
                out.decimal(u32::from(*size));
                out.text(" exceeds the maximum of ");
                out.decimal(MAX_IO_SIZE as u32);
                out.text(" bytes");
            }
            ConfigError::SameAssemblyInstance => out.text("input and output assembly instances must differ"),
            ConfigError::AssemblyInstanceZero => out.text("assembly instance 0 is the class"),
            ConfigError::PortOutOfRange => out.text("port number must be 0..=127"),
            ConfigError::ZeroEprResolution => out.text("EPR resolution must be at least 1 ms"),
            ConfigError::ProductNameNotAscii => out.text("product name must be printable ASCII"),
            ConfigError::MajorRevisionOutOfRange => out.text("major revision must be 1..=127"),
        }
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl core::error::Error for ConfigError {}

impl DeviceConfig {
    /// Checks every field; the node only accepts a configuration that passes.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for size in [self.produced_size, self.consumed_size] {
            if usize::from(size) > MAX_IO_SIZE {
                return Err(ConfigError::IoSizeTooLarge { size });
            }
        }
        if self.input_assembly == 0 || self.output_assembly == 0 {
            return Err(ConfigError::AssemblyInstanceZero);
        }
        if self.input_assembly == self.output_assembly {
            return Err(ConfigError::SameAssemblyInstance);
        }
        if self.port > 127 {
            return Err(ConfigError::PortOutOfRange);
        }
        if self.epr_resolution_ms == 0 {
            return Err(ConfigError::ZeroEprResolution);
        }
        if !self.identity.product_name.bytes().all(|b| (0x20..0x7F).contains(&b)) {
            return Err(ConfigError::ProductNameNotAscii);
        }
        if !(1..=127).contains(&self.identity.major_revision) {
            return Err(ConfigError::MajorRevisionOutOfRange);
        }
        Ok(())
    }

    /// The reference device of protocol §2 and of the project's default
    /// description: MAC 5, vendor 0x1234, device type 0x000C, product code 1, revision 1.1,
    /// serial 0x12345678, "Serial-DeviceNet Bridge", 250 kbit/s, poll produced 18 / consumed 8,
    /// input assembly 100, output assembly 150.
    pub fn reference() -> DeviceConfig {
        let mut product_name = heapless::String::new();
        // 23 ASCII characters always fit in 32.
        let _ = product_name.push_str("Serial-DeviceNet Bridge");
        DeviceConfig {
            identity: Identity {
                vendor_id: 0x1234,
                device_type: 0x000C,
                product_code: 1,
                major_revision: 1,
                minor_revision: 1,
                serial_number: 0x1234_5678,
                product_name,
            },
            mac_id: MacId::from_low_bits(5),
            baud_rate: BaudRate::Kbps250,
            port: 0,
            bus_off_interrupt: false,
            switches: Switches::default(),
            input_assembly: 100,
            output_assembly: 150,
            produced_size: 18,
            consumed_size: 8,
            epr_resolution_ms: 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[test]
    fn reference_is_valid() {
        assert_eq!(DeviceConfig::reference().validate(), Ok(()));
    }

    #[rstest]
    #[case::produced_too_big(|c: &mut DeviceConfig| c.produced_size = 129, ConfigError::IoSizeTooLarge { size: 129 })]
    #[case::same_assembly(|c: &mut DeviceConfig| c.output_assembly = c.input_assembly, ConfigError::SameAssemblyInstance)]
    #[case::assembly_zero(|c: &mut DeviceConfig| c.input_assembly = 0, ConfigError::AssemblyInstanceZero)]
    #[case::port(|c: &mut DeviceConfig| c.port = 128, ConfigError::PortOutOfRange)]
    #[case::epr_resolution(|c: &mut DeviceConfig| c.epr_resolution_ms = 0, ConfigError::ZeroEprResolution)]
    #[case::major_zero(|c: &mut DeviceConfig| c.identity.major_revision = 0, ConfigError::MajorRevisionOutOfRange)]
    #[case::name(|c: &mut DeviceConfig| { c.identity.product_name.clear(); let _ = c.identity.product_name.push('\u{7}'); }, ConfigError::ProductNameNotAscii)]
    fn invalid_configs(#[case] edit: fn(&mut DeviceConfig), #[case] err: ConfigError) {
        let mut c = DeviceConfig::reference();
        edit(&mut c);
        assert_eq!(c.validate(), Err(err));
    }

    #[rstest]
    #[case::largest_io_sizes(|c: &mut DeviceConfig| { c.produced_size = 128; c.consumed_size = 128; })]
    #[case::largest_port(|c: &mut DeviceConfig| c.port = 127)]
    fn limits_are_inclusive(#[case] edit: fn(&mut DeviceConfig)) {
        let mut c = DeviceConfig::reference();
        edit(&mut c);
        assert_eq!(c.validate(), Ok(()));
    }

    #[rstest]
    #[case::io_size(ConfigError::IoSizeTooLarge { size: 129 }, "I/O size 129 exceeds the maximum of 128 bytes")]
    #[case::same_assembly(
        ConfigError::SameAssemblyInstance,
        "input and output assembly instances must differ"
    )]
    #[case::assembly_zero(ConfigError::AssemblyInstanceZero, "assembly instance 0 is the class")]
    #[case::port(ConfigError::PortOutOfRange, "port number must be 0..=127")]
    #[case::epr_resolution(ConfigError::ZeroEprResolution, "EPR resolution must be at least 1 ms")]
    #[case::name(ConfigError::ProductNameNotAscii, "product name must be printable ASCII")]
    #[case::major_revision(ConfigError::MajorRevisionOutOfRange, "major revision must be 1..=127")]
    fn errors_display(#[case] err: ConfigError, #[case] text: &str) {
        assert_eq!(std::format!("{err}"), text);
    }

    #[rstest]
    #[case::k125(0, BaudRate::Kbps125, 125_000)]
    #[case::k250(1, BaudRate::Kbps250, 250_000)]
    #[case::k500(2, BaudRate::Kbps500, 500_000)]
    fn baud_codes(#[case] v: u8, #[case] b: BaudRate, #[case] bps: u32) {
        assert_eq!(BaudRate::from_attribute_value(v), Some(b));
        assert_eq!(b.attribute_value(), v);
        assert_eq!(b.bits_per_second(), bps);
    }
}
