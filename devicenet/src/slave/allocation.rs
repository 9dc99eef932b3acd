//! The Predefined Master/Slave Connection Set (protocol §3.4): Allocate and Release,
//! through the Group 2 Only Unconnected Explicit Request port or through the explicit connection
//! (DeviceNet object, class 3 instance 1).
//!
//! Requests are validated in JB's order and answered with the error codes of protocol §3.4, with the
//! change-of-state/cyclic rules of §II.2.5 (docs/src/reference/io-connections.md). This node offers every
//! connection but multicast poll ([`SUPPORTED`]).

use super::explicit_messaging::{invalid_group2_only_request, Port};
use super::{ConnectionKind, Event, ObjectHandler, Reply, ServiceError, SlaveNode};
use crate::explicit::{additional, BodyFormat, GeneralStatus, Request, ServiceCode};
use crate::id::MacId;
use crate::messages::AllocationChoice;
use crate::objects::class;
use crate::time::Instant;

/// The connection types this node offers: all but multicast poll (§II.3).
pub(super) const SUPPORTED: AllocationChoice = AllocationChoice::from_bits(0x77);

/// Change of state and cyclic: one of them at most (§II.0: NI, OMR).
const COS_OR_CYCLIC: AllocationChoice = AllocationChoice::CHANGE_OF_STATE.union(AllocationChoice::CYCLIC);

impl SlaveNode {
    /// A request on the Group 2 Only Unconnected Explicit Request port (protocol §3.4): only
    /// Allocate and Release of the DeviceNet object are served; the response goes out at once.
    pub(super) fn on_group2_only<H: ObjectHandler>(&mut self, data: &[u8], now: Instant) {
        match data {
            // Unconnected messages are never fragmented; responses are not for us.
            [header, service, ..] if header & 0x80 == 0 && service & 0x80 == 0 => {
                self.serve(data, now, Port::<H>::Group2Only);
            }
            _ => {}
        }
    }

    /// The services of the Group 2 Only port for a parsed request from `requester`.
    pub(super) fn group2_only_service(
        &mut self,
        req: &Request<'_>,
        requester: MacId,
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        match req.service {
            ServiceCode::AllocateMasterSlave | ServiceCode::ReleaseMasterSlave
                if (req.class, req.instance) != (class::DEVICENET, 1) =>
            {
                Err(ServiceError::OBJECT_DOES_NOT_EXIST)
            }
            ServiceCode::AllocateMasterSlave => self.allocate(req.data, reply, now),
            ServiceCode::ReleaseMasterSlave => self.release(requester, req.data),
            _ => Err(invalid_group2_only_request()),
        }
    }

    /// Allocate_Master/Slave_Connection_Set (protocol §3.4), validation in JB's order. The success
    /// response carries the body format byte.
    pub(super) fn allocate(
        &mut self,
        data: &[u8],
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        // AllocateRequest's layout matched in place, without its parser's Result (firmware size).
        let &[choice, allocator] = data else {
            return Err(ServiceError::wrong_length(data, 2));
        };
        let choice = AllocationChoice::from_bits(choice);
        let Some(allocator) = MacId::new(allocator) else {
            return Err(invalid_choice());
        };
        if self.master.is_some_and(|m| m != allocator) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ObjectStateConflict,
                additional::ALLOCATION_CONFLICT,
            ));
        }
        if choice.is_empty() {
            return Err(invalid_choice());
        }
        if choice.contains(AllocationChoice::ACK_SUPPRESSION) && !choice.intersects(COS_OR_CYCLIC) {
            return Err(invalid_choice());
        }
        // COS and cyclic together, asked at once or one on top of the other: the same invalid
        // choice (the code is UNCONFIRMED, §II.0; by analogy with JB's).
        if choice.union(self.allocation).contains(COS_OR_CYCLIC) {
            return Err(invalid_choice());
        }
        if !SUPPORTED.contains(choice) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ResourceUnavailable,
                additional::INVALID_CHOICE,
            ));
        }
        if !choice.contains(AllocationChoice::EXPLICIT) && !self.explicit.exists() {
            return Err(invalid_choice());
        }
        if choice.intersects(self.allocation) {
            return Err(ServiceError::with_additional(
                GeneralStatus::AlreadyInRequestedState,
                additional::INVALID_CHOICE,
            ));
        }
        self.master = Some(allocator);
        self.allocation = self.allocation.union(choice);
        if choice.contains(AllocationChoice::EXPLICIT) {
            self.explicit.allocate(now);
            self.push_event(Event::ConnectionEstablished(ConnectionKind::Explicit));
        }
        if choice.contains(AllocationChoice::POLL) {
            self.poll.allocate(now);
        }
        if choice.contains(AllocationChoice::BIT_STROBE) {
            self.strobe.allocate(now);
        }
        if choice.intersects(COS_OR_CYCLIC) {
            self.cos.allocate(now);
            // Without poll, Connection 2 consumes the master's COS/cyclic data (§II.2.5).
            if !self.poll.exists() {
                self.poll.allocate(now);
            }
        }
        self.push_event(Event::Allocated { choice, master: allocator });
        // Our explicit connection uses message body format 0 (8/8).
        reply.u8(BodyFormat::Class8Instance8.code())
    }

    /// Release_Master/Slave_Connection_Set (protocol §3.4).
    pub(super) fn release(&mut self, requester: MacId, data: &[u8]) -> Result<(), ServiceError> {
        // ReleaseRequest's layout matched in place (firmware size).
        let &[choice] = data else {
            return Err(ServiceError::wrong_length(data, 1));
        };
        let choice = AllocationChoice::from_bits(choice);
        if self.master.is_some_and(|m| m != requester) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ObjectStateConflict,
                additional::ALLOCATION_CONFLICT,
            ));
        }
        if choice.is_empty() || choice.contains(AllocationChoice::ACK_SUPPRESSION) {
            return Err(invalid_choice());
        }
        if !SUPPORTED.contains(choice) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ResourceUnavailable,
                additional::INVALID_CHOICE,
            ));
        }
        if !self.allocation.contains(choice) {
            return Err(ServiceError::with_additional(
                GeneralStatus::AlreadyInRequestedState,
                additional::INVALID_CHOICE,
            ));
        }
        if choice.intersects(COS_OR_CYCLIC) {
            self.delete_connection(ConnectionKind::ChangeOfState);
        }
        if choice.contains(AllocationChoice::BIT_STROBE) {
            self.delete_connection(ConnectionKind::Strobe);
        }
        if choice.contains(AllocationChoice::POLL) {
            self.delete_connection(ConnectionKind::Poll);
        }
        if choice.contains(AllocationChoice::EXPLICIT) {
            self.delete_connection(ConnectionKind::Explicit);
        }
        self.push_event(Event::Released { choice, owned: self.master.is_some() });
        Ok(())
    }
}

/// An allocation choice that is malformed or inconsistent: 0x09 / 0x02 (protocol §3.4).
fn invalid_choice() -> ServiceError {
    ServiceError::with_additional(GeneralStatus::InvalidAttributeValue, additional::INVALID_CHOICE)
}
