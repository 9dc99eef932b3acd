//! The plant of the multi-network tests (`dnet-master ui --plant FILE`): the simulated breaker's
//! scan list, a plant file naming one network per bus, and two breaker benches on socat ptys as
//! the networks of the real SLCAN path.

use crate::PtyRig;
use std::path::{Path, PathBuf};

/// A scan list of one node: the simulated breaker (`dnet-sim-breaker` behind `dnet-soft-slave`,
/// or the simulated bus's breaker) at MAC 5, polled, 18 input and 8 output bytes. It ends with a
/// newline, so a test may append keys of the node (`adr = ...`).
pub const BREAKER_SCANLIST: &str = r#"
[[node]]
mac = 5
connection = "poll"
vendor_id = 0x1234
device_type = 0x000C
product_code = 1
major_revision = 1
input_size = 18
output_size = 8
"#;

/// Writes `dir/plant.toml` with a network per `(name, bus)`, each scanning its own copy of
/// [`BREAKER_SCANLIST`] (`dir/NAME.toml`); its path.
pub fn plant_file(dir: &Path, networks: &[(&str, &str)]) -> PathBuf {
    let mut text = String::new();
    for (name, bus) in networks {
        let list = dir.join(format!("{name}.toml"));
        std::fs::write(&list, BREAKER_SCANLIST).unwrap_or_else(|e| panic!("{}: {e}", list.display()));
        text.push_str(&format!(
            "[[network]]\nname = \"{name}\"\nbus = \"{bus}\"\nscanlist = \"{name}.toml\"\n\n"
        ));
    }
    let path = dir.join("plant.toml");
    std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    path
}

/// Two breaker benches (`TEST-a`, `TEST-b`), each the simulated breaker reporting every 0.3 s
/// behind a soft slave at MAC 5 with its built-in description: two networks on the SLCAN path.
pub fn two_breaker_benches(test: &str) -> (PtyRig, PtyRig) {
    let bench = |net: &str| PtyRig::breaker(&format!("{test}-{net}"), &["--period", "0.3"], None);
    (bench("a"), bench("b"))
}
