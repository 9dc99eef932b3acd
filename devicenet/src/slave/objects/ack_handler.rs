//! The Acknowledge Handler object (class 0x2B, protocol §II.2.4): the acknowledge timer
//! and retry limit of acknowledged change-of-state/cyclic productions (used in
//! `change_of_state.rs`).
//!
//! Class attributes 1 revision and 2 max instance, both 1 (TOSH, ICP, RA 1329I); instance 1
//! attributes 1 acknowledge timer (UINT ms, Get/Set, 1-65535), 2 retry limit (USINT, Get/Set) and 3
//! the producing connection instance (UINT, Get, 4).

use crate::explicit::{Request, ServiceCode};
use crate::slave::{Reply, ServiceError, SlaveNode};

impl SlaveNode {
    /// Acknowledge Handler instance services: Get_Attribute_Single, Set_Attribute_Single (the
    /// Message Router serves the class instance, its revision and max instance).
    pub(super) fn ack_handler_service(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
    ) -> Result<(), ServiceError> {
        match (req.instance, req.service) {
            (1, ServiceCode::GetAttributeSingle) => {
                let &[attr] = req.data else {
                    return Err(ServiceError::wrong_length(req.data, 1));
                };
                let handler = self.ack_handler;
                match attr {
                    1 => reply.u16(handler.acknowledge_timer_ms),
                    2 => reply.u8(handler.retry_limit),
                    // The COS/cyclic producing connection.
                    3 => reply.u16(4),
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            (1, ServiceCode::SetAttributeSingle) => {
                let (&attr, value) = req.data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                match (attr, value) {
                    (1, &[0, 0]) => Err(ServiceError::INVALID_ATTRIBUTE_VALUE),
                    (1, &[lo, hi]) => {
                        self.ack_handler.acknowledge_timer_ms = u16::from_le_bytes([lo, hi]);
                        Ok(())
                    }
                    (2, &[limit]) => {
                        self.ack_handler.retry_limit = limit;
                        Ok(())
                    }
                    (1, _) => Err(ServiceError::wrong_length(value, 2)),
                    (2, _) => Err(ServiceError::wrong_length(value, 1)),
                    (3, _) => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            (1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
    }
}
