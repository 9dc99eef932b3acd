//! `configure --mac N FILE` and `configure --mac N --read FILE`: a device description reaches the
//! adapter over DeviceNet, and comes back from it, with no toolchain on the integrator's side.
//!
//! Download ([`download`]):
//!
//! 1. the description is loaded and validated (the TOML loader's errors, naming file and key),
//!    then encoded as the configuration image ([`slave_fw::image`]);
//! 2. an explicit connection is allocated; Begin_Download (0x4C) with the size, the image in
//!    chunks of [`CHUNK`] bytes with Write_Chunk (0x4D, offset first), Commit_Download (0x4E) on
//!    the configuration object ([`CONFIGURATION_CLASS`], instance 1). A refusal is reported with
//!    the device's reason (attribute 5, a refusal record of numbers and the key that the master
//!    words, `RefusalRecord`), e.g. `profile.serial.baud: 4000000 is outside the allowed range
//!    300..=2625000`;
//! 3. the stored image is read back (Read_Chunk 0x4B of the pending image) and compared byte for
//!    byte;
//! 4. Identity Reset; the master watches for the device's duplicate MAC ID check (at `--mac` or at
//!    the description's MAC) and waits until it is on-line. When the description's data rate is
//!    not the one the device runs at (the bus's), the master says so first ([`DownloadReport::notes`],
//!    and the `note` callback at once): a device that takes its data rate from the description
//!    (the soft slave, the simulated device) leaves this bus at its reset;
//! 5. the device is checked against the description: configuration state "stored image in force"
//!    and the image's CRC, Identity vendor, device type, product code, revision and product name,
//!    and the poll connection's produced and consumed sizes; and the serial number is the one the
//!    device had before: a device keeps its own (the board's from its MCU's unique ID, the soft
//!    slave's from its state file), the description's is a default for simulated devices only.
//!
//! Values are written as `dnet-master decode` writes them ([`value_text`]); every error names the
//! request that failed ([`request_name`] for the configuration object's own services, whose codes
//! other classes use for other services).
//!
//! Upload ([`upload`]): the image in force is read in chunks, decoded and written as a
//! description file ([`slave_fw::description::DeviceDescription::to_toml`]).
//!
//! The configuration object's services and attributes are the converter's
//! (`slave_fw::converter`); protocol §3.2 for the service code ranges (0x4B–0x63: object class
//! specific).

use devicenet::explicit::{Request, ServiceCode};
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::slave::BaudRate;
use devicenet::{Duration, MacId};
use harness_common::error::HarnessError;
use master_core::client::Port;
use master_core::decode::value_text;
use master_core::error::{MasterError, UsageError};
use master_core::master::Master;
use slave_fw::converter::config_object::RefusalRecord;
use slave_fw::converter::ConverterConfig;
use slave_fw::description::DeviceDescription;

/// The configuration object (vendor class).
pub const CONFIGURATION_CLASS: u16 = 0x66;
/// Read_Chunk: `[which][offset UINT][count USINT]`.
pub const READ_CHUNK: u8 = 0x4B;
/// Begin_Download: `[size UINT]`.
pub const BEGIN_DOWNLOAD: u8 = 0x4C;
/// Write_Chunk: `[offset UINT][bytes]`.
pub const WRITE_CHUNK: u8 = 0x4D;
/// Commit_Download: no data.
pub const COMMIT_DOWNLOAD: u8 = 0x4E;
/// Bytes of image per request: a Write_Chunk request is then 62 bytes, within the device's
/// 64-byte explicit message limit.
pub const CHUNK: usize = 56;
/// How long the device may take to come back after its reset (its duplicate MAC ID check takes
/// 2 s of that).
pub const BACK_ONLINE: Duration = Duration::from_secs(6);

/// How often the wait for the device after its reset looks for its duplicate MAC ID check.
const WATCH_STEP: Duration = Duration::from_millis(100);

/// The wait after the device is on-line, by the master's reckoning, before the first request.
const ONLINE_MARGIN: Duration = Duration::from_millis(250);

/// One comparison of the device against the description.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Check {
    /// What was compared.
    pub what: String,
    /// The description's value.
    pub expected: String,
    /// The device's.
    pub actual: String,
}

impl Check {
    /// Whether they agree.
    #[must_use]
    pub fn holds(&self) -> bool {
        self.expected == self.actual
    }
}

/// What a download did.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct DownloadReport {
    /// The device's MAC before the download.
    pub mac: u8,
    /// Where it came back after the reset.
    pub back_at: Option<u8>,
    /// Image bytes.
    pub bytes: usize,
    /// Write_Chunk requests.
    pub chunks: usize,
    /// The read-back equals the image.
    pub verified: bool,
    /// Bus time from the reset to the device being on-line again, ms.
    pub back_online_ms: Option<u64>,
    /// The device against the description.
    pub checks: Vec<Check>,
    /// What the master said before the reset (a data rate other than the bus's).
    pub notes: Vec<String>,
}

impl DownloadReport {
    /// Checks that failed.
    #[must_use]
    pub fn failures(&self) -> Vec<&Check> {
        self.checks.iter().filter(|c| !c.holds()).collect()
    }
}

fn service(code: u8) -> ServiceCode {
    ServiceCode::from(code)
}

/// The configuration object's request `code` with `data`, by name: `Read_Chunk (0x4B) of the
/// stored image at offset 56, 42 bytes, configuration object (class 0x66, instance 1)`. Its
/// services are class-specific (protocol §3.2): the decoder's names for their codes are other
/// classes' services (0x4B is the DeviceNet object's Allocate).
#[must_use]
pub fn request_name(code: u8, data: &[u8]) -> String {
    let what = match (code, data) {
        (READ_CHUNK, &[which, lo, hi, count]) => format!(
            "Read_Chunk (0x4B) of the {} image at offset {}, {count} bytes",
            match which {
                0 => "in force",
                1 => "stored",
                _ => "unknown",
            },
            u16::from_le_bytes([lo, hi])
        ),
        (BEGIN_DOWNLOAD, &[lo, hi]) => {
            format!("Begin_Download (0x4C) of {} bytes", u16::from_le_bytes([lo, hi]))
        }
        (WRITE_CHUNK, &[lo, hi, ref part @ ..]) => {
            format!("Write_Chunk (0x4D) at offset {}, {} bytes", u16::from_le_bytes([lo, hi]), part.len())
        }
        (COMMIT_DOWNLOAD, _) => "Commit_Download (0x4E)".to_string(),
        (READ_CHUNK, _) => "Read_Chunk (0x4B)".to_string(),
        (BEGIN_DOWNLOAD, _) => "Begin_Download (0x4C)".to_string(),
        (WRITE_CHUNK, _) => "Write_Chunk (0x4D)".to_string(),
        (other, _) => format!("service 0x{other:02X}"),
    };
    format!("{what}, configuration object (class 0x{CONFIGURATION_CLASS:02X}, instance 1)")
}

/// A class-specific request to the configuration object; an error response becomes
/// [`MasterError::ErrorResponse`] (and the record a failure). Every error names the request
/// ([`request_name`]).
fn config_request(
    master: &mut Master<'_, '_>,
    mac: MacId,
    code: u8,
    data: &[u8],
) -> Result<Vec<u8>, MasterError> {
    let req = Request { service: service(code), class: CONFIGURATION_CLASS, instance: 1, data };
    master.request_ok(mac, Port::Explicit, &req).map(|(d, _)| d).map_err(|e| match e {
        MasterError::ErrorResponse { mac, general, additional, text, .. } => {
            MasterError::ErrorResponse { what: request_name(code, data), mac, general, additional, text }
        }
        MasterError::Timeout { mac, after, timeout, .. } => {
            MasterError::Timeout { what: request_name(code, data), mac, after, timeout }
        }
        MasterError::Protocol { reason, .. } => {
            MasterError::Protocol { what: request_name(code, data), reason }
        }
        other => other,
    })
}

/// The device's reason for its last refusal (configuration object attribute 5).
fn refusal_reason(master: &mut Master<'_, '_>, mac: MacId) -> String {
    match master.get(mac, CONFIGURATION_CLASS, 1, 5) {
        Ok((data, _)) => {
            RefusalRecord::parse(&data).map_or_else(|| "no reason given".into(), |record| record.to_string())
        }
        Err(e) => format!("the reason could not be read: {e}"),
    }
}

/// Reads `size` bytes of image `which` (0 in force, 1 stored) from the device at `mac` in chunks
/// (Read_Chunk; an explicit connection must be open).
pub fn read_image(
    master: &mut Master<'_, '_>,
    mac: MacId,
    which: u8,
    size: usize,
) -> Result<Vec<u8>, MasterError> {
    let mut image = Vec::with_capacity(size);
    while image.len() < size {
        let offset = u16::try_from(image.len()).map_err(|_| UsageError::ImageTooLong { size })?;
        let count = u8::try_from((size - image.len()).min(CHUNK)).unwrap_or(CHUNK as u8);
        let [lo, hi] = offset.to_le_bytes();
        let part = config_request(master, mac, READ_CHUNK, &[which, lo, hi, count])?;
        if part.is_empty() || part.len() > usize::from(count) {
            return Err(MasterError::Protocol {
                what: request_name(READ_CHUNK, &[which, lo, hi, count]),
                reason: format!("{} bytes answered, {count} asked", part.len()),
            });
        }
        image.extend_from_slice(&part);
    }
    Ok(image)
}

/// Attribute `attr` of `class_id` instance `instance` at `mac`, as `decode` writes it.
fn attr_text(
    master: &mut Master<'_, '_>,
    mac: MacId,
    class_id: u16,
    instance: u16,
    attr: u8,
) -> Result<String, MasterError> {
    let (data, _) = master.get(mac, class_id, instance, attr)?;
    Ok(value_text(class_id, instance, attr, &data))
}

/// A data rate as people write it.
fn rate_text(rate: BaudRate) -> String {
    format!("{} kbit/s", rate.bits_per_second() / 1000)
}

/// The configuration object's attribute 3 (the converter's `ConfigState`), in words.
fn config_state_text(data: &[u8]) -> String {
    match data {
        [0] => "0 (factory default in force)".into(),
        [1] => "1 (stored image in force)".into(),
        [2] => "2 (new image pending, applies at reset)".into(),
        [3] => "3 (stored image refused, factory default in force)".into(),
        other => value_text(CONFIGURATION_CLASS, 1, 3, other),
    }
}

/// A CRC-32 (configuration object attribute 4, a UDINT) as `decode` writes a UDINT.
fn crc_text(data: &[u8]) -> String {
    match data {
        &[a, b, c, d] => format!("0x{:08X}", u32::from_le_bytes([a, b, c, d])),
        other => value_text(CONFIGURATION_CLASS, 1, 4, other),
    }
}

/// What the device at `mac` runs before the download: its data rate (the bus's, DeviceNet object
/// attribute 2) and its serial number (Identity attribute 6).
fn before_download(
    master: &mut Master<'_, '_>,
    mac: MacId,
) -> Result<(Option<BaudRate>, Vec<u8>), MasterError> {
    let (rate, _) = master.get(mac, class::DEVICENET, 1, 2)?;
    let rate = rate.first().copied().and_then(BaudRate::from_attribute_value);
    let (serial, _) = master.get(mac, class::IDENTITY, 1, 6)?;
    Ok((rate, serial))
}

/// Downloads `description` to the device at `mac`, verifies, resets and checks it. See the
/// [module docs](self). `note` hears, as it happens, what the master says before the reset (also
/// kept in [`DownloadReport::notes`]).
pub fn download(
    master: &mut Master<'_, '_>,
    mac: MacId,
    description: &DeviceDescription,
    note: &mut dyn FnMut(&str),
) -> Result<DownloadReport, HarnessError> {
    let image = slave_fw::image::encode_to_vec(&description.converter).map_err(HarnessError::Image)?;
    let mut report = DownloadReport { mac: mac.as_raw(), bytes: image.len(), ..DownloadReport::default() };

    master.open_explicit(mac)?;
    let (bus_rate, serial_before) = before_download(master, mac)?;
    let size = u16::try_from(image.len()).map_err(|_| HarnessError::ImageTooLong { bytes: image.len() })?;
    let refused = |master: &mut Master<'_, '_>, step: &'static str, e: MasterError| -> HarnessError {
        match e {
            MasterError::ErrorResponse { text, .. } => {
                let reason = refusal_reason(master, mac);
                HarnessError::ConfigurationRefused { mac, step, response: text, reason }
            }
            other => other.into(),
        }
    };
    config_request(master, mac, BEGIN_DOWNLOAD, &size.to_le_bytes())
        .map_err(|e| refused(master, "Begin_Download", e))?;
    for (k, part) in image.chunks(CHUNK).enumerate() {
        let offset = u16::try_from(k * CHUNK).unwrap_or(u16::MAX);
        let mut data = offset.to_le_bytes().to_vec();
        data.extend_from_slice(part);
        config_request(master, mac, WRITE_CHUNK, &data).map_err(|e| refused(master, "Write_Chunk", e))?;
        report.chunks += 1;
    }
    config_request(master, mac, COMMIT_DOWNLOAD, &[]).map_err(|e| refused(master, "Commit_Download", e))?;
    let back = read_image(master, mac, 1, image.len())?;
    report.verified = back == image;
    if !report.verified {
        return Err(HarnessError::ReadBackDiffers { mac, bytes: image.len() });
    }

    let described_rate = description.converter.device.baud_rate;
    if let Some(bus) = bus_rate.filter(|&bus| bus != described_rate) {
        let text = format!(
            "the description's data rate is {}, MAC {mac} runs at {} (this bus's): a device that takes \
             its data rate from its configuration leaves this bus when it applies it (the board takes \
             it from its switches, the soft slave at its next start)",
            rate_text(described_rate),
            rate_text(bus)
        );
        note(&text);
        report.notes.push(text);
    }

    // Identity Reset: the new configuration applies.
    let reset = Request { service: ServiceCode::Reset, class: class::IDENTITY, instance: 1, data: &[] };
    master.request_ok(mac, Port::Explicit, &reset)?;
    let reset_at = master.session.now();
    // The reset dropped the device's connections: nothing is left to release.
    master.set_held(mac, AllocationChoice::empty());
    let described = description.converter.device.mac_id;
    let candidates: Vec<MacId> = if described == mac { vec![mac] } else { vec![mac, described] };
    let deadline = reset_at + BACK_ONLINE;
    let back_at = loop {
        if let Some(m) = candidates.iter().copied().find(|m| {
            master.tracker.online_at(m.as_raw()).is_some_and(|at| at > reset_at && at <= master.session.now())
        }) {
            break m;
        }
        if master.session.now() >= deadline {
            return Err(HarnessError::NotBackOnline {
                mac,
                within: BACK_ONLINE,
                watched: candidates.clone(),
                notes: report.notes.clone(),
            });
        }
        let until = candidates
            .iter()
            .filter_map(|m| master.tracker.online_at(m.as_raw()).filter(|&at| at > reset_at))
            .min()
            // Until the device's check shows, look again every WATCH_STEP.
            .unwrap_or(master.session.now() + WATCH_STEP)
            .min(deadline);
        master.idle_until(until)?;
    };
    report.back_at = Some(back_at.as_raw());
    report.back_online_ms = Some((master.session.now() - reset_at).total_millis());
    // The device goes on-line by its own clock, 1 s after its second check request; a request
    // sent at the moment the master reckons may reach it first (the emulated board in QEMU,
    // whose clock falls behind the host's when the host is busy). A device still checking does
    // not answer: the allocation is repeated, as a scanner repeats it, until BACK_ONLINE.
    let settled = master.session.now() + ONLINE_MARGIN;
    master.idle_until(settled)?;

    master.set_device(back_at);
    loop {
        match master.allocate(back_at, Port::Group2Only, AllocationChoice::EXPLICIT) {
            Ok(_) => break,
            Err(MasterError::Timeout { .. }) if master.session.now() < deadline => continue,
            Err(e) => return Err(e.into()),
        }
    }
    check_against(master, back_at, description, (&image, &serial_before), &mut report)?;
    Ok(report)
}

/// Compares the device at `mac` with `description`, the `image` downloaded and the serial number
/// it had before (see the [module docs](self), step 5).
fn check_against(
    master: &mut Master<'_, '_>,
    mac: MacId,
    description: &DeviceDescription,
    (image, serial_before): (&[u8], &[u8]),
    report: &mut DownloadReport,
) -> Result<(), HarnessError> {
    let config: &ConverterConfig = &description.converter;
    let id = &config.device.identity;
    let mut check = |what: &str, expected: String, actual: String| {
        report.checks.push(Check { what: what.into(), expected, actual });
    };
    let identity = |attr: u8, bytes: &[u8]| value_text(class::IDENTITY, 1, attr, bytes);
    let (state, _) = master.get(mac, CONFIGURATION_CLASS, 1, 3)?;
    check("configuration state", config_state_text(&[1]), config_state_text(&state));
    let (crc, _) = master.get(mac, CONFIGURATION_CLASS, 1, 4)?;
    let expected_crc = image.get(image.len().saturating_sub(4)..).unwrap_or_default();
    check("configuration CRC-32", crc_text(expected_crc), crc_text(&crc));
    let id_checks: [(&str, u8, Vec<u8>); 6] = [
        ("Identity vendor ID", 1, id.vendor_id.to_le_bytes().to_vec()),
        ("Identity device type", 2, id.device_type.to_le_bytes().to_vec()),
        ("Identity product code", 3, id.product_code.to_le_bytes().to_vec()),
        ("Identity revision", 4, vec![id.major_revision, id.minor_revision]),
        // The device's own, kept (module docs): not the description's.
        ("Identity serial number", 6, serial_before.to_vec()),
        ("Identity product name", 7, short_string_bytes(&id.product_name)),
    ];
    for (what, attr, expected) in id_checks {
        check(what, identity(attr, &expected), attr_text(master, mac, class::IDENTITY, 1, attr)?);
    }
    master.allocate(mac, Port::Explicit, AllocationChoice::POLL)?;
    let device = config.device_config();
    let connection = |size: u16| value_text(class::CONNECTION, 2, 7, &size.to_le_bytes());
    check(
        "poll produced size",
        connection(device.produced_size),
        attr_text(master, mac, class::CONNECTION, 2, 7)?,
    );
    check(
        "poll consumed size",
        connection(device.consumed_size),
        attr_text(master, mac, class::CONNECTION, 2, 8)?,
    );
    Ok(())
}

/// `name` as a SHORT_STRING (a length byte, then the characters), as Identity attribute 7 is sent.
fn short_string_bytes(name: &str) -> Vec<u8> {
    let mut bytes = vec![u8::try_from(name.len()).unwrap_or(u8::MAX)];
    bytes.extend_from_slice(name.as_bytes());
    bytes
}

/// What `configure --read` gives back.
#[derive(Clone, Debug)]
pub struct Uploaded {
    /// The configuration in force, as a description (its `identity.serial_number` is the image's).
    pub description: DeviceDescription,
    /// The device's own serial number (Identity attribute 6), as `decode` writes it: a device
    /// keeps its own whatever the image says ([module docs](self)).
    pub serial_number: String,
}

/// Reads the configuration in force at `mac` and gives it back as a description, with the
/// device's own serial number.
pub fn upload(master: &mut Master<'_, '_>, mac: MacId) -> Result<Uploaded, HarnessError> {
    master.open_explicit(mac)?;
    let size = master.get_u16(mac, CONFIGURATION_CLASS, 1, 2)?.ok_or_else(|| MasterError::Protocol {
        what: "configuration size".into(),
        reason: "not a UINT".into(),
    })?;
    let image = read_image(master, mac, 0, usize::from(size))?;
    let converter = slave_fw::image::decode(&image)
        .map_err(|e| HarnessError::ImageUndecodable { mac, detail: e.to_string() })?;
    let (serial, _) = master.get(mac, class::IDENTITY, 1, 6)?;
    Ok(Uploaded {
        description: DeviceDescription { converter, vendor_name: String::new(), catalog: String::new() },
        serial_number: value_text(class::IDENTITY, 1, 6, &serial),
    })
}
