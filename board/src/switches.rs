//! The eight DIP switches on PB0–PB7 (the reference board only, [`BANK`]), and what the node
//! makes of them at reset. A board without switches runs with the stored MAC ID and data rate
//! ([`resolve_stored`]), as in the program position; out of the box (nothing stored) that is
//! MAC ID 63 and the data rate found by [`crate::autobaud`].
//!
//! ## MAC ID 63 out of the box
//!
//! 63 is the address DeviceNet devices are shipped with when their address is software-set, so
//! that new nodes can be commissioned one at a time from it (Offline Connection Set, ADR):
//! Rockwell Automation XM-440 user manual (GMSI10-UM009D-EN-P, DeviceNet object attribute 1,
//! default 63) and 193-EDN (193-UM006A-EN-P, "Nonvolatile MAC ID", default 63); RA 855T, as
//! summarised in protocol §II.6 ("several new nodes powered at default MAC 63"); the scanners'
//! address recovery looks for replacements there (protocol §II.9.2). Not confirmed: that the
//! DeviceNet specification itself requires 63 (its text was not retrieved).
//!
//! Each switch connects its pin to ground against the internal pull-up, so a switch that is **on**
//! reads 0; [`SwitchReading::from_port`] inverts the port so that "on" counts as 1.
//!
//! | switches | meaning |
//! |---|---|
//! | 1–6 (PB0–PB5) | MAC ID, switch 1 is bit 0 |
//! | 7–8 (PB6–PB7) | data rate: 0 = 125k, 1 = 250k, 2 = 500k, 3 = **program** |
//!
//! In the program position both the MAC ID and the data rate come from the non-volatile
//! [`Settings`] and the master may change them over the network (DeviceNet attributes 1 and 2);
//! otherwise the switches rule and those attributes are read-only.
//!
//! The switches are read once, at reset. The "switch changed" attributes (DeviceNet attributes 6
//! and 7) compare that reading with the one stored at the previous reset
//! ([`Settings::last_switches`]): they report that someone moved the switches since the last
//! power-up. [`resolve`] tells the firmware when to store the new reading.

use crate::boards::{SwitchBank, SELECTED};
use crate::settings::Settings;
use devicenet::slave::{BaudRate, Switches};
use devicenet::MacId;

/// The data rate switches (7–8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BaudSwitch {
    /// A fixed DeviceNet rate.
    Rate(BaudRate),
    /// The fourth position: use the MAC ID and rate stored in flash.
    Program,
}

/// The eight switches as read at reset, "on" = 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SwitchReading(u8);

impl SwitchReading {
    /// From the low byte of GPIOB's input data register (pulled up: "on" reads 0).
    pub const fn from_port(port: u8) -> SwitchReading {
        SwitchReading(!port)
    }

    /// From switch bits where "on" is already 1 (as stored in the settings).
    pub const fn from_bits(bits: u8) -> SwitchReading {
        SwitchReading(bits)
    }

    /// The switch bits, "on" = 1.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// The MAC ID switches (1–6).
    pub const fn mac_id(self) -> MacId {
        MacId::from_low_bits(self.0)
    }

    /// The raw value of the data rate switches (7–8), `0..=3`.
    pub const fn baud_code(self) -> u8 {
        self.0 >> 6
    }

    /// The data rate switches.
    pub const fn baud(self) -> BaudSwitch {
        match BaudRate::from_attribute_value(self.baud_code()) {
            Some(rate) => BaudSwitch::Rate(rate),
            None => BaudSwitch::Program,
        }
    }
}

/// What the node runs with, decided at reset from the switches and the stored settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resolved {
    /// The MAC ID in use.
    pub mac_id: MacId,
    /// The data rate in use.
    pub baud_rate: BaudRate,
    /// DeviceNet attributes 6–9 and whether MAC ID and rate are settable over the network.
    pub switches: Switches,
    /// The reading differs from the stored one: store it ([`Settings::last_switches`]) so that
    /// the "changed" attributes clear at the next reset.
    pub store_reading: bool,
    /// No data rate is known: find it by listening ([`crate::autobaud`]) before joining;
    /// [`Resolved::baud_rate`] is only the first rate tried.
    pub autobaud: bool,
}

/// The selected board's switches; `None` on a board without them.
pub const BANK: Option<SwitchBank> = SELECTED.switches;

/// What a board without switches runs with: the stored MAC ID and data rate, which the master may
/// change over the network (as in the program position); attributes 6–9 report no switches.
///
/// `stored` is the newest record of the settings journal, `None` when it holds none (a new board,
/// erased settings): then the node starts at MAC ID 63 (module docs) and finds the data rate by
/// autobaud. Autobaud stores nothing; the journal has no "rate not set" mark (its format is
/// unchanged), so the first record written for any reason (the master setting the MAC ID, the
/// rate, the bus-off interrupt, or downloading a configuration) carries the rate in use, and from
/// then on the rate counts as stored.
pub fn resolve_stored(stored: Option<&Settings>) -> Resolved {
    let defaults = Settings::default();
    let autobaud = stored.is_none();
    let stored = stored.unwrap_or(&defaults);
    Resolved {
        mac_id: stored.mac_id,
        baud_rate: stored.baud_rate,
        switches: Switches {
            mac_id: None,
            baud_rate: None,
            mac_id_changed: false,
            baud_rate_changed: false,
            programmable: true,
        },
        store_reading: false,
        autobaud,
    }
}

/// Decides MAC ID, data rate and the switch attributes from a reading and the stored settings.
pub fn resolve(reading: SwitchReading, stored: &Settings) -> Resolved {
    let previous = stored.last_switches.map(SwitchReading::from_bits);
    let mac_id_changed = previous.is_some_and(|p| p.mac_id() != reading.mac_id());
    let baud_rate_changed = previous.is_some_and(|p| p.baud_code() != reading.baud_code());
    let (mac_id, baud_rate, programmable) = match reading.baud() {
        BaudSwitch::Rate(rate) => (reading.mac_id(), rate, false),
        BaudSwitch::Program => (stored.mac_id, stored.baud_rate, true),
    };
    Resolved {
        mac_id,
        baud_rate,
        switches: Switches {
            mac_id: Some(reading.mac_id().as_raw()),
            baud_rate: Some(reading.baud_code()),
            mac_id_changed,
            baud_rate_changed,
            programmable,
        },
        store_reading: previous != Some(reading),
        autobaud: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn mac(raw: u8) -> MacId {
        MacId::new(raw).unwrap()
    }

    #[rstest]
    // Pulled-up port: every switch off reads 0xFF.
    #[case::all_off(0xFF, 0, BaudSwitch::Rate(BaudRate::Kbps125))]
    #[case::mac5_250k(!(0b01_000101u8), 5, BaudSwitch::Rate(BaudRate::Kbps250))]
    #[case::mac63_500k(!(0b10_111111u8), 63, BaudSwitch::Rate(BaudRate::Kbps500))]
    // Every pin low (QEMU's unimplemented GPIO reads 0): every switch on.
    #[case::all_on(0x00, 63, BaudSwitch::Program)]
    fn decode(#[case] port: u8, #[case] mac_id: u8, #[case] baud: BaudSwitch) {
        let r = SwitchReading::from_port(port);
        assert_eq!(r.mac_id(), mac(mac_id));
        assert_eq!(r.baud(), baud);
    }

    #[test]
    fn switches_never_autobaud() {
        for bits in [0u8, 0b01_000101, 0b11_000101] {
            assert!(!resolve(SwitchReading::from_bits(bits), &Settings::default()).autobaud);
        }
    }

    #[test]
    fn switches_rule_unless_program() {
        let stored = Settings { mac_id: mac(20), baud_rate: BaudRate::Kbps500, ..Settings::default() };
        let r = resolve(SwitchReading::from_bits(0b01_000101), &stored);
        assert_eq!((r.mac_id, r.baud_rate), (mac(5), BaudRate::Kbps250));
        assert!(!r.switches.programmable);
        assert_eq!(r.switches.mac_id, Some(5));
        assert_eq!(r.switches.baud_rate, Some(1));
    }

    #[test]
    fn no_switches_use_stored_values() {
        let stored = Settings { mac_id: mac(20), baud_rate: BaudRate::Kbps500, ..Settings::default() };
        let r = resolve_stored(Some(&stored));
        assert_eq!((r.mac_id, r.baud_rate), (mac(20), BaudRate::Kbps500));
        assert!(r.switches.programmable && !r.store_reading && !r.autobaud);
        assert_eq!((r.switches.mac_id, r.switches.baud_rate), (None, None));
    }

    #[test]
    fn no_switches_nothing_stored_starts_at_mac_63_and_autobauds() {
        let r = resolve_stored(None);
        assert_eq!(r.mac_id, MacId::MAX);
        assert_eq!(r.mac_id.as_raw(), 63);
        assert!(r.autobaud, "no stored data rate: listen for it");
        assert_eq!(r.baud_rate, crate::autobaud::RATES[0], "the first rate listened to");
        assert!(r.switches.programmable && !r.store_reading);
    }

    #[test]
    fn no_switches_on_an_erased_journal_is_mac_63_with_autobaud() {
        // The configuration at reset as the firmware makes it: the newest record, none here.
        use crate::settings::{RamFlash, SettingsStore, RECORD_LEN};
        let mut store = SettingsStore::new(RamFlash::<{ 4 * RECORD_LEN }>::new());
        let loaded = store.load().unwrap().map(|l| l.settings);
        let r = resolve_stored(loaded.as_ref());
        assert_eq!((r.mac_id.as_raw(), r.autobaud), (63, true));
        // Once the master set something, the record's values rule, rate included.
        let set = Settings { mac_id: mac(7), baud_rate: BaudRate::Kbps250, ..Settings::default() };
        store.save(&set).unwrap();
        let loaded = store.load().unwrap().map(|l| l.settings);
        let r = resolve_stored(loaded.as_ref());
        assert_eq!((r.mac_id.as_raw(), r.baud_rate, r.autobaud), (7, BaudRate::Kbps250, false));
    }

    #[test]
    fn program_position_uses_stored_values() {
        let stored = Settings { mac_id: mac(20), baud_rate: BaudRate::Kbps500, ..Settings::default() };
        let r = resolve(SwitchReading::from_bits(0b11_000101), &stored);
        assert_eq!((r.mac_id, r.baud_rate), (mac(20), BaudRate::Kbps500));
        assert!(r.switches.programmable);
        assert_eq!(r.switches.baud_rate, Some(3));
    }

    #[test]
    fn program_position_with_nothing_stored_is_mac_63() {
        // The reference board out of the box with its rate switches at "program": MAC ID 63, where
        // a scanner's address recovery looks for it (protocol §II.9.2), settable over the network.
        let r = resolve(SwitchReading::from_bits(0b11_000101), &Settings::default());
        assert_eq!((r.mac_id.as_raw(), r.baud_rate), (63, BaudRate::Kbps125));
        assert!(r.switches.programmable);
        assert_eq!(r.switches.mac_id, Some(5), "attribute 8 still reports the switches");
    }

    #[rstest]
    #[case::first_boot(None, 0b01_000101, false, false, true)]
    #[case::unchanged(Some(0b01_000101), 0b01_000101, false, false, false)]
    #[case::mac_moved(Some(0b01_000101), 0b01_000110, true, false, true)]
    #[case::rate_moved(Some(0b01_000101), 0b10_000101, false, true, true)]
    #[case::both_moved(Some(0b01_000101), 0b11_000000, true, true, true)]
    fn changed_attributes(
        #[case] last: Option<u8>,
        #[case] now: u8,
        #[case] mac_changed: bool,
        #[case] baud_changed: bool,
        #[case] store: bool,
    ) {
        let stored = Settings { last_switches: last, ..Settings::default() };
        let r = resolve(SwitchReading::from_bits(now), &stored);
        assert_eq!(r.switches.mac_id_changed, mac_changed);
        assert_eq!(r.switches.baud_rate_changed, baud_changed);
        assert_eq!(r.store_reading, store);
    }
}
