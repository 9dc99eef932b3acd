//! The Modbus unit health object, vendor class [`UNITS_CLASS`] 0x69: the Modbus profile's unit
//! table ([`UnitHealth`](crate::serial::modbus::UnitHealth)) over the bus, one instance per unit.
//! Ours, not a spec object: the class and its attributes are this converter's (protocol §6.4).
//!
//! Instance `n` (1-based) is the `n`-th distinct unit address of the scan list, in scan list
//! order; instances past the last unit, and every instance of a converter that is not a Modbus
//! gateway, answer 0x16 (object does not exist). Instance attributes (Get_Attribute_Single only;
//! Set_Attribute_Single answers 0x0E for 1–7, 0x14 otherwise):
//!
//! | attribute | type | value |
//! |---|---|---|
//! | 1 | USINT | the unit address |
//! | 2 | USINT | the state: 0 starting, 1 ok, 2 lost, 3 exception ([`UnitState`]) |
//! | 3 | UDINT | lost data: transactions failed after all retries (wraps) |
//! | 4 | UDINT | retries sent (wraps) |
//! | 5 | UDINT | exception responses (wraps) |
//! | 6 | UDINT | milliseconds since the unit's last answer (saturating at 0xFFFF_FFFE), 0xFFFF_FFFF before the first |
//! | 7 | USINT | the number of units (the same on every instance) |
//!
//! Class attribute 1 is the revision, 1 (answered by the node). Request data of another length
//! than one byte answers 0x13 / 0x15, other services 0x08.

use crate::serial::modbus::{UnitRow, UnitState};
use crate::serial::Profile;
use devicenet::explicit::{Request, ServiceCode};
use devicenet::slave::{Reply, ServiceError};
use devicenet::Instant;

/// Vendor-specific class of the Modbus unit health object, one instance per unit.
pub const UNITS_CLASS: u16 = 0x69;

/// The highest instance attribute.
pub const LAST_ATTRIBUTE: u8 = 7;

/// The value of attribute 6 before a unit's first answer.
pub const NEVER_ANSWERED: u32 = u32::MAX;

/// Serves a request to [`UNITS_CLASS`] instance 1 or later (class instance 0 is the node's).
pub fn handle(
    profile: &Profile,
    now: Instant,
    req: &Request<'_>,
    reply: &mut Reply<'_>,
) -> Result<(), ServiceError> {
    let Profile::Modbus(master) = profile else {
        return Err(ServiceError::OBJECT_DOES_NOT_EXIST);
    };
    let count = master.units().len();
    let Some(row) = usize::from(req.instance).checked_sub(1).and_then(|r| master.unit_row(r, now)) else {
        return Err(ServiceError::OBJECT_DOES_NOT_EXIST);
    };
    match (req.service, req.data) {
        (ServiceCode::GetAttributeSingle, &[id]) => get(&row, count, id, reply),
        (ServiceCode::GetAttributeSingle, data) => Err(ServiceError::wrong_length(data, 1)),
        (ServiceCode::SetAttributeSingle, &[1..=LAST_ATTRIBUTE, ..]) => {
            Err(ServiceError::ATTRIBUTE_NOT_SETTABLE)
        }
        (ServiceCode::SetAttributeSingle, &[_, ..]) => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        (ServiceCode::SetAttributeSingle, []) => Err(ServiceError::NOT_ENOUGH_DATA),
        _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
    }
}

fn get(row: &UnitRow, count: usize, id: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
    match id {
        1 => reply.u8(row.unit),
        2 => reply.u8(row.state as u8),
        3 => reply.u32(row.lost_data),
        4 => reply.u32(row.retries),
        5 => reply.u32(row.exceptions),
        6 => reply.u32(row.since_answer_ms.map_or(NEVER_ANSWERED, |ms| ms.min(NEVER_ANSWERED - 1))),
        7 => reply.u8(count as u8),
        _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
    }
}

/// The state's name, as tools print it.
pub fn state_name(state: UnitState) -> &'static str {
    match state {
        UnitState::Starting => "starting",
        UnitState::Ok => "ok",
        UnitState::Lost => "lost",
        UnitState::Exception => "exception",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::modbus::{Function, ModbusConfig, ModbusMaster, ScanEntry};
    use devicenet::explicit::ServiceCode;
    use rstest::rstest;

    fn profile() -> Profile {
        let e = |unit, offset| ScanEntry {
            unit,
            function: Function::ReadHoldingRegisters,
            address: 0,
            count: 1,
            offset,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        };
        let scan = heapless::Vec::from_slice(&[e(7, 0), e(9, 2), e(7, 4)]).unwrap();
        Profile::Modbus(ModbusMaster::new(ModbusConfig::new(scan), Instant::from_millis(0)).unwrap())
    }

    fn call(instance: u16, service: ServiceCode, data: &[u8]) -> Result<std::vec::Vec<u8>, ServiceError> {
        let p = profile();
        let req = Request { class: UNITS_CLASS, instance, service, data };
        let mut buf = [0u8; 16];
        let mut reply = Reply::new(&mut buf);
        handle(&p, Instant::from_millis(10), &req, &mut reply)?;
        let n = reply.len();
        Ok(buf[..n].to_vec())
    }

    #[rstest]
    #[case::address_1(1, 1, &[7])]
    #[case::address_2(2, 1, &[9])]
    #[case::starting(1, 2, &[0])]
    #[case::lost_data(1, 3, &[0, 0, 0, 0])]
    #[case::never_answered(2, 6, &[0xFF; 4])]
    #[case::count(2, 7, &[2])]
    fn get_reads_the_row(#[case] instance: u16, #[case] attribute: u8, #[case] expected: &[u8]) {
        assert_eq!(call(instance, ServiceCode::GetAttributeSingle, &[attribute]).unwrap(), expected);
    }

    #[rstest]
    #[case::instance_0_is_not_ours(0, ServiceCode::GetAttributeSingle, &[1], ServiceError::OBJECT_DOES_NOT_EXIST)]
    #[case::past_the_last_unit(3, ServiceCode::GetAttributeSingle, &[1], ServiceError::OBJECT_DOES_NOT_EXIST)]
    #[case::unknown_attribute(1, ServiceCode::GetAttributeSingle, &[8], ServiceError::ATTRIBUTE_NOT_SUPPORTED)]
    #[case::no_attribute(1, ServiceCode::GetAttributeSingle, &[], ServiceError::NOT_ENOUGH_DATA)]
    #[case::two_bytes(1, ServiceCode::GetAttributeSingle, &[1, 0], ServiceError::TOO_MUCH_DATA)]
    #[case::set_known(1, ServiceCode::SetAttributeSingle, &[3, 0, 0, 0, 0], ServiceError::ATTRIBUTE_NOT_SETTABLE)]
    #[case::set_unknown(1, ServiceCode::SetAttributeSingle, &[9, 0], ServiceError::ATTRIBUTE_NOT_SUPPORTED)]
    #[case::set_empty(1, ServiceCode::SetAttributeSingle, &[], ServiceError::NOT_ENOUGH_DATA)]
    #[case::other_service(1, ServiceCode::Reset, &[], ServiceError::SERVICE_NOT_SUPPORTED)]
    fn malformed_requests_are_refused(
        #[case] instance: u16,
        #[case] service: ServiceCode,
        #[case] data: &[u8],
        #[case] error: ServiceError,
    ) {
        assert_eq!(call(instance, service, data), Err(error));
    }
}
