//! The CAN controller's error state, as far as a bus can report it ([`Bus::error_state`]): the
//! ISO 11898-1 fault confinement counters ([`ErrorCounters`]), what SocketCAN's error frames say
//! ([`SocketCanErrors`]) and what an SLCAN adapter's status flags say ([`SlcanStatus`]).
//!
//! ## Fault confinement (ISO 11898-1 §12, in short)
//!
//! | event | counter |
//! |---|---|
//! | a transmitter detects an error | TEC + 8 |
//! | a receiver detects an error | REC + 1 |
//! | a frame transmitted without error | TEC − 1 (not below 0) |
//! | a frame received without error | REC − 1; above 127 it is set back to 127 (the standard allows 119..=127) |
//!
//! A node is *error active* while both counters are at most 127, *error passive* when either
//! is 128 or more, and *bus-off* when TEC reaches 256; it comes back error active with both
//! counters zero after 128 × 11 recessive bits. *Error warning* (either counter at 96 or more) is
//! not in ISO 11898-1: it is the controllers' early warning (SJA1000's EI, bxCAN's EWGF, Linux's
//! `CAN_STATE_ERROR_WARNING`), kept because every backend reports it.
//!
//! [`Bus::error_state`]: super::Bus::error_state

use serde::Serialize;

/// A CAN controller's fault confinement state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorState {
    /// Error active: both counters at most 127 (and below the warning level).
    #[default]
    Active,
    /// Error warning: a counter at [`WARNING_LEVEL`] or more (still error active).
    Warning,
    /// Error passive: a counter at 128 or more.
    Passive,
    /// Bus-off: TEC reached 256; the controller takes no part in bus traffic.
    BusOff,
}

impl ErrorState {
    /// The state's name as `scanner --json` writes it (`active`, `warning`, `passive`, `bus_off`).
    pub fn name(self) -> &'static str {
        match self {
            ErrorState::Active => "active",
            ErrorState::Warning => "warning",
            ErrorState::Passive => "passive",
            ErrorState::BusOff => "bus_off",
        }
    }
}

/// The error warning level of the controllers (not ISO 11898-1, see the [module docs](self)).
pub const WARNING_LEVEL: u16 = 96;
/// A counter at this value or more makes the node error passive.
pub const PASSIVE_LEVEL: u16 = 128;
/// TEC at this value makes the node bus-off.
pub const BUS_OFF_LEVEL: u16 = 256;

/// What a bus reports of its controller's error state ([`Bus::error_state`](super::Bus::error_state)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ErrorReport {
    /// The fault confinement state.
    pub state: ErrorState,
    /// The transmit error counter, when the backend reports it.
    pub tec: Option<u16>,
    /// The receive error counter, when the backend reports it.
    pub rec: Option<u16>,
    /// Error frames seen since the bus was opened (each error the controller reported, or, on the
    /// simulated bus, each error frame on the wire).
    pub error_frames: u64,
    /// Times the controller went bus-off since the bus was opened.
    pub bus_offs: u64,
}

/// The two fault confinement counters of one node, kept by the ISO 11898-1 rules (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ErrorCounters {
    /// Transmit error counter (0..=256; 256 is bus-off).
    pub tec: u16,
    /// Receive error counter (0..=255).
    pub rec: u16,
}

impl ErrorCounters {
    /// The transmitter detected an error: TEC + 8. Returns `true` when this made the node bus-off.
    pub fn transmit_error(&mut self) -> bool {
        let before = self.tec;
        self.tec = (self.tec + 8).min(BUS_OFF_LEVEL);
        before < BUS_OFF_LEVEL && self.tec >= BUS_OFF_LEVEL
    }

    /// A receiver detected an error: REC + 1 (held at 255).
    pub fn receive_error(&mut self) {
        self.rec = (self.rec + 1).min(255);
    }

    /// A frame was transmitted without error: TEC − 1.
    pub fn transmitted(&mut self) {
        if self.tec < BUS_OFF_LEVEL {
            self.tec = self.tec.saturating_sub(1);
        }
    }

    /// A frame was received without error: REC − 1, or back to 127 from above it.
    pub fn received(&mut self) {
        self.rec = if self.rec >= PASSIVE_LEVEL { PASSIVE_LEVEL - 1 } else { self.rec.saturating_sub(1) };
    }

    /// Bus-off recovery done (128 × 11 recessive bits): both counters zero.
    pub fn recover(&mut self) {
        *self = ErrorCounters::default();
    }

    /// Driven bus-off by an outside cause (fault injection): TEC at 256.
    pub fn force_bus_off(&mut self) {
        self.tec = BUS_OFF_LEVEL;
    }

    /// The state the counters give.
    pub fn state(&self) -> ErrorState {
        if self.tec >= BUS_OFF_LEVEL {
            ErrorState::BusOff
        } else if self.tec >= PASSIVE_LEVEL || self.rec >= PASSIVE_LEVEL {
            ErrorState::Passive
        } else if self.tec >= WARNING_LEVEL || self.rec >= WARNING_LEVEL {
            ErrorState::Warning
        } else {
            ErrorState::Active
        }
    }
}

/// Linux `can/error.h`: the error class bits of an error frame's identifier.
mod can_err {
    pub const CRTL: u32 = 0x0000_0004;
    pub const BUSOFF: u32 = 0x0000_0040;
    pub const RESTARTED: u32 = 0x0000_0100;
    pub const CNT: u32 = 0x0000_0200;
    /// `data[1]` of a controller problem.
    pub const CRTL_RX_WARNING: u8 = 0x04;
    pub const CRTL_TX_WARNING: u8 = 0x08;
    pub const CRTL_RX_PASSIVE: u8 = 0x10;
    pub const CRTL_TX_PASSIVE: u8 = 0x20;
    pub const CRTL_ACTIVE: u8 = 0x40;
}

/// The error state a SocketCAN interface reports through its error frames (with the error mask
/// `CAN_ERR_MASK` set on the socket; Linux `include/uapi/linux/can/error.h`).
///
/// Every error frame counts in [`ErrorReport::error_frames`]. `CAN_ERR_BUSOFF` is bus-off,
/// `CAN_ERR_RESTARTED` back to error active; a controller problem (`CAN_ERR_CRTL`) gives warning,
/// passive or active from `data[1]`; `data[6]` and `data[7]` are TEC and REC when the kernel sets
/// `CAN_ERR_CNT` (Linux 6.2 and later; older kernels fill them for some drivers only, so they are
/// taken only with the flag).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SocketCanErrors {
    report: ErrorReport,
}

impl SocketCanErrors {
    /// Takes one error frame: its identifier's error class bits (`can_id & CAN_ERR_MASK`) and its
    /// eight data bytes (missing bytes read as zero).
    pub fn error_frame(&mut self, class: u32, data: &[u8]) {
        let byte = |i: usize| data.get(i).copied().unwrap_or(0);
        let r = &mut self.report;
        r.error_frames += 1;
        if class & can_err::CNT != 0 {
            r.tec = Some(u16::from(byte(6)));
            r.rec = Some(u16::from(byte(7)));
        }
        if class & can_err::BUSOFF != 0 {
            if r.state != ErrorState::BusOff {
                r.bus_offs += 1;
            }
            r.state = ErrorState::BusOff;
        } else if class & can_err::RESTARTED != 0 {
            r.state = ErrorState::Active;
        } else if class & can_err::CRTL != 0 {
            let status = byte(1);
            if status & (can_err::CRTL_RX_PASSIVE | can_err::CRTL_TX_PASSIVE) != 0 {
                r.state = ErrorState::Passive;
            } else if status & (can_err::CRTL_RX_WARNING | can_err::CRTL_TX_WARNING) != 0 {
                r.state = ErrorState::Warning;
            } else if status & can_err::CRTL_ACTIVE != 0 {
                r.state = ErrorState::Active;
            }
        }
    }

    /// What the error frames so far say.
    pub fn report(&self) -> ErrorReport {
        self.report
    }
}

/// The status flags an SLCAN adapter answers to `F` (`Fxx\r`, two hex digits), as Lawicel's
/// CANUSB manual defines them (the bits mirror the SJA1000's interrupt flags):
///
/// | bit | meaning |
/// |---|---|
/// | 0 | CAN receive FIFO full |
/// | 1 | CAN transmit FIFO full |
/// | 2 | error warning (EI) |
/// | 3 | data overrun (DOI) |
/// | 4 | not used |
/// | 5 | error passive (EPI) |
/// | 6 | arbitration lost (ALI) |
/// | 7 | bus error (BEI) |
///
/// The flags carry no counters and no bus-off bit: an adapter's report has `tec` and `rec`
/// `None`, and a bus error flag counts as one error frame per answer that has it (the flags are
/// cleared when read).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SlcanStatus(pub u8);

impl SlcanStatus {
    /// Receive FIFO full.
    pub const RX_FULL: u8 = 1 << 0;
    /// Transmit FIFO full.
    pub const TX_FULL: u8 = 1 << 1;
    /// Error warning.
    pub const ERROR_WARNING: u8 = 1 << 2;
    /// Data overrun.
    pub const OVERRUN: u8 = 1 << 3;
    /// Error passive.
    pub const ERROR_PASSIVE: u8 = 1 << 5;
    /// Arbitration lost.
    pub const ARBITRATION_LOST: u8 = 1 << 6;
    /// Bus error.
    pub const BUS_ERROR: u8 = 1 << 7;

    /// Parses an adapter's answer line without its `\r` (`F24`); `None` when it is not one.
    pub fn parse(line: &[u8]) -> Option<SlcanStatus> {
        let [b'F', hi, lo] = line else { return None };
        let hex = |c: u8| char::from(c).to_digit(16);
        Some(SlcanStatus((hex(*hi)? * 16 + hex(*lo)?) as u8))
    }

    /// The state the flags give (error passive before warning; never bus-off, see the type docs).
    pub fn state(self) -> ErrorState {
        if self.0 & Self::ERROR_PASSIVE != 0 {
            ErrorState::Passive
        } else if self.0 & Self::ERROR_WARNING != 0 {
            ErrorState::Warning
        } else {
            ErrorState::Active
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[test]
    fn counters_follow_the_iso_rules() {
        let mut c = ErrorCounters::default();
        for _ in 0..15 {
            assert!(!c.transmit_error());
        }
        assert_eq!((c.tec, c.state()), (120, ErrorState::Warning));
        assert!(!c.transmit_error());
        assert_eq!((c.tec, c.state()), (128, ErrorState::Passive));
        c.transmitted();
        assert_eq!((c.tec, c.state()), (127, ErrorState::Warning));
        for _ in 0..16 {
            c.transmit_error();
        }
        assert_eq!((c.tec, c.state()), (255, ErrorState::Passive));
        assert!(c.transmit_error(), "255 + 8 reaches 256: bus-off");
        assert_eq!((c.tec, c.state()), (256, ErrorState::BusOff));
        c.transmitted();
        assert_eq!(c.tec, 256, "a bus-off node transmits nothing; only recovery clears it");
        c.recover();
        assert_eq!((c.tec, c.rec, c.state()), (0, 0, ErrorState::Active));
    }

    #[test]
    fn receive_counter_passive_at_128_and_back_to_127() {
        let mut c = ErrorCounters::default();
        for _ in 0..128 {
            c.receive_error();
        }
        assert_eq!((c.rec, c.state()), (128, ErrorState::Passive));
        c.received();
        assert_eq!((c.rec, c.state()), (127, ErrorState::Warning));
        c.received();
        assert_eq!(c.rec, 126);
    }

    #[rstest]
    #[case::busoff(0x40, [0; 8], ErrorState::BusOff, None)]
    #[case::passive_with_counts(0x204, [0, 0x20, 0, 0, 0, 0, 130, 5], ErrorState::Passive, Some((130, 5)))]
    #[case::warning(0x04, [0, 0x08, 0, 0, 0, 0, 100, 0], ErrorState::Warning, None)]
    #[case::restarted(0x100, [0; 8], ErrorState::Active, None)]
    fn socketcan_error_frames(
        #[case] class: u32,
        #[case] data: [u8; 8],
        #[case] state: ErrorState,
        #[case] counts: Option<(u16, u16)>,
    ) {
        let mut e = SocketCanErrors::default();
        e.error_frame(class, &data);
        let r = e.report();
        assert_eq!(r.state, state);
        assert_eq!(r.error_frames, 1);
        assert_eq!(r.tec.zip(r.rec), counts);
    }

    #[test]
    fn socketcan_bus_off_counted_once_until_restarted() {
        let mut e = SocketCanErrors::default();
        e.error_frame(0x40, &[0; 8]);
        e.error_frame(0x40, &[0; 8]);
        e.error_frame(0x100, &[0; 8]);
        e.error_frame(0x40, &[]);
        let r = e.report();
        assert_eq!((r.bus_offs, r.error_frames, r.state), (2, 4, ErrorState::BusOff));
    }

    #[rstest]
    #[case::clear("F00", Some(0x00), ErrorState::Active)]
    #[case::warning("F04", Some(0x04), ErrorState::Warning)]
    #[case::passive_and_bus_error("FA0", Some(0xA0), ErrorState::Passive)]
    #[case::lower_case("Fa4", Some(0xA4), ErrorState::Passive)]
    #[case::short("F0", None, ErrorState::Active)]
    #[case::not_hex("FZZ", None, ErrorState::Active)]
    #[case::frame("t1230", None, ErrorState::Active)]
    fn slcan_status_flags(#[case] line: &str, #[case] flags: Option<u8>, #[case] state: ErrorState) {
        let parsed = SlcanStatus::parse(line.as_bytes());
        assert_eq!(parsed.map(|s| s.0), flags);
        assert_eq!(parsed.unwrap_or_default().state(), state);
    }
}
