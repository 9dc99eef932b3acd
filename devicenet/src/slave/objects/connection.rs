//! The Connection object (class 0x05, devicenet-notes §5): the attributes of the explicit
//! (instance 1) and poll (instance 2) connections, Set of the expected packet rate and watchdog
//! action, the Reset service, and what happens when a watchdog expires or a connection is
//! deleted. The per-instance state machine is [`Connection`].

use crate::explicit::{Request, ServiceCode};
use crate::id::{Group1MessageId, Group2Message, Identifier};
use crate::messages::AllocationChoice;
use crate::objects::class;
use crate::slave::connection::{Expiry, MAX_EPR_MS};
use crate::slave::{
    Connection, ConnectionKind, ConnectionState, Event, Reply, ServiceError, SlaveNode, MAX_EXPLICIT_SIZE,
};
use crate::time::Instant;

impl SlaveNode {
    /// Connection services: Get/Set_Attribute_Single and Reset on an existing instance.
    pub(super) fn connection_service(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        let conn = match self.connection_mut(req.instance) {
            Some(c) if c.exists() => *c,
            _ => return Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        };
        match req.service {
            ServiceCode::GetAttributeSingle => {
                let &[attr] = req.data else {
                    return Err(ServiceError::wrong_length(req.data, 1));
                };
                self.connection_attribute(&conn, attr, reply)
            }
            ServiceCode::SetAttributeSingle => {
                let (&attr, value) = req.data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                self.set_connection_attribute(conn.kind, attr, value, reply, now)
            }
            ServiceCode::Reset => {
                // Restart the watchdog; deferred delete and timed out return to established
                // (notes §3.2 Westlock; §9.8 for timed-out I/O, UNCONFIRMED).
                let was_timed_out = conn.state == ConnectionState::TimedOut;
                if let Some(c) = self.connection_mut(req.instance) {
                    if matches!(c.state, ConnectionState::DeferredDelete | ConnectionState::TimedOut) {
                        c.state = ConnectionState::Established;
                    }
                    c.restart_timer(now);
                }
                if was_timed_out {
                    self.push_event(Event::ConnectionEstablished(conn.kind));
                }
                Ok(())
            }
            _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
        }
    }

    /// Instance attribute `attr` of `conn` (notes §5.1 table).
    fn connection_attribute(
        &self,
        conn: &Connection,
        attr: u8,
        reply: &mut Reply<'_>,
    ) -> Result<(), ServiceError> {
        let mac = self.config.mac_id;
        let explicit = conn.kind == ConnectionKind::Explicit;
        // Attributes 14 and 16 (notes §5.1): logical class segment (Assembly), instance segment
        // (the assembly), attribute segment 3 (data).
        let path = |asm: u8| [0x20, class::ASSEMBLY as u8, 0x24, asm, 0x30, 0x03];
        match attr {
            1 => reply.u8(conn.state.attribute_value()),
            2 => reply.u8(if explicit { 0 } else { 1 }),
            3 => reply.u8(if explicit { 0x83 } else { 0x82 }),
            4 => reply.u16(if explicit {
                Identifier::group2(mac, Group2Message::ExplicitResponse).as_raw()
            } else {
                Identifier::group1(Group1MessageId::POLL_RESPONSE, mac).as_raw()
            }),
            5 => reply.u16(if explicit {
                Identifier::group2(mac, Group2Message::ExplicitRequest).as_raw()
            } else {
                Identifier::group2(mac, Group2Message::PollCommand).as_raw()
            }),
            6 => reply.u8(if explicit { 0x21 } else { 0x01 }),
            7 => reply.u16(if explicit { MAX_EXPLICIT_SIZE as u16 } else { self.config.produced_size }),
            8 => reply.u16(if explicit { MAX_EXPLICIT_SIZE as u16 } else { self.config.consumed_size }),
            9 => reply.u16(conn.expected_packet_rate),
            12 => reply.u8(conn.watchdog_action.attribute_value()),
            13 | 15 => reply.u16(if explicit { 0 } else { 6 }),
            14 if explicit => Ok(()),
            14 => reply.bytes(&path(self.config.input_assembly)),
            16 if explicit => Ok(()),
            16 => reply.bytes(&path(self.config.output_assembly)),
            17 => reply.u16(0),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    /// Set_Attribute_Single: the expected packet rate (9) and the watchdog timeout action (12)
    /// are the only settable attributes (notes §5.1, §5.3, §5.4).
    fn set_connection_attribute(
        &mut self,
        kind: ConnectionKind,
        attr: u8,
        value: &[u8],
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        let resolution = self.config.epr_resolution_ms;
        match attr {
            9 => {
                let &[lo, hi] = value else {
                    return Err(ServiceError::wrong_length(value, 2));
                };
                let requested = u16::from_le_bytes([lo, hi]);
                if requested > MAX_EPR_MS {
                    return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                }
                // Rounded up to the timer resolution; the response carries the value in use
                // (notes §5.3).
                let applied = requested.div_ceil(resolution).saturating_mul(resolution);
                let conn = if kind == ConnectionKind::Explicit { &mut self.explicit } else { &mut self.poll };
                let was_configuring = conn.state == ConnectionState::Configuring;
                conn.set_expected_packet_rate(applied, now);
                if was_configuring {
                    self.push_event(Event::ConnectionEstablished(kind));
                }
                reply.u16(applied)
            }
            12 => {
                let &[value] = value else {
                    return Err(ServiceError::wrong_length(value, 1));
                };
                let action = kind.parse_action(value).ok_or(ServiceError::INVALID_ATTRIBUTE_VALUE)?;
                let conn = if kind == ConnectionKind::Explicit { &mut self.explicit } else { &mut self.poll };
                conn.watchdog_action = action;
                Ok(())
            }
            1..=8 | 13..=17 => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    // ----- watchdogs and deletion (notes §5.2) ----------------------------------------------

    /// Runs both connections' inactivity watchdogs at `now` (notes §5.2, §5.4).
    pub(in crate::slave) fn run_watchdogs(&mut self, now: Instant) {
        match self.poll.expire(now) {
            Expiry::TimedOut => {
                self.push_event(Event::ConnectionTimedOut(ConnectionKind::Poll));
                self.after_io_lost();
            }
            Expiry::Delete => {
                self.delete_connection(ConnectionKind::Poll);
                self.push_event(Event::ConnectionDeleted(ConnectionKind::Poll));
                self.after_io_lost();
            }
            Expiry::Reset | Expiry::None | Expiry::DeferredDelete => {}
        }
        match self.explicit.expire(now) {
            Expiry::Delete => self.delete_by_watchdog(ConnectionKind::Explicit),
            Expiry::DeferredDelete if self.poll.is_established() => {
                self.explicit.state = ConnectionState::DeferredDelete;
            }
            Expiry::DeferredDelete => self.delete_by_watchdog(ConnectionKind::Explicit),
            Expiry::TimedOut | Expiry::Reset | Expiry::None => {}
        }
    }

    /// An I/O connection timed out or was deleted: an explicit connection in deferred delete
    /// goes with it (notes §5.2).
    fn after_io_lost(&mut self) {
        if self.explicit.state == ConnectionState::DeferredDelete {
            self.delete_by_watchdog(ConnectionKind::Explicit);
        }
    }

    /// Deletes `kind` because its watchdog expired, and says so.
    fn delete_by_watchdog(&mut self, kind: ConnectionKind) {
        self.delete_connection(kind);
        self.push_event(Event::ConnectionDeleted(kind));
    }

    /// Deletes `kind` (release or watchdog) and ends the master's ownership with the last
    /// connection.
    pub(in crate::slave) fn delete_connection(&mut self, kind: ConnectionKind) {
        match kind {
            ConnectionKind::Explicit => {
                self.explicit.delete();
                self.explicit_rx.reset();
                self.explicit_tx.reset();
                self.allocation = self.allocation.difference(AllocationChoice::EXPLICIT);
            }
            ConnectionKind::Poll => {
                self.poll.delete();
                self.poll_rx.reset();
                self.io_idle = false;
                self.allocation = self.allocation.difference(AllocationChoice::POLL);
            }
        }
        // With no connection left the master's ownership ends (JB, notes §3.4).
        if self.allocation.difference(AllocationChoice::ACK_SUPPRESSION).is_empty() {
            self.allocation = AllocationChoice::empty();
            self.master = None;
        }
    }

    /// The connection object instance `instance`, if it is one of ours.
    // Out of line: the firmware's flash is 20 bytes smaller than with it inlined at each use.
    #[inline(never)]
    fn connection_mut(&mut self, instance: u16) -> Option<&mut Connection> {
        match instance {
            1 => Some(&mut self.explicit),
            2 => Some(&mut self.poll),
            _ => None,
        }
    }
}
