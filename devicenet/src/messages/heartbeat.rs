//! The Device Heartbeat and Device Shutdown messages (protocol §3.7, §II.5), sent by a
//! device on its explicit response identifier with its own MAC ID in the header.
//!
//! Each layout is the whole CAN data field, header byte included; these messages are never
//! fragmented.

use super::{exact, fixed_length, service, unfragmented, MessageError};
use crate::explicit::Header;
use crate::id::MacId;

/// The Device Heartbeat service byte (response form of 0x4D).
pub const DEVICE_HEARTBEAT: u8 = 0xCD;
/// The Device Shutdown service byte (response form of 0x4E).
pub const DEVICE_SHUTDOWN: u8 = 0xCE;

/// The Identity object's state (attribute 8, protocol §6.2), as carried by the heartbeat; unknown
/// values are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeviceState {
    /// 0: non-existent.
    NonExistent,
    /// 1: device self testing.
    SelfTesting,
    /// 2: standby.
    Standby,
    /// 3: operational.
    Operational,
    /// 4: major recoverable fault.
    MajorRecoverableFault,
    /// 5: major unrecoverable fault.
    MajorUnrecoverableFault,
    /// Any other value, kept as received.
    Unknown(u8),
}

impl From<u8> for DeviceState {
    fn from(raw: u8) -> DeviceState {
        match raw {
            0 => DeviceState::NonExistent,
            1 => DeviceState::SelfTesting,
            2 => DeviceState::Standby,
            3 => DeviceState::Operational,
            4 => DeviceState::MajorRecoverableFault,
            5 => DeviceState::MajorUnrecoverableFault,
            other => DeviceState::Unknown(other),
        }
    }
}

impl From<DeviceState> for u8 {
    fn from(state: DeviceState) -> u8 {
        match state {
            DeviceState::NonExistent => 0,
            DeviceState::SelfTesting => 1,
            DeviceState::Standby => 2,
            DeviceState::Operational => 3,
            DeviceState::MajorRecoverableFault => 4,
            DeviceState::MajorUnrecoverableFault => 5,
            DeviceState::Unknown(raw) => raw,
        }
    }
}

/// The heartbeat's fault/event flags byte (protocol §3.7), a bit set that keeps all 8 bits (bits 7–4
/// are reserved).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeartbeatFlags(u8);

impl HeartbeatFlags {
    /// Bit 0, DF: device fault, an internal fault not caused by the user or the bus.
    pub const DEVICE_FAULT: HeartbeatFlags = HeartbeatFlags(0x01);
    /// Bit 1, UF: user fault.
    pub const USER_FAULT: HeartbeatFlags = HeartbeatFlags(0x02);
    /// Bit 2, SF: system fault, caused by bus interaction (e.g. a connection timeout).
    pub const SYSTEM_FAULT: HeartbeatFlags = HeartbeatFlags(0x04);
    /// Bit 3, EV: event.
    pub const EVENT: HeartbeatFlags = HeartbeatFlags(0x08);

    /// The set with exactly these bits.
    pub const fn from_bits(bits: u8) -> HeartbeatFlags {
        HeartbeatFlags(bits)
    }

    /// The flags byte.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// `true` when every bit of `other` is set in `self`.
    pub const fn contains(self, other: HeartbeatFlags) -> bool {
        self.0 & other.0 == other.0
    }

    /// The bits set in either.
    pub const fn union(self, other: HeartbeatFlags) -> HeartbeatFlags {
        HeartbeatFlags(self.0 | other.0)
    }
}

/// Device Heartbeat message, the whole frame data (protocol §3.7), sent by a device on its response
/// identifier with its own MAC in the header:
/// `[hdr] CD <Identity instance LE16> <state> <flags> <configuration consistency LE16>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceHeartbeat {
    /// Transaction ID.
    pub xid: bool,
    /// The sending device (header MAC).
    pub mac: MacId,
    /// The Identity object instance reported on.
    pub identity_instance: u16,
    /// The Identity object's state.
    pub state: DeviceState,
    /// Fault and event flags.
    pub flags: HeartbeatFlags,
    /// The configuration consistency value (Identity attribute 9), 0 when unsupported.
    pub configuration_consistency: u16,
}

impl DeviceHeartbeat {
    /// Parses the 8 data bytes.
    pub fn parse(data: &[u8]) -> Result<DeviceHeartbeat, MessageError> {
        let [header, svc, i0, i1, state, flags, c0, c1] = exact::<8>(data)?;
        let header = unfragmented(header)?;
        service(DEVICE_HEARTBEAT, svc)?;
        Ok(DeviceHeartbeat {
            xid: header.xid,
            mac: header.mac,
            identity_instance: u16::from_le_bytes([i0, i1]),
            state: DeviceState::from(state),
            flags: HeartbeatFlags(flags),
            configuration_consistency: u16::from_le_bytes([c0, c1]),
        })
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; 8] {
        let [i0, i1] = self.identity_instance.to_le_bytes();
        let [c0, c1] = self.configuration_consistency.to_le_bytes();
        let header = Header::new(self.xid, self.mac).to_byte();
        [header, DEVICE_HEARTBEAT, i0, i1, u8::from(self.state), self.flags.bits(), c0, c1]
    }
}

fixed_length!(DeviceHeartbeat, 8);

/// Device Shutdown message, the whole frame data (protocol §3.7), sent by a device on its response
/// identifier with its own MAC in the header:
/// `[hdr] CE <class LE16> <instance LE16> <shutdown code LE16>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceShutdown {
    /// Transaction ID.
    pub xid: bool,
    /// The sending device (header MAC).
    pub mac: MacId,
    /// The class of the object that caused the shutdown.
    pub class: u16,
    /// The instance of the object that caused the shutdown.
    pub instance: u16,
    /// The shutdown code.
    pub shutdown_code: u16,
}

impl DeviceShutdown {
    /// Parses the 8 data bytes.
    pub fn parse(data: &[u8]) -> Result<DeviceShutdown, MessageError> {
        let [header, svc, c0, c1, i0, i1, s0, s1] = exact::<8>(data)?;
        let header = unfragmented(header)?;
        service(DEVICE_SHUTDOWN, svc)?;
        Ok(DeviceShutdown {
            xid: header.xid,
            mac: header.mac,
            class: u16::from_le_bytes([c0, c1]),
            instance: u16::from_le_bytes([i0, i1]),
            shutdown_code: u16::from_le_bytes([s0, s1]),
        })
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; 8] {
        let [c0, c1] = self.class.to_le_bytes();
        let [i0, i1] = self.instance.to_le_bytes();
        let [s0, s1] = self.shutdown_code.to_le_bytes();
        [Header::new(self.xid, self.mac).to_byte(), DEVICE_SHUTDOWN, c0, c1, i0, i1, s0, s1]
    }
}

fixed_length!(DeviceShutdown, 8);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::testing::mac;
    use rstest::rstest;

    #[rstest]
    #[case::operational(&[0x05, 0xCD, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00], DeviceHeartbeat { xid: false, mac: mac(5), identity_instance: 1, state: DeviceState::Operational, flags: HeartbeatFlags::default(), configuration_consistency: 0 })]
    #[case::system_fault(&[0x05, 0xCD, 0x01, 0x00, 0x04, 0x04, 0xCD, 0xAB], DeviceHeartbeat { xid: false, mac: mac(5), identity_instance: 1, state: DeviceState::MajorRecoverableFault, flags: HeartbeatFlags::SYSTEM_FAULT, configuration_consistency: 0xABCD })]
    #[case::unknown_state(&[0x7F, 0xCD, 0x02, 0x01, 0x09, 0xF9, 0x00, 0x00], DeviceHeartbeat { xid: true, mac: mac(63), identity_instance: 0x102, state: DeviceState::Unknown(9), flags: HeartbeatFlags::from_bits(0xF9), configuration_consistency: 0 })]
    fn heartbeat_codec(#[case] bytes: &[u8], #[case] msg: DeviceHeartbeat) {
        assert_eq!(DeviceHeartbeat::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[rstest]
    #[case::identity_reset(&[0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00], DeviceShutdown { xid: false, mac: mac(5), class: 1, instance: 1, shutdown_code: 4 })]
    #[case::vendor_code(&[0x45, 0xCE, 0x66, 0x00, 0x01, 0x00, 0x01, 0x02], DeviceShutdown { xid: true, mac: mac(5), class: 0x66, instance: 1, shutdown_code: 0x201 })]
    fn shutdown_codec(#[case] bytes: &[u8], #[case] msg: DeviceShutdown) {
        assert_eq!(DeviceShutdown::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[rstest]
    #[case::heartbeat_as_shutdown(&[0x05, 0xCD, 0, 0, 0, 0, 0, 0], MessageError::UnexpectedService { expected: 0xCE, got: 0xCD })]
    #[case::fragmented(&[0x85, 0xCE, 0, 0, 0, 0, 0, 0], MessageError::Fragmented)]
    #[case::short(&[0x05, 0xCE, 0, 0, 0, 0, 0], MessageError::WrongLength { expected: 8, got: 7 })]
    fn shutdown_errors(#[case] bytes: &[u8], #[case] err: MessageError) {
        assert_eq!(DeviceShutdown::parse(bytes), Err(err));
    }

    #[test]
    fn heartbeat_errors_and_states() {
        assert_eq!(
            DeviceHeartbeat::parse(&[0x05, 0x4D, 0, 0, 0, 0, 0, 0]),
            Err(MessageError::UnexpectedService { expected: 0xCD, got: 0x4D })
        );
        for raw in 0..=0xFFu8 {
            assert_eq!(u8::from(DeviceState::from(raw)), raw);
        }
        let flags = HeartbeatFlags::DEVICE_FAULT.union(HeartbeatFlags::EVENT);
        assert_eq!(flags.bits(), 0x09);
        assert!(flags.contains(HeartbeatFlags::EVENT));
        assert!(!flags.contains(HeartbeatFlags::USER_FAULT));
    }
}
