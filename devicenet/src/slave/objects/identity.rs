//! The Identity object (class 0x01, protocol §6.2): the device's identity from its
//! configuration, the status word and state drawn from the connections and the application's
//! fault flags, the configuration consistency value the application keeps (attribute 9,
//! protocol §II.5.3), and the Reset service.

use crate::explicit::{Request, ServiceCode};
use crate::slave::{Event, Reply, ServiceError, SlaveNode};
use crate::time::Instant;

impl SlaveNode {
    /// The Identity status word, attribute 5 (protocol §6.2).
    pub fn identity_status(&self) -> u16 {
        let s = &self.app_status;
        let extended: u16 = if self.io_timed_out() {
            0b0010 // at least one faulted I/O connection
        } else if !self.io_established() {
            0b0011 // no I/O connection established
        } else if self.io_idle {
            0b0111 // I/O connection established, all idle
        } else {
            0b0110 // at least one I/O connection in run mode
        };
        u16::from(self.master.is_some())
            | u16::from(s.configured) << 2
            | extended << 4
            | u16::from(s.minor_recoverable_fault) << 8
            | u16::from(s.minor_unrecoverable_fault) << 9
            | u16::from(s.major_recoverable_fault) << 10
            | u16::from(s.major_unrecoverable_fault) << 11
    }

    /// Identity state, attribute 8.
    pub(in crate::slave) fn identity_state(&self) -> u8 {
        if self.app_status.major_unrecoverable_fault {
            5
        } else if self.app_status.major_recoverable_fault {
            4
        } else {
            3
        }
    }

    /// Identity services: Get_Attribute_Single/All, Set_Attribute_Single (the heartbeat interval),
    /// Reset (answered, then the shutdown message, §II.5.2).
    pub(super) fn identity_service(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        match (req.instance, req.service) {
            (1, ServiceCode::GetAttributeSingle) => {
                let &[attr] = req.data else {
                    return Err(ServiceError::wrong_length(req.data, 1));
                };
                self.identity_attribute(attr, reply)
            }
            (1, ServiceCode::GetAttributesAll) => {
                // Attributes 1-7, the layout every source shows; whether newer editions append
                // state, CCV and heartbeat interval is UNCONFIRMED (protocol §II.5.3).
                for attr in 1..=7 {
                    self.identity_attribute(attr, reply)?;
                }
                Ok(())
            }
            (1, ServiceCode::SetAttributeSingle) => {
                let (&attr, value) = req.data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                match attr {
                    1..=8 => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    // The CCV follows the stored configuration; a tool changes it only by
                    // changing the configuration (§II.5.3).
                    9 if self.configuration_consistency.is_some() => {
                        Err(ServiceError::ATTRIBUTE_NOT_SETTABLE)
                    }
                    // Heartbeat interval, USINT seconds (TOSH, LIM; §II.5.1).
                    10 => {
                        let &[seconds] = value else {
                            return Err(ServiceError::wrong_length(value, 1));
                        };
                        self.set_heartbeat_interval(seconds, now);
                        Ok(())
                    }
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            (1, ServiceCode::Reset) => {
                let kind = match req.data {
                    [] => 0,
                    [k @ (0 | 1)] => *k,
                    [_] => return Err(ServiceError::INVALID_PARAMETER),
                    _ => return Err(ServiceError::TOO_MUCH_DATA),
                };
                self.push_event(Event::ResetRequested(kind));
                self.heartbeat.shutdown_pending = true;
                Ok(())
            }
            (1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
    }

    /// Instance attribute `attr` (protocol §6.2 table).
    fn identity_attribute(&self, attr: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let id = &self.config.identity;
        // Attributes 1-5 are two bytes each and share one reply (firmware size).
        let word = match attr {
            1 => id.vendor_id,
            2 => id.device_type,
            3 => id.product_code,
            // Revision: major, then minor (the bytes of a little-endian UINT).
            4 => u16::from_le_bytes([id.major_revision, id.minor_revision]),
            5 => self.identity_status(),
            6 => return reply.u32(id.serial_number),
            7 => return reply.short_string(&id.product_name),
            8 => return reply.u8(self.identity_state()),
            // The configuration consistency value, where the application keeps one (§II.5.3).
            9 => match self.configuration_consistency {
                Some(ccv) => ccv,
                None => return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
            },
            10 => return reply.u8(self.heartbeat.interval),
            _ => return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        };
        reply.u16(word)
    }
}
