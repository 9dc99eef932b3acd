//! The Connection object (class 0x05, protocol §5, §II.1, §II.2): the attributes of the
//! explicit (1), poll (2), bit-strobe (3) and change-of-state/cyclic (4) connections, Set of the
//! expected packet rate, watchdog action and production inhibit time, the Reset service, and what
//! happens when a watchdog expires or a connection is deleted. The per-instance state machine is
//! [`Connection`].

use crate::explicit::{Request, ServiceCode};
use crate::id::{Group1MessageId, Group2Message, Identifier};
use crate::messages::AllocationChoice;
use crate::objects::class;
use crate::slave::change_of_state::Production;
use crate::slave::connection::{Expiry, MAX_EPR_MS};
use crate::slave::{
    strobe_produced_size, Connection, ConnectionKind, ConnectionState, Event, Reply, ServiceError, SlaveNode,
    MAX_EXPLICIT_SIZE,
};
use crate::time::Instant;

/// The attributes of a connection that follow from its kind and the allocation (protocol §5.1,
/// §II.1.1, §II.2.2, docs/src/reference/io-connections.md).
struct IoAttributes {
    /// Attribute 3, transport class and trigger.
    transport: u8,
    /// Attribute 4.
    produced_id: u16,
    /// Attribute 5.
    consumed_id: u16,
    /// Attribute 6, initial comm characteristics.
    initial_comm: u8,
    /// Attribute 7.
    produced_size: u16,
    /// Attribute 8.
    consumed_size: u16,
    /// Whether attribute 14 (produced path) is present.
    produced_path: bool,
    /// Whether attribute 16 (consumed path) is present.
    consumed_path: bool,
}

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
                // (protocol §3.2 Westlock; §9.8 for timed-out I/O, UNCONFIRMED).
                let was_timed_out = conn.state == ConnectionState::TimedOut;
                if let Some(c) = self.connection_mut(req.instance) {
                    if matches!(c.state, ConnectionState::DeferredDelete | ConnectionState::TimedOut) {
                        c.state = ConnectionState::Established;
                    }
                    c.restart_timer(now);
                }
                if conn.kind == ConnectionKind::ChangeOfState && self.ack_suppressed() {
                    // It consumes nothing: no watchdog (docs/src/reference/io-connections.md).
                    self.cos.deadline = Instant::MAX;
                }
                if was_timed_out {
                    self.push_event(Event::ConnectionEstablished(conn.kind));
                }
                Ok(())
            }
            _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
        }
    }

    /// Instance attribute `attr` of `conn` (protocol §5.1, §II.1.1, §II.2.2; the values chosen where
    /// the notes are UNCONFIRMED are in docs/src/reference/io-connections.md).
    fn connection_attribute(
        &self,
        conn: &Connection,
        attr: u8,
        reply: &mut Reply<'_>,
    ) -> Result<(), ServiceError> {
        let io = self.io_attributes(conn.kind);
        let path_len = |present: bool| if present { 6 } else { 0 };
        // The two-byte attributes share one reply (firmware size).
        let word = match attr {
            1 => return reply.u8(conn.state.attribute_value()),
            2 => return reply.u8(u8::from(conn.kind != ConnectionKind::Explicit)),
            3 => return reply.u8(io.transport),
            4 => io.produced_id,
            5 => io.consumed_id,
            6 => return reply.u8(io.initial_comm),
            7 => io.produced_size,
            8 => io.consumed_size,
            9 => conn.expected_packet_rate,
            12 => return reply.u8(conn.watchdog_action.attribute_value()),
            13 => path_len(io.produced_path),
            15 => path_len(io.consumed_path),
            14 | 16 => {
                // Attributes 14 and 16 (protocol §5.1): logical class segment, instance segment,
                // attribute segment: an assembly's data, or the Acknowledge Handler's first
                // attribute (§II.2.2); one path built for both (firmware size). Empty when absent.
                let (present, class, instance, attribute) = match (attr, conn.kind) {
                    (14, _) => (io.produced_path, class::ASSEMBLY, self.config.input_assembly, 3),
                    (_, ConnectionKind::ChangeOfState) => {
                        (io.consumed_path, class::ACKNOWLEDGE_HANDLER, 1, 1)
                    }
                    _ => (io.consumed_path, class::ASSEMBLY, self.config.output_assembly, 3),
                };
                if !present {
                    return Ok(());
                }
                return reply.bytes(&[0x20, class as u8, 0x24, instance, 0x30, attribute]);
            }
            17 if conn.kind == ConnectionKind::ChangeOfState => self.production.inhibit_ms,
            17 => 0,
            _ => return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        };
        reply.u16(word)
    }

    /// The fixed attributes of connection `kind` as allocated now.
    fn io_attributes(&self, kind: ConnectionKind) -> IoAttributes {
        let mac = self.config.mac_id;
        let p = self.config.produced_size;
        let c = self.config.consumed_size;
        let suppressed = self.ack_suppressed();
        let cyclic = self.allocation.contains(AllocationChoice::CYCLIC);
        let explicit_size = MAX_EXPLICIT_SIZE as u16;
        let g1 = |message| Identifier::group1(message, mac).as_raw();
        let g2 = |message| Identifier::group2(mac, message).as_raw();
        match kind {
            ConnectionKind::Explicit => IoAttributes {
                transport: 0x83,
                produced_id: g2(Group2Message::ExplicitResponse),
                consumed_id: g2(Group2Message::ExplicitRequest),
                initial_comm: 0x21,
                produced_size: explicit_size,
                consumed_size: explicit_size,
                produced_path: false,
                consumed_path: false,
            },
            // Created by COS/cyclic without poll: consumes the master's COS/cyclic data and
            // produces the zero-length acknowledgement, or nothing when suppressed (§II.2.5, EAT).
            ConnectionKind::Poll if !self.allocation.contains(AllocationChoice::POLL) => IoAttributes {
                transport: if suppressed { 0x80 } else { 0x82 },
                produced_id: g1(Group1MessageId::POLL_RESPONSE),
                consumed_id: g2(Group2Message::PollCommand),
                initial_comm: if suppressed { 0xF1 } else { 0x01 },
                produced_size: 0,
                consumed_size: c,
                produced_path: false,
                consumed_path: true,
            },
            ConnectionKind::Poll => IoAttributes {
                transport: 0x82,
                produced_id: g1(Group1MessageId::POLL_RESPONSE),
                consumed_id: g2(Group2Message::PollCommand),
                initial_comm: 0x01,
                produced_size: p,
                consumed_size: c,
                produced_path: true,
                consumed_path: true,
            },
            // Consumes the owner's strobe: Group 2 message 0 with the master's MAC (§II.1.1).
            ConnectionKind::Strobe => IoAttributes {
                transport: 0x82,
                produced_id: g1(Group1MessageId::BIT_STROBE_RESPONSE),
                consumed_id: Identifier::group2(self.master.unwrap_or(mac), Group2Message::BitStrobeCommand)
                    .as_raw(),
                initial_comm: 0x02,
                produced_size: strobe_produced_size(p),
                consumed_size: 8,
                produced_path: true,
                consumed_path: false,
            },
            // Client, trigger COS (1) or cyclic (0), class 3 acknowledged or 0 suppressed (RA
            // tables, §II.2.2).
            ConnectionKind::ChangeOfState => IoAttributes {
                transport: if cyclic { 0x00 } else { 0x10 } | if suppressed { 0 } else { 0x03 },
                produced_id: g1(Group1MessageId::COS_CYCLIC),
                consumed_id: if suppressed { 0xFFFF } else { g2(Group2Message::CosCyclicAck) },
                initial_comm: if suppressed { 0x0F } else { 0x01 },
                produced_size: p,
                consumed_size: 0,
                produced_path: true,
                consumed_path: !suppressed,
            },
        }
    }

    /// Set_Attribute_Single: the expected packet rate (9), the watchdog timeout action (12) and,
    /// of Connection 4, the production inhibit time (17) are settable (protocol §5.1, §5.3, §5.4,
    /// §II.2.2).
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
                // EPR 0 would stop a COS/cyclic connection's productions (HOR rejects it).
                if requested > MAX_EPR_MS || (requested == 0 && kind == ConnectionKind::ChangeOfState) {
                    return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                }
                // Rounded up to the timer resolution; the response carries the value in use
                // (protocol §5.3).
                let applied = requested.div_ceil(resolution).saturating_mul(resolution);
                let Some(conn) = self.connection_mut(kind.instance()) else {
                    return Err(ServiceError::OBJECT_DOES_NOT_EXIST);
                };
                let was_configuring = conn.state == ConnectionState::Configuring;
                conn.set_expected_packet_rate(applied, now);
                if kind == ConnectionKind::ChangeOfState {
                    self.cos_established(now);
                }
                if was_configuring {
                    self.push_event(Event::ConnectionEstablished(kind));
                }
                reply.u16(applied)
            }
            12 => {
                let &[value] = value else {
                    return Err(ServiceError::wrong_length(value, 1));
                };
                let Some(action) = kind.parse_action(value) else {
                    return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                };
                if let Some(conn) = self.connection_mut(kind.instance()) {
                    conn.watchdog_action = action;
                }
                Ok(())
            }
            17 if kind == ConnectionKind::ChangeOfState => {
                let &[lo, hi] = value else {
                    return Err(ServiceError::wrong_length(value, 2));
                };
                // Settable while configuring and established (RA 855T; UNCONFIRMED after).
                self.production.inhibit_ms = u16::from_le_bytes([lo, hi]);
                Ok(())
            }
            1..=8 | 13..=17 => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    // ----- watchdogs and deletion (protocol §5.2) ----------------------------------------------

    /// Runs every connection's inactivity watchdog at `now` (protocol §5.2, §5.4).
    pub(in crate::slave) fn run_watchdogs(&mut self, now: Instant) {
        for kind in [ConnectionKind::Poll, ConnectionKind::Strobe, ConnectionKind::ChangeOfState] {
            let Some(conn) = self.connection_mut(kind.instance()) else { continue };
            match conn.expire(now) {
                Expiry::TimedOut => {
                    self.push_event(Event::ConnectionTimedOut(kind));
                    self.after_io_lost();
                }
                Expiry::Delete => {
                    self.delete_connection(kind);
                    self.push_event(Event::ConnectionDeleted(kind));
                    self.after_io_lost();
                }
                Expiry::Reset | Expiry::None | Expiry::DeferredDelete => {}
            }
        }
        match self.explicit.expire(now) {
            Expiry::Delete => self.delete_by_watchdog(ConnectionKind::Explicit),
            Expiry::DeferredDelete if self.io_established() => {
                self.explicit.state = ConnectionState::DeferredDelete;
            }
            Expiry::DeferredDelete => self.delete_by_watchdog(ConnectionKind::Explicit),
            Expiry::TimedOut | Expiry::Reset | Expiry::None => {}
        }
    }

    /// An I/O connection timed out or was deleted: an explicit connection in deferred delete
    /// goes with it (protocol §5.2).
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
        let released = match kind {
            ConnectionKind::Explicit => {
                self.explicit.delete();
                self.explicit_rx.reset();
                self.explicit_tx.reset();
                AllocationChoice::EXPLICIT
            }
            ConnectionKind::Poll => {
                self.poll.delete();
                self.poll_rx.reset();
                self.io_idle = false;
                AllocationChoice::POLL
            }
            ConnectionKind::Strobe => {
                self.strobe.delete();
                self.strobe_bit = false;
                AllocationChoice::BIT_STROBE
            }
            ConnectionKind::ChangeOfState => {
                self.cos.delete();
                self.production = Production::new();
                // The Connection 2 it created goes with it (§II.2.5); COS/cyclic is still
                // allocated meanwhile, so the ownership stays.
                if !self.allocation.contains(AllocationChoice::POLL) && self.poll.exists() {
                    self.delete_connection(ConnectionKind::Poll);
                }
                AllocationChoice::CHANGE_OF_STATE
                    .union(AllocationChoice::CYCLIC)
                    .union(AllocationChoice::ACK_SUPPRESSION)
            }
        };
        self.allocation = self.allocation.difference(released);
        // With no connection left the master's ownership ends (JB, protocol §3.4).
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
            3 => Some(&mut self.strobe),
            4 => Some(&mut self.cos),
            _ => None,
        }
    }
}
