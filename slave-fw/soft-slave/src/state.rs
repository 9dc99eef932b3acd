//! `--state FILE`: what the board keeps in its settings journal, kept by the soft slave in a file,
//! so that a restarted process behaves like the board after a power cycle.
//!
//! The file holds the settings written over the network (DeviceNet attributes 1–3: MAC ID, data
//! rate, bus-off interrupt; protocol §II.7) and the configuration image downloaded through the
//! configuration object, as JSON, and the device's own serial number:
//!
//! ```json
//! { "mac_id": 9, "baud_rate": "250k", "bus_off_interrupt": false, "configuration": "444E4349...",
//!   "serial_number": 305419896 }
//! ```
//!
//! The serial number is the device's, as the board's comes from its MCU: a downloaded
//! configuration never changes it. Without the key the soft slave takes the serial number of the
//! description it was started with; give each soft slave on one network a state file with its own.
//!
//! Every key is optional; what is absent comes from the description, except the MAC ID of a
//! device in the program position (`programmable = true`): with none stored it starts at 63, as a
//! board does out of the box ([`StoredState::apply`]). The file is replaced
//! atomically (written to a temporary file in the same folder, synced, renamed over the old one,
//! the folder synced), so a crash or power cut at any point leaves the old state or the new one,
//! never a mixture. A file that cannot be read or parsed at start is an error naming the file and
//! the line (exit 2): the soft slave never runs on state it did not understand.

use devicenet::slave::{BaudRate, SettingChanged};
use devicenet::Instant;
use devicenet::MacId;
use slave_fw::converter::{ConfigOrigin, Converter, ConverterConfig, ConverterConfigError};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The state kept across restarts.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoredState {
    /// DeviceNet attribute 1, set over the network.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mac_id: Option<u8>,
    /// DeviceNet attribute 2, set over the network: `125k`, `250k` or `500k`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baud_rate: Option<String>,
    /// DeviceNet attribute 3, set over the network.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bus_off_interrupt: Option<bool>,
    /// The configuration image downloaded over the network, in hex.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub configuration: Option<String>,
    /// The device's own serial number (Identity attribute 6); absent: the description's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub serial_number: Option<u32>,
}

impl StoredState {
    /// The stored data rate.
    pub fn baud(&self) -> Option<BaudRate> {
        match self.baud_rate.as_deref()? {
            "125k" => Some(BaudRate::Kbps125),
            "250k" => Some(BaudRate::Kbps250),
            "500k" => Some(BaudRate::Kbps500),
            _ => None,
        }
    }

    /// Stores `baud`.
    pub fn set_baud(&mut self, baud: BaudRate) {
        self.baud_rate = Some(
            match baud {
                BaudRate::Kbps125 => "125k",
                BaudRate::Kbps250 => "250k",
                BaudRate::Kbps500 => "500k",
            }
            .to_string(),
        );
    }

    /// The stored configuration image's bytes.
    pub fn image(&self) -> Option<Vec<u8>> {
        let hex = self.configuration.as_deref()?;
        if hex.len() % 2 != 0 {
            return None;
        }
        (0..hex.len())
            .step_by(2)
            .map(|i| hex.get(i..i + 2).and_then(|d| u8::from_str_radix(d, 16).ok()))
            .collect()
    }

    /// Stores `image`.
    pub fn set_image(&mut self, image: &[u8]) {
        self.configuration = Some(image.iter().map(|b| format!("{b:02X}")).collect());
    }

    /// Takes a setting changed over the network; `true` when the state changed.
    pub fn note(&mut self, change: &SettingChanged) -> bool {
        let before = self.clone();
        match change {
            SettingChanged::MacId(m) => self.mac_id = Some(m.as_raw()),
            SettingChanged::BaudRate(b) => self.set_baud(*b),
            SettingChanged::BusOffInterrupt(on) => self.bus_off_interrupt = Some(*on),
        }
        *self != before
    }

    /// What the device runs with after a start or a reset: the stored configuration image when
    /// there is one and it decodes, else `base` (the description; [`ConfigOrigin::resolve`], the
    /// board's rule, a refused image being a configuration fault), with the settings on top. In
    /// the program position (`network.programmable`, protocol §II.7) the MAC ID and data rate set
    /// over the network are used, MAC ID 63 when none was set (the description's `mac_id` is then
    /// the switches' value, which the program position ignores, as on the board); the bus-off
    /// interrupt setting always is. `mac_override`
    /// (`--mac`) wins over all. The serial number is the state's, else `base`'s: never the
    /// stored image's (module docs).
    pub fn apply(
        &self,
        base: &ConverterConfig,
        mac_override: Option<MacId>,
    ) -> (ConverterConfig, ConfigOrigin) {
        let image = self.image();
        let (mut config, origin) = ConfigOrigin::resolve(base, image.as_deref());
        let device = &mut config.device;
        if device.switches.programmable {
            // The MAC ID stored over the network; none stored (out of the box): 63, where a
            // scanner's address recovery and the Offline Connection Set look for new devices, as
            // the board without switches does (protocol §II.7, `board::switches`).
            device.mac_id = self.mac_id.and_then(MacId::new).unwrap_or(MacId::MAX);
            if let Some(b) = self.baud() {
                device.baud_rate = b;
            }
        }
        if let Some(on) = self.bus_off_interrupt {
            device.bus_off_interrupt = on;
        }
        device.identity.serial_number = self.serial_number.unwrap_or(base.device.identity.serial_number);
        if let Some(m) = mac_override {
            device.mac_id = m;
        }
        (config, origin)
    }

    /// The converter this state makes on `base` at `now` ([`StoredState::apply`]). A stored image
    /// in force is the image as it was downloaded, whatever network settings run on top of it,
    /// as on the board: a tool reading it back (configuration object attributes 2 and 4,
    /// Read_Chunk) finds the bytes it wrote.
    pub fn converter(
        &self,
        base: &ConverterConfig,
        mac_override: Option<MacId>,
        now: Instant,
    ) -> Result<Converter, ConverterConfigError> {
        let (config, origin) = self.apply(base, mac_override);
        match (origin, self.image()) {
            (ConfigOrigin::Stored, Some(image)) => Converter::with_image(config, origin, &image, now),
            _ => Converter::with_origin(config, origin, now),
        }
    }

    /// The first value out of its range: its key and why.
    fn check(&self) -> Result<(), (&'static str, String)> {
        if let Some(m) = self.mac_id.filter(|&m| m > 63) {
            return Err(("mac_id", format!("{m} is outside 0..=63")));
        }
        if self.baud_rate.is_some() && self.baud().is_none() {
            return Err((
                "baud_rate",
                format!(
                    "\"{}\" is not one of \"125k\", \"250k\", \"500k\"",
                    self.baud_rate.as_deref().unwrap_or_default()
                ),
            ));
        }
        if self.configuration.is_some() && self.image().is_none() {
            return Err(("configuration", "not a string of hex bytes".into()));
        }
        Ok(())
    }
}

/// What is wrong with the `--state` file; each names the file (exit 2: the soft slave never runs
/// on state it did not understand, nor with state it could not keep).
#[derive(Debug, thiserror::Error)]
pub enum StateError {
    /// The file exists but cannot be read.
    #[error("{}: cannot read: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// Not JSON, or not the state's JSON (an unknown key, a value of the wrong type).
    #[error("{}: line {line} column {column}: {source}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What serde_json found.
        source: serde_json::Error,
    },
    /// A value out of its range.
    #[error("{}: {key}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The key.
        key: &'static str,
        /// Why.
        message: String,
    },
    /// The file (or its temporary file, in its folder) cannot be written.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}

/// The state file of `--state FILE`.
#[derive(Clone, Debug)]
pub struct StateFile {
    path: PathBuf,
}

impl StateFile {
    /// The state kept in `path` (which need not exist yet).
    pub fn new(path: impl Into<PathBuf>) -> StateFile {
        StateFile { path: path.into() }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn cannot_write(&self, source: std::io::Error) -> StateError {
        StateError::Write { path: self.path.clone(), source }
    }

    /// Reads the state; an absent file is the empty state.
    pub fn load(&self) -> Result<StoredState, StateError> {
        let path = || self.path.clone();
        let text = match std::fs::read_to_string(&self.path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(StoredState::default()),
            Err(source) => return Err(StateError::Read { path: path(), source }),
        };
        let state: StoredState = serde_json::from_str(&text).map_err(|source| StateError::Parse {
            path: path(),
            line: source.line(),
            column: source.column(),
            source,
        })?;
        state.check().map_err(|(key, message)| StateError::Invalid { path: path(), key, message })?;
        Ok(state)
    }

    /// The file's folder, and the temporary file [`StateFile::save`] writes before the rename.
    fn folder_and_temp(&self) -> (PathBuf, PathBuf) {
        let dir = match self.path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = self.path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let temp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
        (dir, temp)
    }

    /// Checks at start, before the device goes on the bus, that [`StateFile::save`] can work: its
    /// temporary file is created in the file's folder and removed again. A folder that does not
    /// exist or cannot be written is refused here (exit 2), not when a master first changes a
    /// setting (the master would only see the device fall silent).
    pub fn check_writable(&self) -> Result<(), StateError> {
        let (_, temp) = self.folder_and_temp();
        let probe = std::fs::OpenOptions::new().write(true).create_new(true).open(&temp);
        match probe {
            Ok(file) => {
                drop(file);
                std::fs::remove_file(&temp).map_err(|e| self.cannot_write(e))
            }
            Err(e) => Err(self.cannot_write(e)),
        }
    }

    /// Replaces the file with `state`, atomically (see the [module docs](self)).
    pub fn save(&self, state: &StoredState) -> Result<(), StateError> {
        let text = serde_json::to_string_pretty(state).map_err(|e| self.cannot_write(e.into()))?;
        let (dir, temp) = self.folder_and_temp();
        let write = || -> std::io::Result<()> {
            let mut f = std::fs::File::create(&temp)?;
            f.write_all(text.as_bytes())?;
            f.write_all(b"\n")?;
            f.sync_all()?;
            std::fs::rename(&temp, &self.path)?;
            // The rename itself is durable once the folder is synced.
            std::fs::File::open(&dir)?.sync_all()
        };
        write().map_err(|e| {
            let _ = std::fs::remove_file(&temp);
            self.cannot_write(e)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::SoftSlaveError;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("soft-slave-state-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn an_absent_file_is_the_empty_state_and_a_saved_one_reads_back() {
        let file = StateFile::new(temp("roundtrip.json"));
        let _ = std::fs::remove_file(file.path());
        assert_eq!(file.load().unwrap(), StoredState::default());
        let mut state =
            StoredState { mac_id: Some(9), bus_off_interrupt: Some(true), ..StoredState::default() };
        state.set_baud(BaudRate::Kbps500);
        state.set_image(&[0x44, 0x4E, 0x00, 0xFF]);
        file.save(&state).unwrap();
        let back = file.load().unwrap();
        assert_eq!(back, state);
        assert_eq!(back.image(), Some(vec![0x44, 0x4E, 0x00, 0xFF]));
        assert_eq!(back.baud(), Some(BaudRate::Kbps500));
        // No temporary file is left behind.
        let dir = file.path().parent().unwrap();
        let leftovers: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .filter_map(Result::ok)
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }

    #[test]
    fn bad_state_is_refused_with_the_file_and_the_reason() {
        let path = temp("bad.json");
        for (text, needle) in [
            ("{ \"mac_id\": 70 }", "mac_id: 70 is outside 0..=63"),
            ("{ \"baud_rate\": \"1M\" }", "baud_rate: \"1M\" is not one of"),
            ("{ \"configuration\": \"4G\" }", "configuration: not a string of hex bytes"),
            ("{ \"mac\": 5 }", "unknown field `mac`"),
            ("{\n  \"mac_id\": 5,\n", "line 3"),
        ] {
            std::fs::write(&path, text).unwrap();
            let e = StateFile::new(&path).load().map_err(SoftSlaveError::from).unwrap_err().to_string();
            assert!(e.starts_with(&format!("state file {}: ", path.display())), "{e}");
            assert!(e.contains(needle), "{text}: {e}");
            assert_eq!(
                StateFile::new(&path).load().map_err(SoftSlaveError::from).unwrap_err().exit_code(),
                2
            );
        }
    }

    #[test]
    fn stored_settings_apply_in_the_program_position_only_and_mac_overrides_win() {
        let mut base = ConverterConfig::breaker_reference();
        let mut state = StoredState::default();
        assert!(state.note(&SettingChanged::MacId(MacId::new(9).unwrap())));
        assert!(!state.note(&SettingChanged::MacId(MacId::new(9).unwrap())), "no change");
        assert!(state.note(&SettingChanged::BaudRate(BaudRate::Kbps500)));
        assert!(state.note(&SettingChanged::BusOffInterrupt(true)));
        // Not programmable: the description's MAC and rate stay; BOI is taken.
        let (c, origin) = state.apply(&base, None);
        assert_eq!(origin, ConfigOrigin::FactoryDefault);
        assert_eq!((c.device.mac_id.as_raw(), c.device.baud_rate), (5, BaudRate::Kbps250));
        assert!(c.device.bus_off_interrupt);
        base.device.switches.programmable = true;
        let (c, _) = state.apply(&base, None);
        assert_eq!((c.device.mac_id.as_raw(), c.device.baud_rate), (9, BaudRate::Kbps500));
        // Programmable, nothing stored: MAC 63 (out of the box), the description's rate.
        let (c, _) = StoredState::default().apply(&base, None);
        assert_eq!((c.device.mac_id.as_raw(), c.device.baud_rate), (63, BaudRate::Kbps250));
        let (c, _) = StoredState::default().apply(&base, MacId::new(12));
        assert_eq!(c.device.mac_id.as_raw(), 12, "--mac wins");
        let (c, _) = state.apply(&base, MacId::new(12));
        assert_eq!(c.device.mac_id.as_raw(), 12);
    }

    #[test]
    fn a_stored_image_runs_and_a_bad_one_is_a_fault_on_the_description() {
        let base = ConverterConfig::breaker_reference();
        let mut other = base.clone();
        other.device.identity.product_code = 42;
        let image = slave_fw::image::encode_to_vec(&other).unwrap();
        let mut state = StoredState::default();
        state.set_image(&image);
        let (c, origin) = state.apply(&base, None);
        assert_eq!((c.device.identity.product_code, origin), (42, ConfigOrigin::Stored));
        state.set_image(&image[..image.len() - 1]);
        let (c, origin) = state.apply(&base, None);
        assert_eq!(c.device.identity.product_code, 1);
        assert!(matches!(origin, ConfigOrigin::Fault(_)), "{origin:?}");
    }

    #[test]
    fn a_stored_image_in_force_is_the_bytes_downloaded_whatever_the_network_settings() {
        let base = ConverterConfig::breaker_reference();
        let mut other = base.clone();
        other.device.identity.product_code = 42;
        other.device.switches.programmable = true;
        let image = slave_fw::image::encode_to_vec(&other).unwrap();
        let mut state = StoredState::default();
        state.set_image(&image);
        state.mac_id = Some(9);
        for mac_override in [None, MacId::new(12)] {
            let converter = state.converter(&base, mac_override, Instant::ZERO).unwrap();
            assert_eq!(converter.image_in_force(), image.as_slice(), "--mac {mac_override:?}");
        }
        // Nothing stored: the description's own image.
        let converter = StoredState::default().converter(&base, None, Instant::ZERO).unwrap();
        assert_eq!(converter.image_in_force(), slave_fw::image::encode_to_vec(&base).unwrap());
    }

    #[test]
    fn the_configuration_consistency_value_follows_the_stored_image_not_the_network_settings() {
        // Identity attribute 9 (protocol §II.5.3): the MAC ID, rate and bus-off interrupt set
        // over the network and the device's serial number leave it alone; a stored image sets it.
        let mut base = ConverterConfig::breaker_reference();
        base.device.switches.programmable = true;
        let ccv = |state: &StoredState| {
            state.converter(&base, None, Instant::ZERO).unwrap().node().configuration_consistency()
        };
        let factory = ccv(&StoredState::default());
        assert!(factory.is_some());
        let mut state = StoredState { serial_number: Some(0x0BAD_F00D), ..StoredState::default() };
        for change in [
            SettingChanged::MacId(MacId::new(9).unwrap()),
            SettingChanged::BaudRate(BaudRate::Kbps500),
            SettingChanged::BusOffInterrupt(true),
        ] {
            state.note(&change);
            assert_eq!(ccv(&state), factory, "after {change:?}");
        }
        let mut other = base.clone();
        other.device.identity.product_code = 42;
        let image = slave_fw::image::encode_to_vec(&other).unwrap();
        state.set_image(&image);
        let stored = ccv(&state);
        assert_ne!(stored, factory);
        assert_eq!(stored, Some(slave_fw::converter::consistency::consistency_value(&image)));
    }

    #[test]
    fn the_serial_number_is_the_states_else_the_descriptions_never_the_images() {
        let base = ConverterConfig::breaker_reference();
        let mut downloaded = base.clone();
        downloaded.device.identity.serial_number = 0x00C0_FFEE;
        let mut state = StoredState::default();
        state.set_image(&slave_fw::image::encode_to_vec(&downloaded).unwrap());
        let (c, origin) = state.apply(&base, None);
        assert_eq!(origin, ConfigOrigin::Stored);
        assert_eq!(c.device.identity.serial_number, base.device.identity.serial_number);
        state.serial_number = Some(0x0BAD_CAFE);
        let (c, _) = state.apply(&base, None);
        assert_eq!(c.device.identity.serial_number, 0x0BAD_CAFE);
        // Kept in the file.
        let file = StateFile::new(temp("serial.json"));
        file.save(&state).unwrap();
        assert_eq!(file.load().unwrap().serial_number, Some(0x0BAD_CAFE));
    }

    #[test]
    fn an_unwritable_folder_is_named() {
        let file = StateFile::new("/nonexistent/dir/state.json");
        let e = file.save(&StoredState::default()).map_err(SoftSlaveError::from).unwrap_err().to_string();
        assert!(e.starts_with("state file /nonexistent/dir/state.json: cannot write"), "{e}");
        let e = file.check_writable().map_err(SoftSlaveError::from).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().starts_with("state file /nonexistent/dir/state.json: cannot write"), "{e}");
    }

    #[test]
    fn a_writable_folder_passes_the_check_and_nothing_is_left_behind() {
        let path = temp("checked.json");
        let _ = std::fs::remove_file(&path);
        let file = StateFile::new(&path);
        file.check_writable().unwrap();
        assert!(!path.exists(), "the check writes no state");
        let dir = path.parent().unwrap();
        let leftovers = std::fs::read_dir(dir)
            .unwrap()
            .filter_map(Result::ok)
            .filter(|e| e.file_name().to_string_lossy().starts_with(".checked.json."))
            .count();
        assert_eq!(leftovers, 0);
    }
}
