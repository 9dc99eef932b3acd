//! The Modbus unit table in the EDS: for a Modbus gateway, four monitor parameters per distinct
//! unit address of the scan list (state, lost data, retries, exceptions), read from the Modbus
//! unit health object ([`slave_fw::converter::UNITS_CLASS`] 0x69) instance `n` for the `n`-th unit
//! in scan list order, attributes 2–5 (`slave_fw::converter::units_object`). Numbered from
//! [`FIRST_UNIT_PARAM`] on, in the "Modbus units" group; none for a framed instrument.

use super::{choices, logical_path, Spec, FIRST_LINK_PARAM, LINK_PARAM_COUNT, MONITOR};
use crate::value::DataType;
use slave_fw::converter::UNITS_CLASS;
use slave_fw::description::DeviceDescription;
use slave_fw::serial::modbus::UnitState;
use slave_fw::serial::ProfileConfig;

/// Number of the first unit parameter, after the serial link's.
pub const FIRST_UNIT_PARAM: u32 = FIRST_LINK_PARAM + LINK_PARAM_COUNT;

/// Parameters per unit.
pub const PARAMS_PER_UNIT: u32 = 4;

/// The distinct unit addresses of the scan list, in scan list order (the object's instances).
pub fn units(description: &DeviceDescription) -> Vec<u8> {
    let mut units = Vec::new();
    if let ProfileConfig::Modbus(m) = &description.converter.profile {
        for e in &m.scan {
            if !units.contains(&e.unit) {
                units.push(e.unit);
            }
        }
    }
    units
}

/// The unit parameters of `description` (module docs).
pub(super) fn unit_parameters(description: &DeviceDescription) -> Vec<Spec> {
    let state_choices = choices(&[
        (UnitState::Starting as i128, "Starting"),
        (UnitState::Ok as i128, "Ok"),
        (UnitState::Lost as i128, "Lost"),
        (UnitState::Exception as i128, "Exception"),
    ]);
    let mut specs = Vec::new();
    for (n, unit) in (1u8..).zip(units(description)) {
        let number = FIRST_UNIT_PARAM + u32::from(n - 1) * PARAMS_PER_UNIT;
        let counter = |k: u32, attribute: u8, name: &str, help: String| Spec {
            number: number + k,
            path: logical_path(UNITS_CLASS, n, attribute),
            descriptor: MONITOR,
            data_type: DataType::Udint,
            name: format!("Unit {unit} {name}"),
            units: "",
            help,
            min: 0,
            max: u32::MAX.into(),
            default: 0,
            choices: Vec::new(),
        };
        specs.push(Spec {
            number,
            path: logical_path(UNITS_CLASS, n, 2),
            descriptor: MONITOR,
            data_type: DataType::Usint,
            name: format!("Unit {unit} state"),
            units: "",
            help: format!(
                "Modbus unit {unit}: lost when its last transaction failed after all retries or it has \
                 not answered within the stale timeout; exception when its last answer was one"
            ),
            min: 0,
            max: 3,
            default: 0,
            choices: state_choices.clone(),
        });
        specs.push(counter(
            1,
            3,
            "lost data",
            format!("Modbus unit {unit}: transactions failed after all retries"),
        ));
        specs.push(counter(
            2,
            4,
            "retries",
            format!("Modbus unit {unit}: repetitions sent after a timeout or corrupted answer"),
        ));
        specs.push(counter(3, 5, "exceptions", format!("Modbus unit {unit}: exception responses")));
    }
    specs
}

/// The "Modbus units" group's parameter numbers (empty for a framed instrument).
pub(super) fn unit_group(description: &DeviceDescription) -> Vec<u32> {
    let count = units(description).len() as u32 * PARAMS_PER_UNIT;
    (FIRST_UNIT_PARAM..FIRST_UNIT_PARAM + count).collect()
}

#[cfg(test)]
mod tests {
    use super::super::{generate, input_help, GenerateOptions};
    use super::*;
    use crate::value::LinkPath;

    fn meter() -> DeviceDescription {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../slave-fw/descriptions/modbus-meter.toml");
        DeviceDescription::load(&path).unwrap()
    }

    #[test]
    fn each_distinct_unit_gets_its_instance_and_four_parameters() {
        let mut d = meter();
        let ProfileConfig::Modbus(m) = &mut d.converter.profile else { panic!("not Modbus") };
        // Units 1, 9, 1: two units, 9 is instance 2.
        m.scan[1].unit = 9;
        assert_eq!(units(&d), [1, 9]);
        let eds = generate(&d, &GenerateOptions::default());
        let second = FIRST_UNIT_PARAM + PARAMS_PER_UNIT;
        let p = eds.param(second + 1).unwrap();
        assert_eq!(p.name, "Unit 9 lost data");
        let path = p.link_path.as_ref().and_then(LinkPath::attribute).unwrap();
        assert_eq!((path.class, path.instance, path.attribute), (UNITS_CLASS, 2, Some(3)));
        assert!(eds.param(second + PARAMS_PER_UNIT).is_none(), "nothing after the last unit");
        let group = eds.groups().find(|(_, g)| g.name == "Modbus units").unwrap().1;
        assert_eq!(group.params, (FIRST_UNIT_PARAM..second + PARAMS_PER_UNIT).collect::<Vec<_>>());
    }

    #[test]
    fn a_framed_instrument_has_no_unit_parameters_or_group() {
        let eds = generate(&DeviceDescription::reference(), &GenerateOptions::default());
        assert!(eds.param(FIRST_UNIT_PARAM).is_none());
        assert!(eds.groups().all(|(_, g)| g.name != "Modbus units"));
    }

    #[test]
    fn the_assembly_help_places_the_data_valid_bits() {
        let mut d = meter();
        assert!(!input_help(&d).contains("data-valid"));
        let ProfileConfig::Modbus(m) = &mut d.converter.profile else { panic!("not Modbus") };
        m.valid_bits_offset = Some(12);
        m.input_len = 13;
        let help = input_help(&d);
        assert!(help.contains("; byte 12: data-valid bits, bit k for scan entry k"), "{help}");
        assert!(help.contains("byte 13: link status"), "{help}");
    }
}
