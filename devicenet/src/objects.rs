//! Object class IDs of a group-2-only device and the names of their attributes (protocol
//! §5.1, §6.1, §6.2), for decoders, tools and logs.
//!
//! [`class`] is the one definition of the class IDs: the slave's Message Router, the master
//! harness and the EDS generator all name classes through it.
//!
//! Names follow the notes' tables. Class attribute 1 (instance 0) is the revision for every class.
//! Lookups never fail loudly: an unknown class or attribute gives `None`, and the caller shows the
//! number.

/// Object class IDs (protocol §5, §6).
pub mod class {
    /// Identity object (protocol §6.2).
    pub const IDENTITY: u16 = 0x01;
    /// Message Router object.
    pub const MESSAGE_ROUTER: u16 = 0x02;
    /// DeviceNet object (protocol §6.1).
    pub const DEVICENET: u16 = 0x03;
    /// Assembly object.
    pub const ASSEMBLY: u16 = 0x04;
    /// Connection object (protocol §5).
    pub const CONNECTION: u16 = 0x05;
    /// Parameter object (protocol §II.4).
    pub const PARAMETER: u16 = 0x0F;
    /// Acknowledge Handler object (protocol §II.2.4).
    pub const ACKNOWLEDGE_HANDLER: u16 = 0x2B;
}

/// The name of an object class, if known.
pub fn class_name(class: u16) -> Option<&'static str> {
    Some(match class {
        class::IDENTITY => "Identity",
        class::MESSAGE_ROUTER => "Message Router",
        class::DEVICENET => "DeviceNet",
        class::ASSEMBLY => "Assembly",
        class::CONNECTION => "Connection",
        class::PARAMETER => "Parameter",
        class::ACKNOWLEDGE_HANDLER => "Acknowledge Handler",
        _ => return None,
    })
}

/// The name of `service` on an object of `class`, if known. Codes 0x4B–0x63 are object-specific
/// (protocol §3.2): they carry the DeviceNet object's names (Allocate / Release_Master/Slave_Connection_Set)
/// on the DeviceNet object only, and no name on any other class, whose own services reuse the
/// numbers (a vendor object's Read_Chunk can be 0x4B).
pub fn service_name(class: u16, service: crate::explicit::ServiceCode) -> Option<&'static str> {
    let object_specific = (0x4B..=0x63).contains(&service.as_raw());
    if object_specific && class != class::DEVICENET {
        return None;
    }
    service.name()
}

/// The name of attribute `attribute` of `instance` of `class`, if known. Instance 0 addresses the
/// class itself, whose attribute 1 is the revision.
pub fn attribute_name(class: u16, instance: u16, attribute: u8) -> Option<&'static str> {
    if instance == 0 {
        return match attribute {
            1 => Some("revision"),
            _ => None,
        };
    }
    Some(match (class, attribute) {
        // Identity, protocol §6.2.
        (class::IDENTITY, 1) => "vendor ID",
        (class::IDENTITY, 2) => "device type",
        (class::IDENTITY, 3) => "product code",
        (class::IDENTITY, 4) => "revision",
        (class::IDENTITY, 5) => "status",
        (class::IDENTITY, 6) => "serial number",
        (class::IDENTITY, 7) => "product name",
        (class::IDENTITY, 8) => "state",
        (class::IDENTITY, 9) => "configuration consistency value",
        (class::IDENTITY, 10) => "heartbeat interval",
        // DeviceNet, protocol §6.1.
        (class::DEVICENET, 1) => "MAC ID",
        (class::DEVICENET, 2) => "baud rate",
        (class::DEVICENET, 3) => "bus-off interrupt",
        (class::DEVICENET, 4) => "bus-off counter",
        (class::DEVICENET, 5) => "allocation information",
        (class::DEVICENET, 6) => "MAC ID switch changed",
        (class::DEVICENET, 7) => "baud rate switch changed",
        (class::DEVICENET, 8) => "MAC ID switch value",
        (class::DEVICENET, 9) => "baud rate switch value",
        // Assembly.
        (class::ASSEMBLY, 3) => "data",
        (class::ASSEMBLY, 4) => "size",
        // Connection, protocol §5.1.
        (class::CONNECTION, 1) => "state",
        (class::CONNECTION, 2) => "instance type",
        (class::CONNECTION, 3) => "transport class trigger",
        (class::CONNECTION, 4) => "produced connection ID",
        (class::CONNECTION, 5) => "consumed connection ID",
        (class::CONNECTION, 6) => "initial comm characteristics",
        (class::CONNECTION, 7) => "produced connection size",
        (class::CONNECTION, 8) => "consumed connection size",
        (class::CONNECTION, 9) => "expected packet rate",
        (class::CONNECTION, 12) => "watchdog timeout action",
        (class::CONNECTION, 13) => "produced connection path length",
        (class::CONNECTION, 14) => "produced connection path",
        (class::CONNECTION, 15) => "consumed connection path length",
        (class::CONNECTION, 16) => "consumed connection path",
        (class::CONNECTION, 17) => "production inhibit time",
        _ => return None,
    })
}

/// The name of a Connection object state, attribute 1 (protocol §5.2).
pub fn connection_state_name(state: u8) -> Option<&'static str> {
    Some(match state {
        0 => "non-existent",
        1 => "configuring",
        2 => "waiting for connection ID",
        3 => "established",
        4 => "timed out",
        5 => "deferred delete",
        _ => return None,
    })
}

/// The name of a watchdog timeout action, Connection attribute 12 (protocol §5.4).
pub fn watchdog_action_name(action: u8) -> Option<&'static str> {
    Some(match action {
        0 => "transition to timed out",
        1 => "auto delete",
        2 => "auto reset",
        3 => "deferred delete",
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::identity(class::IDENTITY, Some("Identity"))]
    #[case::connection(class::CONNECTION, Some("Connection"))]
    #[case::unknown(0x99, None)]
    fn class_names(#[case] id: u16, #[case] name: Option<&str>) {
        assert_eq!(class_name(id), name);
    }

    #[rstest]
    #[case::vendor(class::IDENTITY, 1, 1, Some("vendor ID"))]
    #[case::product_name(class::IDENTITY, 1, 7, Some("product name"))]
    #[case::epr(class::CONNECTION, 2, 9, Some("expected packet rate"))]
    #[case::watchdog(class::CONNECTION, 1, 12, Some("watchdog timeout action"))]
    #[case::class_revision(class::CONNECTION, 0, 1, Some("revision"))]
    #[case::class_other(class::CONNECTION, 0, 2, None)]
    #[case::unknown_attr(class::IDENTITY, 1, 99, None)]
    #[case::unknown_class(0x99, 1, 1, None)]
    fn attribute_names(#[case] class: u16, #[case] inst: u16, #[case] attr: u8, #[case] name: Option<&str>) {
        assert_eq!(attribute_name(class, inst, attr), name);
    }

    #[rstest]
    #[case::allocate_on_devicenet(class::DEVICENET, 0x4B, Some("Allocate_Master/Slave_Connection_Set"))]
    #[case::release_on_devicenet(class::DEVICENET, 0x4C, Some("Release_Master/Slave_Connection_Set"))]
    #[case::object_specific_elsewhere(0x66, 0x4B, None)]
    #[case::last_object_specific_elsewhere(class::IDENTITY, 0x63, None)]
    #[case::common_service_anywhere(0x66, 0x0E, Some("Get_Attribute_Single"))]
    fn service_names(#[case] class: u16, #[case] code: u8, #[case] name: Option<&str>) {
        assert_eq!(service_name(class, crate::explicit::ServiceCode::from(code)), name);
    }

    #[test]
    fn state_and_action_names() {
        assert_eq!(connection_state_name(3), Some("established"));
        assert_eq!(connection_state_name(6), None);
        assert_eq!(watchdog_action_name(3), Some("deferred delete"));
        assert_eq!(watchdog_action_name(4), None);
    }
}
