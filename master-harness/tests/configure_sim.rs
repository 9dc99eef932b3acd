//! `configure` and `params` on the simulated bus (the converter as a simulated device, which keeps
//! a downloaded image across its Identity Reset as the board keeps it in flash), and the bad
//! inputs: each refused with a clear error, the device working on.

use devicenet::explicit::{Request, ServiceCode};
use devicenet::MacId;
use master_core::client::Port;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use master_harness::cli::run;
use master_harness::configure::{BEGIN_DOWNLOAD, COMMIT_DOWNLOAD, CONFIGURATION_CLASS, WRITE_CHUNK};
use slave_fw::converter::config_object::RefusalRecord;
use slave_fw::description::DeviceDescription;
use std::path::PathBuf;

fn workspace_file(path: &str) -> String {
    pty_rig::workspace_dir().join(path).to_str().unwrap().to_string()
}

fn dnet(args: &[&str]) -> (u8, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut all = vec!["dnet-master"];
    all.extend_from_slice(args);
    let code = run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-configure-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn the_reference_device_becomes_the_meter_and_reads_back() {
    let meter = workspace_file("slave-fw/descriptions/modbus-meter.toml");
    let (code, out, err) = dnet(&["--bus", "sim", "configure", "--mac", "5", &meter]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("read back and verified"), "{out}");
    // The meter's description says MAC 7: the device comes back there.
    assert!(out.contains("on-line again at MAC 7"), "{out}");
    assert!(out.contains("the device runs the description"), "{out}");
    assert!(!out.contains("FAIL"), "{out}");
}

/// The line of `out` that reports `what`.
fn line_of<'a>(out: &'a str, what: &str) -> &'a str {
    out.lines().find(|l| l.contains(what)).unwrap_or_else(|| panic!("no {what} line in\n{out}"))
}

#[test]
fn values_are_written_as_decode_writes_them_and_the_serial_number_is_the_devices() {
    let meter = workspace_file("slave-fw/descriptions/modbus-meter.toml");
    let (code, out, err) = dnet(&["--bus", "sim", "configure", "--mac", "5", &meter]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(!out.contains('['), "no byte lists: {out}");
    // The reference device's own serial number, kept: not the description's 0x00C0FFEE.
    assert!(line_of(&out, "Identity serial number").ends_with(" 0x12345678"), "{out}");
    assert!(!out.contains("C0FFEE"), "{out}");
    let crc = line_of(&out, "configuration CRC-32").split_whitespace().last().unwrap();
    assert!(crc.len() == 10 && crc.starts_with("0x"), "a UDINT: {out}");
    assert!(line_of(&out, "Identity vendor ID").ends_with(" 0x1234 (4660)"), "{out}");
    assert!(line_of(&out, "Identity revision").ends_with(" 1.0"), "{out}");
    assert!(line_of(&out, "Identity product name").ends_with(" \"Modbus-DeviceNet Gateway\""), "{out}");
    assert!(line_of(&out, "poll produced size").ends_with(" 14 bytes"), "{out}");
    assert!(line_of(&out, "configuration state").ends_with(" 1 (stored image in force)"), "{out}");
}

#[test]
fn a_data_rate_other_than_the_buss_is_said_before_the_reset() {
    // The meter's description says 500k; the simulated bus runs at 250k.
    let meter = workspace_file("slave-fw/descriptions/modbus-meter.toml");
    let (code, out, err) = dnet(&["--bus", "sim", "configure", "--mac", "5", &meter]);
    assert_eq!(code, 0, "{out}{err}");
    let note = out
        .find("note: the description's data rate is 500 kbit/s, MAC 5 runs at 250 kbit/s")
        .unwrap_or_else(|| panic!("{out}"));
    assert!(note < out.find("; reset;").unwrap(), "said before the reset: {out}");
    // The same rate as the bus: nothing said.
    let same = temp("meter-250k.toml");
    let text =
        std::fs::read_to_string(&meter).unwrap().replace("baud_rate = \"500k\"", "baud_rate = \"250k\"");
    std::fs::write(&same, text).unwrap();
    let (code, out, err) = dnet(&["--bus", "sim", "configure", "--mac", "5", same.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(!out.contains("data rate"), "{out}");
}

#[test]
fn a_failing_read_chunk_names_the_read_chunk() {
    let mut bus = system_bus();
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let mac = MacId::new(5).unwrap();
    master.open_explicit(mac).unwrap();
    // Nothing was downloaded: the stored image cannot be read (object state conflict).
    let e = master_harness::configure::read_image(&mut master, mac, 1, 10).unwrap_err().to_string();
    assert!(
        e.starts_with(
            "Read_Chunk (0x4B) of the stored image at offset 0, 10 bytes, configuration object (class 0x66, instance 1): MAC 5 answered with an error"
        ),
        "{e}"
    );
    assert!(!e.contains("Allocate"), "{e}");
}

#[test]
fn two_devices_configured_from_one_file_keep_their_own_serial_numbers() {
    let mut bus = can_io::sim::SimBus::new(can_io::bus::Bitrate::K250);
    for mac in [5, 6] {
        bus.attach(
            Box::new(converter_sim::SoftSlave::reference(MacId::new(mac).unwrap())),
            can_io::sim::PowerOn::WhenMasterOnline,
        );
    }
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let mut meter = DeviceDescription::load(std::path::Path::new(&workspace_file(
        "slave-fw/descriptions/modbus-meter.toml",
    )))
    .unwrap();
    let mut serials = Vec::new();
    for mac in [5, 6] {
        let mac = MacId::new(mac).unwrap();
        // The file's MAC is the device's own, so that the two stay apart.
        meter.converter.device.mac_id = mac;
        let report = master_harness::configure::download(&mut master, mac, &meter, &mut |_| {}).unwrap();
        assert!(report.failures().is_empty(), "{report:?}");
        serials.push(master.get(mac, 1, 1, 6).unwrap().0);
        master.release_held().unwrap();
    }
    // The reference devices' own (0x12345678 + MAC - 5), not the description's.
    assert_eq!(serials, [0x1234_5678u32.to_le_bytes(), 0x1234_5679u32.to_le_bytes()]);
}

#[test]
fn a_description_that_fails_validation_names_the_key_and_sends_nothing() {
    let bad = temp("bad-meter.toml");
    let text = std::fs::read_to_string(workspace_file("slave-fw/descriptions/modbus-meter.toml"))
        .unwrap()
        .replace("mac_id = 7", "mac_id = 70");
    std::fs::write(&bad, text).unwrap();
    let log = temp("bad-meter.log");
    let (code, _, err) = dnet(&[
        "--bus",
        "sim",
        "--log",
        log.to_str().unwrap(),
        "configure",
        "--mac",
        "5",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("network.mac_id: 70 is outside 0..=63"), "{err}");
    assert_eq!(std::fs::read_to_string(&log).unwrap_or_default(), "", "nothing was sent");
}

/// Sends a raw download of `image` to the reference device; the device's answer to the commit.
fn raw_download(image: &[u8]) -> (Result<(), String>, String) {
    let mut bus = system_bus();
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let mac = MacId::new(5).unwrap();
    master.open_explicit(mac).unwrap();
    let request = |master: &mut Master<'_, '_>, code: u8, data: &[u8]| {
        let req = Request { service: ServiceCode::from(code), class: CONFIGURATION_CLASS, instance: 1, data };
        master.request_ok(mac, Port::Explicit, &req).map(|_| ()).map_err(|e| e.to_string())
    };
    let size = u16::try_from(image.len()).unwrap();
    let mut result = request(&mut master, BEGIN_DOWNLOAD, &size.to_le_bytes());
    if result.is_ok() {
        for (k, part) in image.chunks(56).enumerate() {
            let mut data = u16::try_from(k * 56).unwrap().to_le_bytes().to_vec();
            data.extend_from_slice(part);
            result = request(&mut master, WRITE_CHUNK, &data);
            if result.is_err() {
                break;
            }
        }
    }
    if result.is_ok() {
        result = request(&mut master, COMMIT_DOWNLOAD, &[]);
    }
    let reason = master
        .get(mac, CONFIGURATION_CLASS, 1, 5)
        .map(|(d, _)| RefusalRecord::parse(&d).map(|r| r.to_string()).unwrap_or_default())
        .unwrap_or_default();
    // The device works on: it still answers.
    assert_eq!(master.get_u16(mac, 1, 1, 3).unwrap(), Some(1), "still the reference device");
    (result, reason)
}

fn system_bus() -> can_io::sim::SimBus {
    let mut bus = can_io::sim::SimBus::new(can_io::bus::Bitrate::K250);
    bus.attach(
        Box::new(converter_sim::SoftSlave::reference(MacId::new(5).unwrap())),
        can_io::sim::PowerOn::WhenMasterOnline,
    );
    bus
}

fn meter_image() -> Vec<u8> {
    let d = DeviceDescription::load(std::path::Path::new(&workspace_file(
        "slave-fw/descriptions/modbus-meter.toml",
    )))
    .unwrap();
    slave_fw::image::encode_to_vec(&d.converter).unwrap()
}

#[test]
fn bad_images_are_refused_with_the_reason() {
    let good = meter_image();
    let mut wrong_crc = good.clone();
    let last = wrong_crc.len() - 1;
    wrong_crc[last] ^= 0xFF;
    let mut wrong_version = good.clone();
    wrong_version[4] = 9;
    let truncated = good[..good.len() - 7].to_vec();
    for (image, what) in [(wrong_crc, "CRC"), (wrong_version, "version"), (truncated, "")] {
        let (result, reason) = raw_download(&image);
        let e = result.expect_err("refused");
        assert!(e.contains("invalid attribute value (0x09)"), "{what}: {e}");
        assert!(!reason.is_empty(), "{what}: a reason is given");
        if !what.is_empty() {
            assert!(reason.to_lowercase().contains(&what.to_lowercase()), "{what}: {reason}");
        }
    }
    // Oversized: refused at Begin_Download.
    let (result, _) = raw_download(&vec![0u8; slave_fw::image::MAX_IMAGE + 1]);
    assert!(result.unwrap_err().contains("too much data (0x15)"));
}

#[test]
fn parameters_are_listed_set_and_refused_out_of_range() {
    let (code, out, err) = dnet(&["--bus", "sim", "params", "--mac", "5"]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.to_lowercase().contains("stale timeout"), "{out}");
    let (code, out, err) = dnet(&["--bus", "sim", "params", "--mac", "5", "--set", "Stale timeout=0"]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(err.contains("invalid attribute value (0x09)"), "{err}");
    let (code, _, err) = dnet(&["--bus", "sim", "params", "--mac", "5", "--set", "No such thing=1"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no parameter named \"No such thing\""), "{err}");
}

#[test]
fn params_through_the_generated_eds() {
    let eds = temp("breaker.eds");
    let text = eds::generate::generate_text(
        &DeviceDescription::reference(),
        &eds::generate::GenerateOptions::default(),
    );
    std::fs::write(&eds, text).unwrap();
    let (code, out, err) = dnet(&["--bus", "sim", "params", "--mac", "5", "--eds", eds.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("0x0F/"), "the EDS parameters point at the Parameter object: {out}");
}

#[test]
fn a_download_from_a_second_master_is_refused_and_changes_nothing() {
    let mut bus = system_bus();
    let mut session = Session::new(&mut bus);
    let mac = MacId::new(5).unwrap();
    {
        let mut owner = Master::new(
            &mut session,
            MasterConfig { mac: MacId::new(1).unwrap(), ..MasterConfig::default() },
        );
        owner.open_explicit(mac).unwrap();
    }
    let mut second = Master::new(
        &mut session,
        MasterConfig { mac: MacId::new(2).unwrap(), serial_number: 7, ..MasterConfig::default() },
    );
    let meter = DeviceDescription::load(std::path::Path::new(&workspace_file(
        "slave-fw/descriptions/modbus-meter.toml",
    )))
    .unwrap();
    let e =
        master_harness::configure::download(&mut second, mac, &meter, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("MAC 5 is allocated to another master (MAC 1)"), "{e}");
    // Nothing was downloaded: no request of the second master reached the configuration object.
    let requests_to_0x66 = second
        .session
        .records()
        .iter()
        .filter(|r| r.frame.id().as_raw() == 0x42C && r.frame.data().get(2) == Some(&0x66))
        .count();
    assert_eq!(requests_to_0x66, 0);
}
