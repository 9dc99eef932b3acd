//! The duplicate MAC ID check message (protocol §3.5), the whole CAN data field of
//! Group 2 message 7: a node sends two requests before going on-line, and a node that owns the
//! MAC ID answers with a response (protocol §7.1).

use super::{exact, fixed_length, DeviceKey, MessageError};
use crate::frame::CanFrame;
use crate::id::{Group2Message, Identifier, MacId};

/// Duplicate MAC ID check message body (protocol §3.5): always 7 bytes, sent on Group 2 message 7
/// with the checked MAC in the identifier.
///
/// `[R/R(7) | port(6–0)] <vendor LE16> <serial LE32>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DuplicateMacCheck {
    /// `false` for a request, `true` for a response (R/R bit).
    pub response: bool,
    /// Physical port number, `0..=127` (0 for single-port devices); `emit` keeps the low 7 bits.
    pub port: u8,
    /// The sender's vendor ID (Identity attribute 1).
    pub vendor_id: u16,
    /// The sender's serial number (Identity attribute 6).
    pub serial_number: u32,
}

impl DuplicateMacCheck {
    /// A request from a device with this port and identity.
    pub const fn request(port: u8, vendor_id: u16, serial_number: u32) -> DuplicateMacCheck {
        DuplicateMacCheck { response: false, port, vendor_id, serial_number }
    }

    /// A response from a device with this port and identity.
    pub const fn response(port: u8, vendor_id: u16, serial_number: u32) -> DuplicateMacCheck {
        DuplicateMacCheck { response: true, port, vendor_id, serial_number }
    }

    /// The sender's vendor ID and serial number.
    pub const fn device_key(&self) -> DeviceKey {
        DeviceKey { vendor_id: self.vendor_id, serial_number: self.serial_number }
    }

    /// Parses the 7 data bytes.
    pub fn parse(data: &[u8]) -> Result<DuplicateMacCheck, MessageError> {
        let [b0, k0, k1, k2, k3, k4, k5] = exact::<7>(data)?;
        let key = DeviceKey::from_bytes([k0, k1, k2, k3, k4, k5]);
        Ok(DuplicateMacCheck {
            response: b0 & 0x80 != 0,
            port: b0 & 0x7F,
            vendor_id: key.vendor_id,
            serial_number: key.serial_number,
        })
    }

    /// The checked MAC ID when `frame` is a duplicate MAC ID check *request* (Group 2 message 7,
    /// R/R bit clear, protocol §3.5); `None` for a response or any other frame.
    pub fn request_in(frame: &CanFrame) -> Option<MacId> {
        match Identifier::decode(frame.id()) {
            Identifier::Group2 { mac, message: Group2Message::DuplicateMacCheck } => {
                DuplicateMacCheck::parse(frame.data()).ok().filter(|c| !c.response).map(|_| mac)
            }
            _ => None,
        }
    }

    /// The 7 data bytes.
    pub fn emit(&self) -> [u8; 7] {
        let [k0, k1, k2, k3, k4, k5] = self.device_key().to_bytes();
        [(self.response as u8) << 7 | (self.port & 0x7F), k0, k1, k2, k3, k4, k5]
    }
}

fixed_length!(DuplicateMacCheck, 7);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::testing::{MASTER, SLAVE};
    use rstest::rstest;

    #[test]
    fn request_in_names_the_checked_mac_of_requests_only() {
        let frame = |mac: u8, data: &[u8]| {
            let id = Identifier::group2(MacId::new(mac).unwrap(), Group2Message::DuplicateMacCheck);
            CanFrame::new(id, data).unwrap()
        };
        let request = [0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
        let response = [0x80, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
        assert_eq!(DuplicateMacCheck::request_in(&frame(5, &request)), MacId::new(5));
        assert_eq!(DuplicateMacCheck::request_in(&frame(5, &response)), None);
        assert_eq!(DuplicateMacCheck::request_in(&frame(5, &request[..6])), None);
        let other = Identifier::group2(MacId::new(5).unwrap(), Group2Message::ExplicitRequest);
        assert_eq!(DuplicateMacCheck::request_in(&CanFrame::new(other, &request).unwrap()), None);
    }

    #[rstest]
    #[case::frame0_master_request(&[0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01], DuplicateMacCheck::request(0, 0x0001, 0x0102_0304))]
    #[case::frame2_slave_request(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], DuplicateMacCheck::request(0, 0x1234, 0x1234_5678))]
    #[case::slave_response(&[0x80, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], DuplicateMacCheck::response(0, 0x1234, 0x1234_5678))]
    #[case::port_127_response(&[0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF], DuplicateMacCheck::response(127, 0xFFFF, 0xFFFF_FFFF))]
    #[case::port_5_request(&[0x05, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00], DuplicateMacCheck::request(5, 0, 0))]
    fn duplicate_mac_codec(#[case] bytes: &[u8], #[case] msg: DuplicateMacCheck) {
        assert_eq!(DuplicateMacCheck::parse(bytes), Ok(msg));
        assert_eq!(DuplicateMacCheck::try_from(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
        assert_eq!(<[u8; DuplicateMacCheck::LEN]>::from(msg), msg.emit());
    }

    #[test]
    fn duplicate_mac_identity() {
        let frame0 = DuplicateMacCheck::parse(&[0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01]).unwrap();
        assert_eq!(frame0.device_key(), MASTER);
        let frame2 = DuplicateMacCheck::parse(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]).unwrap();
        assert_eq!(frame2.device_key(), SLAVE);
    }

    #[rstest]
    #[case::empty(&[], 0)]
    #[case::six(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34], 6)]
    #[case::eight(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12, 0x00], 8)]
    fn duplicate_mac_wrong_length(#[case] bytes: &[u8], #[case] got: usize) {
        assert_eq!(DuplicateMacCheck::parse(bytes), Err(MessageError::WrongLength { expected: 7, got }));
    }

    #[test]
    fn duplicate_mac_port_is_masked_on_emit() {
        let msg = DuplicateMacCheck::request(0x85, 0, 0);
        assert_eq!(msg.emit()[0], 0x05);
    }
}
