//! The DeviceNet object (class 0x03, protocol §6.1): MAC ID, baud rate, bus-off interrupt
//! and counter, allocation information, the switches, and the Allocate/Release services of the
//! Predefined Master/Slave Connection Set (whose logic is in `allocation.rs`).

use crate::explicit::{Request, ServiceCode};
use crate::id::MacId;
use crate::slave::{BaudRate, Event, Reply, ServiceError, SlaveNode};
use crate::time::Instant;

/// A DeviceNet object attribute the master changed, which the application should store
/// (non-volatile) and apply as the attribute says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SettingChanged {
    /// DeviceNet attribute 1; takes effect after a reset.
    MacId(MacId),
    /// DeviceNet attribute 2; takes effect after a reset.
    BaudRate(BaudRate),
    /// DeviceNet attribute 3; takes effect at once.
    BusOffInterrupt(bool),
}

impl SlaveNode {
    /// DeviceNet object services: Get/Set_Attribute_Single, Allocate and Release on instance 1.
    pub(super) fn devicenet_service(
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
                self.devicenet_attribute(attr, reply)
            }
            (1, ServiceCode::SetAttributeSingle) => self.set_devicenet_attribute(req.data),
            (1, ServiceCode::AllocateMasterSlave) => self.allocate(req.data, reply, now),
            (1, ServiceCode::ReleaseMasterSlave) => {
                // Through the explicit connection the requester is the owner (checked on entry).
                let owner = self.master.unwrap_or(MacId::MAX);
                self.release(owner, req.data)
            }
            (1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
    }

    /// Instance attribute `attr` (protocol §6.1 table).
    fn devicenet_attribute(&self, attr: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let sw = &self.config.switches;
        // The one-byte attributes, `None` where there is none: one reply, no `?` (firmware size).
        let byte = match attr {
            1 => Some(self.pending_mac.as_raw()),
            2 => Some(self.pending_baud.attribute_value()),
            3 => Some(u8::from(self.bus_off_interrupt)),
            4 => Some(self.bus_off_counter),
            5 => {
                // Allocation choice, then the master's MAC ID.
                let master = self.master.map_or(0xFF, MacId::as_raw);
                return reply.bytes(&[self.allocation.bits(), master]);
            }
            6 => Some(u8::from(sw.mac_id_changed)),
            7 => Some(u8::from(sw.baud_rate_changed)),
            // The switches' values, where the device has them.
            8 => sw.mac_id,
            9 => sw.baud_rate,
            _ => None,
        };
        byte.map_or(Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED), |b| reply.u8(b))
    }

    /// Set_Attribute_Single: MAC ID and baud rate only with the switches in "program" (notes
    /// §II.7), bus-off interrupt, and clearing the bus-off counter.
    fn set_devicenet_attribute(&mut self, data: &[u8]) -> Result<(), ServiceError> {
        let (&attr, value) = data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
        let programmable = self.config.switches.programmable;
        let changed = match attr {
            1 | 2 if !programmable => return Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            1..=4 => {
                let &[v] = value else {
                    return Err(ServiceError::wrong_length(value, 1));
                };
                match attr {
                    1 => {
                        let Some(mac) = MacId::new(v) else {
                            return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                        };
                        self.pending_mac = mac;
                        Some(SettingChanged::MacId(mac))
                    }
                    2 => {
                        let Some(baud) = BaudRate::from_attribute_value(v) else {
                            return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                        };
                        self.pending_baud = baud;
                        Some(SettingChanged::BaudRate(baud))
                    }
                    3 => {
                        let boi = match v {
                            0 => false,
                            1 => true,
                            _ => return Err(ServiceError::INVALID_ATTRIBUTE_VALUE),
                        };
                        self.bus_off_interrupt = boi;
                        Some(SettingChanged::BusOffInterrupt(boi))
                    }
                    _ => {
                        // The bus-off counter can only be cleared.
                        if v != 0 {
                            return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                        }
                        self.bus_off_counter = 0;
                        None
                    }
                }
            }
            5..=9 => return Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            _ => return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        };
        if let Some(c) = changed {
            self.push_event(Event::SettingChanged(c));
        }
        Ok(())
    }
}
