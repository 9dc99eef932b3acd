//! Every way the soft slave and the simulated breaker can fail, each naming what it was about.

use can_io::bus::BusError;
use slave_fw::converter::ConverterConfigError;
use slave_fw::description::DescriptionError;

/// A failure of `dnet-soft-slave` or `dnet-sim-breaker`.
#[derive(Debug, thiserror::Error)]
pub enum SoftSlaveError {
    /// The device description file is unreadable or invalid (names the file and the key).
    #[error("{0}")]
    Description(#[from] DescriptionError),
    /// The configuration, after command-line overrides, is refused by the converter.
    #[error("configuration: {0}")]
    Config(#[from] ConverterConfigError),
    /// A command-line value that clap could not check on its own.
    #[error("{0}")]
    Usage(String),
    /// The serial port could not be opened with the profile's settings.
    #[error("cannot open the serial port '{path}' ({settings}): {source}")]
    SerialOpen {
        /// The device path.
        path: String,
        /// The line settings that were asked for, e.g. `9600 8N1`.
        settings: String,
        /// Why.
        source: serialport::Error,
    },
    /// Reading or writing the serial port failed (e.g. the adapter was unplugged).
    #[error("serial port '{path}': {what}: {source}")]
    SerialIo {
        /// The device path.
        path: String,
        /// `reading` or `writing`.
        what: &'static str,
        /// The OS error.
        source: std::io::Error,
    },
    /// The CAN bus could not be opened, read or written.
    #[error("CAN bus: {0}")]
    Bus(#[from] BusError),
    /// A log file could not be created or written (an output file: exit 2, as in `dnet-master`).
    #[error("log file '{path}': {source}")]
    Log {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// `--log FILE` in a format that is not written (`--format`, or the file's extension).
    #[error(transparent)]
    LogFormat(#[from] can_io::trace::write::LogFormatError),
    /// The `--state` file is unreadable, malformed or cannot be written (names the file).
    #[error("state file {0}")]
    State(#[from] crate::state::StateError),
    /// The firmware directory or key (`--firmware-dir`, `--firmware-key`).
    #[error(transparent)]
    Firmware(#[from] crate::firmware::FirmwareDirError),
    /// The SIGINT/SIGTERM handler could not be installed.
    #[error("cannot install the SIGINT/SIGTERM handler: {0}")]
    Signal(String),
}

impl SoftSlaveError {
    /// The process exit status (guide: docs/src/reference/exit-status.md): 2 for a usage or
    /// configuration error
    /// (as clap uses), an output file (log, state) that cannot be written among them; 1 for the
    /// bus or the serial port failing.
    pub fn exit_code(&self) -> u8 {
        match self {
            SoftSlaveError::Description(_)
            | SoftSlaveError::Config(_)
            | SoftSlaveError::Usage(_)
            | SoftSlaveError::State(_)
            | SoftSlaveError::Firmware(_)
            | SoftSlaveError::Log { .. }
            | SoftSlaveError::LogFormat(_) => 2,
            _ => 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_and_messages() {
        let usage = SoftSlaveError::Usage("--mac 70 is outside 0..=63".into());
        assert_eq!(usage.exit_code(), 2);
        let io = SoftSlaveError::SerialIo {
            path: "/dev/ttyUSB0".into(),
            what: "reading",
            source: std::io::Error::from(std::io::ErrorKind::BrokenPipe),
        };
        assert_eq!(io.exit_code(), 1);
        assert!(io.to_string().starts_with("serial port '/dev/ttyUSB0': reading: "), "{io}");
        let log = SoftSlaveError::Log {
            path: "/nonexistent/bus.log".into(),
            source: std::io::Error::from(std::io::ErrorKind::NotFound),
        };
        assert_eq!(log.exit_code(), 2, "an output file that cannot be written");
    }
}
