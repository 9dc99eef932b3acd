//! The adapter's side of automatic device replacement (issue 28 item 1, guide:
//! docs/src/integrator/replace.md) on the real SLCAN path: the soft slave and the simulated
//! breaker on socat pty pairs, the master in this process and `dnet-master configure` as a
//! program. A device in the program position with nothing stored comes up at MAC 63; a MAC set
//! over the network is stored and leaves Identity attribute 9 (the configuration consistency
//! value, protocol §II.5.3) alone; a download changes the CCV to the one of the image downloaded;
//! a restart keeps MAC and CCV.
//!
//! Needs socat: ignored in the plain host-test run, run by `scripts/check`'s adr-device stage
//! (`cargo build -p soft-slave -p master-harness && cargo test -p system-tests --test adr_device
//! -- --ignored`).

use devicenet::explicit::{GeneralStatus, Request, ServiceCode};
use devicenet::MacId;
use master_core::client::Port;
use master_core::error::MasterError;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use pty_rig::PtyRig;
use slave_fw::converter::consistency::consistency_value;
use slave_fw::description::DeviceDescription;
use std::path::{Path, PathBuf};

fn mac(m: u8) -> MacId {
    MacId::new(m).unwrap()
}

/// The reference breaker's description in the program position, with `edit` applied to its
/// text, written to `dir/name`; and its image's CCV.
fn description(dir: &Path, name: &str, edit: &dyn Fn(String) -> String) -> (PathBuf, u16) {
    let text = std::fs::read_to_string(pty_rig::workspace_dir().join("slave-fw/descriptions/breaker.toml"))
        .unwrap()
        .replace("programmable = false", "programmable = true");
    let text = edit(text);
    assert!(text.contains("programmable = true"));
    let path = dir.join(name);
    std::fs::write(&path, &text).unwrap();
    let parsed = DeviceDescription::parse(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
    let image = slave_fw::image::encode_to_vec(&parsed.converter).unwrap();
    (path, consistency_value(&image))
}

/// A master on the rig's CAN link (the breaker description's 250 kbit/s).
fn master_bus(rig: &PtyRig) -> can_io::bus::slcan::SlcanBus<Box<dyn serialport::SerialPort>> {
    can_io::bus::slcan::open(&rig.can.b, 115_200, can_io::bus::Bitrate::K250)
        .unwrap_or_else(|e| panic!("opening the master's end {}: {e}\n{}", rig.can.b, rig.dump()))
}

/// Identity attribute 9 at `at`, through a fresh master session.
fn read_ccv(rig: &PtyRig, at: MacId) -> Result<u16, MasterError> {
    let mut bus = master_bus(rig);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    master.open_explicit(at)?;
    let (value, _) = master.get(at, 1, 1, 9)?;
    master.release_held()?;
    let [lo, hi] = value.as_slice() else { panic!("attribute 9 is {value:02x?}, not a UINT") };
    Ok(u16::from_le_bytes([*lo, *hi]))
}

#[test]
#[ignore = "needs socat: run by scripts/check's adr-device stage"]
fn a_replacement_comes_up_at_63_keeps_its_ccv_when_moved_and_takes_a_new_one_with_a_download() {
    if !pty_rig::require_socat() {
        return;
    }
    let dir = pty_rig::scratch("adr-device-files");
    let (factory, factory_ccv) = description(&dir, "factory.toml", &|t| t);
    // Another configuration of the same device: the instrument data goes stale after 5 s.
    let (other, other_ccv) =
        description(&dir, "other.toml", &|t| t.replace("stale_timeout_ms = 3000", "stale_timeout_ms = 5000"));
    assert_ne!(factory_ccv, other_ccv, "the two configurations must differ");
    let state = dir.join("state.json");
    let state_arg = state.to_str().unwrap().to_string();
    let mut rig =
        PtyRig::breaker_with("adr-device", &["--period", "0.3"], Some(&factory), &["--state", &state_arg]);

    // Out of the box (nothing stored, program position): MAC 63, the factory configuration's CCV.
    let started = rig.slave.as_ref().unwrap().stderr.text();
    assert!(started.contains("dnet-soft-slave: MAC 63 "), "{started}");
    assert_eq!(read_ccv(&rig, mac(63)).map_err(|e| e.to_string()), Ok(factory_ccv), "{}", rig.dump());

    {
        let mut bus = master_bus(&rig);
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        master.open_explicit(mac(63)).unwrap_or_else(|e| panic!("{e}\n{}", rig.dump()));
        // The CCV follows the configuration: a tool cannot write it (0x0E, attribute not settable).
        match master.set(mac(63), 1, 1, 9, &[0x34, 0x12]) {
            Err(MasterError::ErrorResponse { general: GeneralStatus::AttributeNotSettable, .. }) => {}
            other => panic!("Set of attribute 9: {other:?}\n{}", rig.dump()),
        }
        // Address recovery's move: DeviceNet attribute 1 := 12, then an Identity Reset.
        master.set(mac(63), 3, 1, 1, &[12]).unwrap_or_else(|e| panic!("{e}\n{}", rig.dump()));
        let reset = Request { service: ServiceCode::Reset, class: 1, instance: 1, data: &[] };
        master.request_ok(mac(63), Port::Explicit, &reset).unwrap_or_else(|e| panic!("{e}\n{}", rig.dump()));
    }
    assert_eq!(
        read_ccv(&rig, mac(12)).map_err(|e| e.to_string()),
        Ok(factory_ccv),
        "moved: same CCV\n{}",
        rig.dump()
    );

    // `dnet-master configure` downloads the other configuration (and resets the device).
    let bus = rig.master_bus_arg();
    let mut configure = pty_rig::Proc::spawn(
        pty_rig::bin("dnet-master"),
        &["--bus", &bus, "--bitrate", "250k", "configure", "--mac", "12", other.to_str().unwrap()],
    );
    let status = configure.wait(std::time::Duration::from_secs(60)).expect("configure ends");
    assert_eq!(status.code(), Some(0), "{}\n{}", configure.dump(), rig.dump());
    assert_eq!(
        read_ccv(&rig, mac(12)).map_err(|e| e.to_string()),
        Ok(other_ccv),
        "after configure\n{}",
        rig.dump()
    );
    let kept = std::fs::read_to_string(&state).unwrap();
    assert!(kept.contains("\"mac_id\": 12") && kept.contains("\"configuration\""), "{kept}");

    // A restart with the same state (the board's power cycle): same MAC, same CCV.
    rig.stop_slave();
    rig.start_slave_with(Some(&factory), &["--state", &state_arg]);
    assert_eq!(
        read_ccv(&rig, mac(12)).map_err(|e| e.to_string()),
        Ok(other_ccv),
        "after the restart\n{}",
        rig.dump()
    );
}
