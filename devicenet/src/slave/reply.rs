//! Building explicit response data, and the error a service answers with.

use crate::explicit::{additional, GeneralStatus};
use core::fmt;

/// The error response a service answers with: general status and additional code
/// (protocol §3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ServiceError {
    /// General status.
    pub general: GeneralStatus,
    /// Additional code ([`additional::NONE`] when there is none).
    pub additional: u8,
}

impl ServiceError {
    /// An error with no additional code.
    pub const fn new(general: GeneralStatus) -> ServiceError {
        ServiceError { general, additional: additional::NONE }
    }

    /// An error with an additional code.
    pub const fn with_additional(general: GeneralStatus, additional: u8) -> ServiceError {
        ServiceError { general, additional }
    }

    /// 0x08 service not supported.
    pub const SERVICE_NOT_SUPPORTED: ServiceError = ServiceError::new(GeneralStatus::ServiceNotSupported);
    /// 0x14 attribute not supported.
    pub const ATTRIBUTE_NOT_SUPPORTED: ServiceError = ServiceError::new(GeneralStatus::AttributeNotSupported);
    /// 0x0E attribute not settable.
    pub const ATTRIBUTE_NOT_SETTABLE: ServiceError = ServiceError::new(GeneralStatus::AttributeNotSettable);
    /// 0x16 object does not exist.
    pub const OBJECT_DOES_NOT_EXIST: ServiceError = ServiceError::new(GeneralStatus::ObjectDoesNotExist);
    /// 0x09 invalid attribute value.
    pub const INVALID_ATTRIBUTE_VALUE: ServiceError = ServiceError::new(GeneralStatus::InvalidAttributeValue);
    /// 0x13 not enough data.
    pub const NOT_ENOUGH_DATA: ServiceError = ServiceError::new(GeneralStatus::NotEnoughData);
    /// 0x15 too much data.
    pub const TOO_MUCH_DATA: ServiceError = ServiceError::new(GeneralStatus::TooMuchData);
    /// 0x11 reply data too large.
    pub const REPLY_TOO_LARGE: ServiceError = ServiceError::new(GeneralStatus::ReplyDataTooLarge);
    /// 0x20 invalid parameter.
    pub const INVALID_PARAMETER: ServiceError = ServiceError::new(GeneralStatus::InvalidParameter);
    /// 0x10 device state conflict.
    pub const DEVICE_STATE_CONFLICT: ServiceError = ServiceError::new(GeneralStatus::DeviceStateConflict);
    /// 0x0C object state conflict.
    pub const OBJECT_STATE_CONFLICT: ServiceError = ServiceError::new(GeneralStatus::ObjectStateConflict);

    /// The error for request data that is not `n` bytes long: 0x13 not enough data, 0x15 too
    /// much. Every length check of the services goes through it, after a slice pattern
    /// (`let &[attr] = data else { return Err(..) }`) or a length comparison: that costs less
    /// flash than a checking helper's `Result` and `?` (some 20 to 40 bytes a site).
    #[inline(never)]
    pub const fn wrong_length(data: &[u8], n: usize) -> ServiceError {
        if data.len() < n {
            ServiceError::NOT_ENOUGH_DATA
        } else {
            ServiceError::TOO_MUCH_DATA
        }
    }
}

impl fmt::Display for ServiceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.general)?;
        match additional::name(self.additional) {
            _ if self.additional == additional::NONE => Ok(()),
            Some(n) => write!(f, ", {n} (0x{:02X})", self.additional),
            None => write!(f, ", additional code 0x{:02X}", self.additional),
        }
    }
}

/// Response data under construction, bounded by the buffer it writes into.
pub struct Reply<'b> {
    buf: &'b mut [u8],
    len: usize,
}

impl<'b> Reply<'b> {
    /// An empty reply writing into `buf`.
    pub fn new(buf: &'b mut [u8]) -> Reply<'b> {
        Reply { buf, len: 0 }
    }

    /// Appends bytes; 0x11 "reply data too large" when they do not fit.
    pub fn bytes(&mut self, data: &[u8]) -> Result<(), ServiceError> {
        let end = self.len + data.len();
        let Some(dst) = self.buf.get_mut(self.len..end) else {
            return Err(ServiceError::REPLY_TOO_LARGE);
        };
        dst.copy_from_slice(data);
        self.len = end;
        Ok(())
    }

    /// Appends a USINT / BYTE / BOOL.
    pub fn u8(&mut self, v: u8) -> Result<(), ServiceError> {
        self.bytes(&[v])
    }

    /// Appends a UINT / WORD, little-endian.
    // Always inlined, as `u32` (some 15 bytes of flash).
    #[inline(always)]
    pub fn u16(&mut self, v: u16) -> Result<(), ServiceError> {
        self.bytes(&v.to_le_bytes())
    }

    /// Appends a UDINT / DWORD, little-endian.
    // Always inlined, as `u16`: the call to `bytes` with the value on the stack is no longer than
    // a call here (some 10 bytes of flash).
    #[inline(always)]
    pub fn u32(&mut self, v: u32) -> Result<(), ServiceError> {
        self.bytes(&v.to_le_bytes())
    }

    /// Appends a SHORT_STRING (length byte + characters).
    pub fn short_string(&mut self, s: &str) -> Result<(), ServiceError> {
        // No `?` on Results (firmware size).
        let Ok(len) = u8::try_from(s.len()) else {
            return Err(ServiceError::REPLY_TOO_LARGE);
        };
        self.u8(len).and_then(|()| self.bytes(s.as_bytes()))
    }

    /// Bytes written so far.
    pub fn len(&self) -> usize {
        self.len
    }

    /// `true` when nothing has been written.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reply_is_bounded() {
        let mut buf = [0u8; 4];
        let mut r = Reply::new(&mut buf);
        r.u16(0x1234).unwrap();
        r.u8(1).unwrap();
        assert_eq!(r.u16(1), Err(ServiceError::REPLY_TOO_LARGE));
        assert_eq!(r.len(), 3);
        assert_eq!(&buf[..3], &[0x34, 0x12, 0x01]);
    }

    #[test]
    fn empty_until_something_is_written() {
        let mut buf = [0u8; 2];
        let mut r = Reply::new(&mut buf);
        assert!(r.is_empty());
        r.u8(7).unwrap();
        assert!(!r.is_empty());
    }

    #[test]
    fn short_string() {
        let mut buf = [0u8; 8];
        let mut r = Reply::new(&mut buf);
        r.short_string("abc").unwrap();
        assert_eq!(&buf[..4], &[3, b'a', b'b', b'c']);
    }

    #[test]
    fn display() {
        extern crate std;
        let e = ServiceError::with_additional(GeneralStatus::ObjectStateConflict, 0x01);
        assert_eq!(std::format!("{e}"), "object state conflict (0x0C), allocation conflict (0x01)");
        assert_eq!(std::format!("{}", ServiceError::TOO_MUCH_DATA), "too much data (0x15)");
    }

    #[test]
    fn wrong_length() {
        assert_eq!(ServiceError::wrong_length(&[1], 2), ServiceError::NOT_ENOUGH_DATA);
        assert_eq!(ServiceError::wrong_length(&[1, 2, 3], 2), ServiceError::TOO_MUCH_DATA);
        assert_eq!(ServiceError::wrong_length(&[], 1), ServiceError::NOT_ENOUGH_DATA);
        assert_eq!(ServiceError::wrong_length(&[1, 2], 1), ServiceError::TOO_MUCH_DATA);
    }
}
