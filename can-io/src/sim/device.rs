//! What the simulated bus drives: the [`SimDevice`] trait every simulated node implements, and
//! the [`PowerOn`] policy of each.

use devicenet::{CanFrame, Duration, Instant, MacId};

/// A simulated device on the bus: a sans-IO node, driven by the bus at the instants it asks for.
///
/// The converter as a simulated device (`converter_sim::SoftSlave`: the converter and a simulated
/// breaker) implements it; any other sans-IO device can be attached the same way.
pub trait SimDevice {
    /// The device's MAC ID (to find it for [`SimBus::force_bus_off`](super::SimBus::force_bus_off)).
    fn mac(&self) -> MacId;
    /// Power-on at `now`.
    fn power_on(&mut self, now: Instant);
    /// A frame another node put on the bus, received at `now`.
    fn handle_frame(&mut self, frame: &CanFrame, now: Instant);
    /// Runs the device's timers due at `now`.
    fn handle_timeout(&mut self, now: Instant);
    /// The next frame the device wants to transmit.
    fn poll_transmit(&mut self) -> Option<CanFrame>;
    /// When [`SimDevice::handle_timeout`] must be called next.
    fn poll_at(&self) -> Option<Instant>;
    /// The device's CAN controller went bus-off at `now` (fault injection, [`super::fault`]): the
    /// frames it had queued are lost. The default ignores it (a device that does not model
    /// bus-off); a DeviceNet device applies its bus-off interrupt setting (protocol §7.2).
    fn handle_bus_off(&mut self, _now: Instant) {}
}

/// When a simulated device is powered on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PowerOn {
    /// When the master is on-line, as in the source capture: 1 s after the master queued its second
    /// duplicate MAC ID check request (protocol §7.1), the instant a master that heard no answer
    /// goes on-line. The bus sees this on the wire; the master tells it nothing.
    #[default]
    WhenMasterOnline,
    /// This long after the master is on-line: a second device at a MAC ID already in use, which
    /// must find the first one on-line and end Communication Faulted (protocol §7.1).
    AfterMasterOnline(Duration),
    /// At the start of the simulation.
    AtStart,
    /// At a fixed instant (a replayed transcript: the recorded time of the device's first
    /// duplicate MAC ID check).
    At(Instant),
}
