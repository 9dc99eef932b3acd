//! The one bus trait every host program runs on, and its implementations: Linux SocketCAN
//! ([`socketcan`](mod@self::socketcan)), SLCAN over a serial line ([`slcan`]) and, with the
//! feature `sim`, the simulated bus ([`crate::sim`]).
//!
//! A bus has its own clock ([`Bus::now`]): virtual time on the simulated bus, time since the bus
//! was opened on a real one. Every frame that completes on the bus comes back from [`Bus::recv`],
//! this program's own frames included (with [`Origin::Local`]), so a transcript holds the bus in
//! the order the wire saw it. The protocol logic never asks which bus it runs on, and nothing
//! simulation-specific passes through the trait. [`BusSpec`] is what `--bus` names;
//! [`BusSpec::open`] opens the real ones.

pub mod health;
pub mod slcan;
#[cfg(target_os = "linux")]
pub mod socketcan;

use devicenet::{CanFrame, Instant};
use std::fmt;
use std::str::FromStr;

/// Who put a frame on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    /// This program (the master, or the replayed stimulus).
    Local,
    /// Any other node.
    Remote,
}

/// A frame that completed on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusEvent {
    /// When it completed, on the bus's clock.
    pub at: Instant,
    /// The frame.
    pub frame: CanFrame,
    /// Who sent it.
    pub origin: Origin,
}

/// Why a bus operation failed.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// The interface or serial port could not be opened.
    #[error("cannot open {what}: {source}")]
    Open {
        /// The interface or port.
        what: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// Reading or writing failed.
    #[error("{what}: {source}")]
    Io {
        /// What was being done.
        what: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The adapter answered with an error or something unintelligible.
    #[error("{0}")]
    Adapter(String),
    /// The serial port does not answer the set-up commands as an SLCAN adapter does.
    #[error("{port} does not answer as an SLCAN adapter: {reason}")]
    NotAnAdapter {
        /// The serial port.
        port: String,
        /// Silent, or what came back.
        reason: slcan::NotAnAdapter,
    },
    /// The SLCAN adapter refused a set-up command (BEL).
    #[error("the SLCAN adapter on {port} refused `{command}` (BEL)")]
    Refused {
        /// The serial port.
        port: String,
        /// The command (`S5`, `O`).
        command: &'static str,
    },
    /// The bus cannot be opened here: `sim` outside a program that simulates devices, or
    /// SocketCAN off Linux.
    #[error("{0}")]
    Unavailable(String),
}

/// A CAN bus the master can send on and listen to.
pub trait Bus {
    /// The interface name written in `candump -L` logs (`sim`, `can0`, `slcan0`).
    fn name(&self) -> &str;

    /// The current time on this bus's clock.
    fn now(&mut self) -> Instant;

    /// Queues `frame` for transmission. It comes back from [`Bus::recv`] as
    /// [`Origin::Local`] once it is on the bus.
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError>;

    /// The next frame that completes on the bus, waiting at most until `deadline`; `None` when the
    /// deadline passed first (the bus clock then reads at least `deadline`).
    fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError>;

    /// The controller's error state and counters, where the backend can tell them
    /// ([`health`]); `None` (the default) when it cannot. An SLCAN adapter is asked (`F`) at most
    /// once a second by this call, and its answer comes with a later [`Bus::recv`].
    fn error_state(&mut self) -> Option<health::ErrorReport> {
        None
    }
}

/// A CAN bit rate of DeviceNet: 125, 250 or 500 kbit/s.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bitrate(u32);

impl Bitrate {
    /// 125 kbit/s.
    pub const K125: Bitrate = Bitrate(125_000);
    /// 250 kbit/s, the rate of the source capture.
    pub const K250: Bitrate = Bitrate(250_000);
    /// 500 kbit/s.
    pub const K500: Bitrate = Bitrate(500_000);

    /// Bits per second.
    pub const fn bits_per_second(self) -> u32 {
        self.0
    }
}

impl From<devicenet::slave::BaudRate> for Bitrate {
    /// The CAN bit rate of a DeviceNet data rate (DeviceNet object attribute 2).
    fn from(rate: devicenet::slave::BaudRate) -> Bitrate {
        Bitrate(rate.bits_per_second())
    }
}

impl Default for Bitrate {
    fn default() -> Self {
        Bitrate::K250
    }
}

impl fmt::Display for Bitrate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}k", self.0 / 1000)
    }
}

impl FromStr for Bitrate {
    type Err = String;

    /// `125k`, `250k`, `500k`, or the same in bit/s (`250000`).
    fn from_str(s: &str) -> Result<Bitrate, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "125k" | "125000" => Ok(Bitrate::K125),
            "250k" | "250000" => Ok(Bitrate::K250),
            "500k" | "500000" => Ok(Bitrate::K500),
            other => Err(format!("unsupported bit rate '{other}': DeviceNet runs at 125k, 250k or 500k")),
        }
    }
}

/// Which bus to open, as given to `--bus`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BusSpec {
    /// The in-process simulated bus.
    Sim,
    /// A SocketCAN interface (Linux).
    SocketCan {
        /// Interface name, e.g. `can0`.
        iface: String,
    },
    /// An SLCAN (Lawicel) adapter on a serial line.
    Slcan {
        /// Serial device path.
        path: String,
        /// Serial baud rate (default 115200).
        baud: u32,
    },
}

/// The serial baud rate used for SLCAN when `@SERIALBAUD` is not given.
pub const DEFAULT_SLCAN_BAUD: u32 = 115_200;

impl FromStr for BusSpec {
    type Err = String;

    /// `sim`, `socketcan:IFACE` or `slcan:PATH[@SERIALBAUD]`.
    fn from_str(s: &str) -> Result<BusSpec, String> {
        const EXPECTED: &str = "expected sim, socketcan:IFACE or slcan:PATH[@SERIALBAUD]";
        if s == "sim" {
            return Ok(BusSpec::Sim);
        }
        if let Some(iface) = s.strip_prefix("socketcan:") {
            if iface.is_empty() {
                return Err(format!("socketcan needs an interface name ({EXPECTED})"));
            }
            return Ok(BusSpec::SocketCan { iface: iface.to_string() });
        }
        if let Some(rest) = s.strip_prefix("slcan:") {
            let (path, baud) = match rest.rsplit_once('@') {
                Some((path, baud)) => {
                    let baud = baud
                        .parse::<u32>()
                        .ok()
                        .filter(|&b| b > 0)
                        .ok_or_else(|| format!("invalid serial baud rate '{baud}' in '{s}'"))?;
                    (path, baud)
                }
                None => (rest, DEFAULT_SLCAN_BAUD),
            };
            if path.is_empty() {
                return Err(format!("slcan needs a serial device path ({EXPECTED})"));
            }
            return Ok(BusSpec::Slcan { path: path.to_string(), baud });
        }
        Err(format!("unknown bus '{s}': {EXPECTED}"))
    }
}

impl fmt::Display for BusSpec {
    /// The `--bus` form: `sim`, `socketcan:IFACE`, `slcan:PATH@SERIALBAUD`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusSpec::Sim => write!(f, "sim"),
            BusSpec::SocketCan { iface } => write!(f, "socketcan:{iface}"),
            BusSpec::Slcan { path, baud } => write!(f, "slcan:{path}@{baud}"),
        }
    }
}

impl BusSpec {
    /// Opens a real bus: the SocketCAN interface, or the SLCAN adapter set up for `bitrate` (on
    /// SocketCAN the bit rate belongs to the interface: `ip link set can0 type can bitrate ...`);
    /// the SLCAN adapter must answer its set-up commands ([`slcan::SetUp::Adapter`]).
    ///
    /// The simulated bus has devices only a program that simulates them can attach; `sim` gives
    /// [`BusError::Unavailable`] here (the master harness and the EDS tool open it through
    /// `converter_sim::open_bus`, which attaches the simulated converters and calls this for the
    /// real buses).
    pub fn open(&self, bitrate: Bitrate) -> Result<Box<dyn Bus>, BusError> {
        self.open_as(bitrate, slcan::SetUp::Adapter)
    }

    /// [`BusSpec::open`], with what an SLCAN port's far end must answer to the set-up commands:
    /// [`slcan::SetUp::Adapter`] (what `open` asks: a port that stays silent or answers garbage is
    /// [`BusError::NotAnAdapter`]) or [`slcan::SetUp::Peer`] (a device program whose far end may be
    /// a host that starts later). Other buses ignore `setup`.
    pub fn open_as(&self, bitrate: Bitrate, setup: slcan::SetUp) -> Result<Box<dyn Bus>, BusError> {
        match self {
            BusSpec::Sim => Err(BusError::Unavailable(
                "the simulated bus runs inside dnet-master and dnet-eds (--bus sim); this program needs a real bus (socketcan:IFACE or slcan:PATH[@SERIALBAUD])".into(),
            )),
            #[cfg(target_os = "linux")]
            BusSpec::SocketCan { iface } => Ok(Box::new(socketcan::SocketCanBus::open(iface)?)),
            #[cfg(not(target_os = "linux"))]
            BusSpec::SocketCan { .. } => {
                Err(BusError::Unavailable("SocketCAN is only available on Linux".into()))
            }
            BusSpec::Slcan { path, baud } => Ok(Box::new(slcan::open_as(path, *baud, bitrate, setup)?)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::sim("sim", BusSpec::Sim)]
    #[case::socketcan("socketcan:can0", BusSpec::SocketCan { iface: "can0".into() })]
    #[case::slcan_default_baud("slcan:/dev/ttyACM0", BusSpec::Slcan { path: "/dev/ttyACM0".into(), baud: 115_200 })]
    #[case::slcan_baud("slcan:/dev/ttyUSB0@921600", BusSpec::Slcan { path: "/dev/ttyUSB0".into(), baud: 921_600 })]
    fn bus_specs(#[case] text: &str, #[case] spec: BusSpec) {
        assert_eq!(text.parse::<BusSpec>(), Ok(spec));
    }

    #[rstest]
    #[case::unknown("vcan0", "unknown bus 'vcan0'")]
    #[case::empty_iface("socketcan:", "needs an interface name")]
    #[case::empty_path("slcan:@115200", "needs a serial device path")]
    #[case::bad_baud("slcan:/dev/ttyACM0@fast", "invalid serial baud rate 'fast'")]
    fn bad_bus_specs(#[case] text: &str, #[case] msg: &str) {
        let err = text.parse::<BusSpec>().unwrap_err();
        assert!(err.contains(msg), "{err}");
    }

    #[rstest]
    #[case::k125("125k", Bitrate::K125)]
    #[case::k250("250K", Bitrate::K250)]
    #[case::k500("500000", Bitrate::K500)]
    fn bitrates(#[case] text: &str, #[case] rate: Bitrate) {
        assert_eq!(text.parse::<Bitrate>(), Ok(rate));
    }

    #[test]
    fn unsupported_bitrate() {
        assert!("1M".parse::<Bitrate>().unwrap_err().contains("125k, 250k or 500k"));
    }
}
