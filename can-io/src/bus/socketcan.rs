//! Linux SocketCAN (`socketcan:IFACE`), through the `socketcan` crate.
//!
//! The bus clock is the time since the interface was opened. Frames this program sends are
//! reported back as [`Origin::Local`] at the moment they were written to the socket; remote frames
//! on the interface are skipped (not DeviceNet traffic). The socket asks for every error frame
//! (`CAN_ERR_MASK`): they are not DeviceNet traffic either, and go to the error state
//! ([`Bus::error_state`], [`SocketCanErrors`]). A driver reports bus errors only with bus-error
//! reporting on: `ip link set IFACE type can berr-reporting on`.

use super::health::{ErrorReport, SocketCanErrors};
use super::{Bus, BusError, BusEvent, Origin};
use devicenet::{CanFrame, Instant};
use socketcan::{CanSocket, Socket, SocketOptions};
use std::collections::VecDeque;

/// A SocketCAN interface.
pub struct SocketCanBus {
    socket: CanSocket,
    iface: String,
    opened: std::time::Instant,
    echo: VecDeque<BusEvent>,
    errors: SocketCanErrors,
}

impl SocketCanBus {
    /// Opens `iface` (e.g. `can0`, `vcan0`).
    pub fn open(iface: &str) -> Result<SocketCanBus, BusError> {
        let socket = CanSocket::open(iface)
            .map_err(|source| BusError::Open { what: format!("SocketCAN interface '{iface}'"), source })?;
        socket.set_error_filter_accept_all().map_err(|source| BusError::Open {
            what: format!("SocketCAN interface '{iface}' (asking for its error frames)"),
            source,
        })?;
        Ok(SocketCanBus {
            socket,
            iface: iface.to_string(),
            opened: std::time::Instant::now(),
            echo: VecDeque::new(),
            errors: SocketCanErrors::default(),
        })
    }

    fn clock(&self) -> Instant {
        Instant::from_micros(u64::try_from(self.opened.elapsed().as_micros()).unwrap_or(u64::MAX))
    }
}

impl Bus for SocketCanBus {
    fn name(&self) -> &str {
        &self.iface
    }

    fn now(&mut self) -> Instant {
        self.clock()
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        let out: socketcan::CanFrame = frame
            .to_embedded()
            .ok_or_else(|| BusError::Adapter(format!("cannot convert {frame} to a SocketCAN frame")))?;
        self.socket
            .write_frame(&out)
            .map_err(|source| BusError::Io { what: format!("writing {frame} to {}", self.iface), source })?;
        let at = self.clock();
        self.echo.push_back(BusEvent { at, frame: *frame, origin: Origin::Local });
        Ok(())
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError> {
        if let Some(ev) = self.echo.pop_front() {
            return Ok(Some(ev));
        }
        loop {
            let now = self.clock();
            if now >= deadline {
                return Ok(None);
            }
            let wait = std::time::Duration::from_micros((deadline - now).total_micros());
            match self.socket.read_frame_timeout(wait) {
                Ok(socketcan::CanFrame::Data(data)) => {
                    if let Ok(frame) = CanFrame::from_embedded(&data) {
                        return Ok(Some(BusEvent { at: self.clock(), frame, origin: Origin::Remote }));
                    }
                }
                Ok(socketcan::CanFrame::Error(error)) => {
                    use socketcan::EmbeddedFrame;
                    self.errors.error_frame(error.error_bits(), error.data());
                }
                Ok(_) => {}
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(source) => {
                    return Err(BusError::Io { what: format!("reading from {}", self.iface), source })
                }
            }
        }
    }

    fn error_state(&mut self) -> Option<ErrorReport> {
        Some(self.errors.report())
    }
}
