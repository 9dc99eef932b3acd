//! The non-volatile settings: what the master set over the network (MAC ID and data rate for the
//! switches' program position, the bus-off interrupt setting), the converter's configuration
//! image, and the switch reading of the last reset.
//!
//! ## Power-safe storage
//!
//! Flash is erased a whole sector at a time, so one sector cannot survive a reset during its own
//! erase. The store therefore uses **two** sectors, A and B, as a journal of fixed-size
//! [`RECORD_LEN`]-byte records, each with a sequence number and a CRC-32:
//!
//! - `save` appends a record with the next sequence number in the first free slot of the sector
//!   holding the newest record; when that sector is full it erases the *other* sector and writes
//!   there. The newest complete record is never erased before a newer one is complete.
//! - `load` scans both sectors and returns the valid record with the highest sequence number;
//!   torn records (bad CRC) and half-erased garbage are skipped.
//!
//! So a reset at any point of a save leaves either the old or the new settings, never neither,
//! and never a mixture: the configuration image travels in the same record as the network
//! settings, so a downloaded image and the settings it was stored with are committed together by
//! the record's CRC. The host tests cut the power after every single byte written or erased, with
//! configuration images of several hundred bytes, to prove it. The logic
//! is written against the [`SettingsFlash`] trait; [`RamFlash`] implements it in memory (host tests,
//! the emulated board) and the firmware's driver implements it on the STM32's sectors 1 and 2
//! ([`crate::memory`]).
//!
//! With 16 KiB sectors a sector holds 25 records, so a sector is erased once every 25 saves
//! (settings change rarely: a MAC ID or data rate set over the network, a configuration
//! download); the 32-bit sequence number cannot wrap within the flash's endurance.
//!
//! Before the firmware update (issue 31) the journal lived in the chip's last two 128 KiB sectors;
//! [`SettingsStore::migrate_from`] moves its newest record into the new sectors once, at the first
//! start of a firmware with the new layout.
//!
//! Records of the earlier 128-byte layout (magic `DNS1`) are not read: a board updated from it
//! starts from the defaults, as a new board does.
//!
//! ## Record layout (little-endian)
//!
//! | bytes | field |
//! |---|---|
//! | 0–3 | magic `DNS2` |
//! | 4–7 | sequence number |
//! | 8 | MAC ID (0–63) |
//! | 9 | data rate, DeviceNet attribute value (0–2) |
//! | 10 | flags: bit 0 bus-off interrupt, bit 1 `last_switches` present |
//! | 11 | last switch reading |
//! | 12–13 | configuration image length (0–[`IMAGE_CAPACITY`]) |
//! | 14–15 | reserved, 0 |
//! | 16–635 | configuration image, then 0 |
//! | 636–639 | CRC-32 of bytes 0–635 |

use core::fmt;
use devicenet::crc32::crc32;
use devicenet::slave::BaudRate;
use devicenet::MacId;

/// Bytes per record (a multiple of the STM32F4's 16-byte flash row).
pub const RECORD_LEN: usize = 640;
/// Largest configuration image the record holds (the converter's images are at most
/// `slave_fw::image::MAX_IMAGE` bytes; the firmware checks the two agree at compile time).
pub const IMAGE_CAPACITY: usize = RECORD_LEN - IMAGE_AT - 4;
/// Record magic.
pub const MAGIC: [u8; 4] = *b"DNS2";

const IMAGE_AT: usize = 16;
const CRC_AT: usize = RECORD_LEN - 4;
const FLAG_BOI: u8 = 1;
const FLAG_SWITCHES: u8 = 2;

/// The settings the board keeps across resets.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Settings {
    /// MAC ID used when the switches are in the program position (DeviceNet attribute 1).
    pub mac_id: MacId,
    /// Data rate used when the switches are in the program position (DeviceNet attribute 2).
    pub baud_rate: BaudRate,
    /// Bus-off interrupt (DeviceNet attribute 3).
    pub bus_off_interrupt: bool,
    /// The switch reading ("on" = 1) of the last reset, for the "switch changed" attributes.
    pub last_switches: Option<u8>,
    /// The converter's configuration image, opaque to the board (empty: none stored).
    pub image: heapless::Vec<u8, IMAGE_CAPACITY>,
}

impl Default for Settings {
    /// An unconfigured DeviceNet node: MAC 63, 125 kbit/s, BOI off, no configuration image.
    fn default() -> Settings {
        Settings {
            mac_id: MacId::MAX,
            baud_rate: BaudRate::Kbps125,
            bus_off_interrupt: false,
            last_switches: None,
            image: heapless::Vec::new(),
        }
    }
}

impl Settings {
    /// The record for these settings with `sequence`.
    pub fn encode(&self, sequence: u32) -> [u8; RECORD_LEN] {
        let mut r = [0u8; RECORD_LEN];
        self.encode_into(sequence, &mut r);
        r
    }

    /// Writes the record for these settings with `sequence` into `r` (zeroed).
    // In place: the save builds its record where it is written from, not a second 640-byte copy
    // on the stack.
    fn encode_into(&self, sequence: u32, r: &mut [u8; RECORD_LEN]) {
        r[0..4].copy_from_slice(&MAGIC);
        r[4..8].copy_from_slice(&sequence.to_le_bytes());
        r[8] = self.mac_id.as_raw();
        r[9] = self.baud_rate.attribute_value();
        r[10] = if self.bus_off_interrupt { FLAG_BOI } else { 0 }
            | if self.last_switches.is_some() { FLAG_SWITCHES } else { 0 };
        r[11] = self.last_switches.unwrap_or(0);
        // At most IMAGE_CAPACITY, which fits 16 bits.
        r[12..14].copy_from_slice(&(self.image.len() as u16).to_le_bytes());
        // The image fits its field (IMAGE_CAPACITY); zipped rather than sliced to its length, so
        // there is no panic path.
        for (to, from) in r[IMAGE_AT..CRC_AT].iter_mut().zip(&self.image) {
            *to = *from;
        }
        let crc = crc32(&r[..CRC_AT]);
        r[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
    }

    /// The settings and sequence number in a record, or why it is not a valid record.
    pub fn decode(record: &[u8; RECORD_LEN]) -> Result<(Settings, u32), RecordError> {
        let sequence = Settings::check(record)?;
        let mut settings = Settings::default();
        settings.fill_checked(record);
        Ok((settings, sequence))
    }

    /// The sequence number of a valid record, or why it is not one ([`Settings::decode`]'s
    /// checks).
    fn check(record: &[u8; RECORD_LEN]) -> Result<u32, RecordError> {
        if record.iter().all(|&b| b == 0xFF) {
            return Err(RecordError::Erased);
        }
        if record[0..4] != MAGIC {
            return Err(RecordError::Magic);
        }
        let crc =
            u32::from_le_bytes([record[CRC_AT], record[CRC_AT + 1], record[CRC_AT + 2], record[CRC_AT + 3]]);
        if crc32(&record[..CRC_AT]) != crc {
            return Err(RecordError::Crc);
        }
        let flags = record[10];
        let len = usize::from(u16::from_le_bytes([record[12], record[13]]));
        if MacId::new(record[8]).is_none()
            || BaudRate::from_attribute_value(record[9]).is_none()
            || flags & !(FLAG_BOI | FLAG_SWITCHES) != 0
            || len > IMAGE_CAPACITY
        {
            return Err(RecordError::Field);
        }
        Ok(u32::from_le_bytes([record[4], record[5], record[6], record[7]]))
    }

    /// Sets these settings to those of a record that [`Settings::check`] accepted.
    // In place: the scan checks every record without building its settings, and fills the newest
    // one's where they are kept instead of moving a 624-byte image through the stack.
    fn fill_checked(&mut self, record: &[u8; RECORD_LEN]) {
        let flags = record[10];
        let len = usize::from(u16::from_le_bytes([record[12], record[13]]));
        self.image.clear();
        // At most the capacity (checked); too long would leave the image empty.
        let _ = self.image.extend_from_slice(record.get(IMAGE_AT..IMAGE_AT + len).unwrap_or_default());
        // Both checked; the defaults are never used.
        self.mac_id = MacId::new(record[8]).unwrap_or(MacId::MAX);
        self.baud_rate = BaudRate::from_attribute_value(record[9]).unwrap_or(BaudRate::Kbps125);
        self.bus_off_interrupt = flags & FLAG_BOI != 0;
        self.last_switches = (flags & FLAG_SWITCHES != 0).then_some(record[11]);
    }
}

/// Why a slot does not hold a valid record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RecordError {
    /// All 0xFF: never written since the last erase.
    Erased,
    /// Not a settings record (garbage, a torn write, a half-erased sector).
    Magic,
    /// A torn or corrupted record.
    Crc,
    /// The CRC matches but a field is out of range (written by an incompatible version).
    Field,
}

/// One of the two sectors of the store.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Sector {
    /// The first sector.
    A,
    /// The second sector.
    B,
}

impl Sector {
    /// The other sector.
    pub const fn other(self) -> Sector {
        match self {
            Sector::A => Sector::B,
            Sector::B => Sector::A,
        }
    }

    /// 0 for A, 1 for B.
    pub const fn index(self) -> usize {
        match self {
            Sector::A => 0,
            Sector::B => 1,
        }
    }
}

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlashError {
    /// The access does not fit in the sector.
    OutOfBounds,
    /// The flash controller reported an error (programming sequence, alignment, write
    /// protection).
    Controller,
    /// Read-back after programming differs from what was written.
    Verify,
    /// The simulated power was cut ([`RamFlash`] only).
    PowerLost,
}

impl fmt::Display for FlashError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FlashError::OutOfBounds => "flash access outside the settings sector",
            FlashError::Controller => "the flash controller reported an error",
            FlashError::Verify => "flash read-back differs from what was written",
            FlashError::PowerLost => "simulated power loss",
        })
    }
}

impl core::error::Error for FlashError {}

/// Two equal, separately erasable flash sectors with NOR semantics: erase sets every byte to
/// 0xFF, programming can only clear bits.
pub trait SettingsFlash {
    /// Bytes per sector; it holds `sector_len / RECORD_LEN` records.
    fn sector_len(&self) -> usize;
    /// Reads `buf.len()` bytes at `offset` of `sector`.
    fn read(&mut self, sector: Sector, offset: usize, buf: &mut [u8]) -> Result<(), FlashError>;
    /// Erases `sector`.
    fn erase(&mut self, sector: Sector) -> Result<(), FlashError>;
    /// Programs `data` at `offset` of `sector`.
    fn program(&mut self, sector: Sector, offset: usize, data: &[u8]) -> Result<(), FlashError>;
}

/// The newest valid record found by [`SettingsStore::load`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Loaded {
    /// The settings.
    pub settings: Settings,
    /// Its sequence number.
    pub sequence: u32,
    /// Where it is.
    pub sector: Sector,
    /// Its slot in the sector.
    pub slot: usize,
}

struct Scan {
    newest: Option<Loaded>,
    /// Per sector, one past the last slot that is not erased.
    used: [usize; 2],
}

/// The power-safe settings journal over a [`SettingsFlash`].
pub struct SettingsStore<F> {
    flash: F,
}

impl<F: SettingsFlash> SettingsStore<F> {
    /// A store over `flash`.
    pub const fn new(flash: F) -> Self {
        SettingsStore { flash }
    }

    /// The flash underneath.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// Gives the flash back.
    pub fn into_inner(self) -> F {
        self.flash
    }

    fn slots(&self) -> usize {
        self.flash.sector_len() / RECORD_LEN
    }

    fn scan(&mut self) -> Result<Scan, FlashError> {
        let mut scan = Scan { newest: None, used: [0, 0] };
        let mut record = [0u8; RECORD_LEN];
        for sector in [Sector::A, Sector::B] {
            for slot in 0..self.slots() {
                self.flash.read(sector, slot * RECORD_LEN, &mut record)?;
                match Settings::check(&record) {
                    Err(RecordError::Erased) => continue,
                    Ok(sequence) => {
                        if scan.newest.as_ref().is_none_or(|n| sequence > n.sequence) {
                            let newest = scan.newest.insert(Loaded {
                                settings: Settings::default(),
                                sequence,
                                sector,
                                slot,
                            });
                            newest.settings.fill_checked(&record);
                        }
                    }
                    Err(_) => {}
                }
                scan.used[sector.index()] = slot + 1;
            }
        }
        Ok(scan)
    }

    /// The newest valid settings, `None` when the store holds none.
    pub fn load(&mut self) -> Result<Option<Loaded>, FlashError> {
        Ok(self.scan()?.newest)
    }

    /// The newest valid settings, or the defaults when there are none or the flash fails.
    pub fn load_or_default(&mut self) -> Settings {
        match self.load() {
            Ok(Some(loaded)) => loaded.settings,
            _ => Settings::default(),
        }
    }

    /// Appends `settings` as the newest record; returns its sequence number.
    pub fn save(&mut self, settings: &Settings) -> Result<u32, FlashError> {
        let scan = self.scan()?;
        let (mut sector, sequence) = match &scan.newest {
            Some(n) => (n.sector, n.sequence.wrapping_add(1)),
            None => (Sector::A, 1),
        };
        let mut slot = scan.used[sector.index()];
        if slot >= self.slots() {
            // The current sector is full: start the other one. The newest record stays intact
            // in this sector until the new one is complete.
            sector = sector.other();
            self.flash.erase(sector)?;
            slot = 0;
        }
        let mut record = [0u8; RECORD_LEN];
        settings.encode_into(sequence, &mut record);
        self.flash.program(sector, slot * RECORD_LEN, &record)?;
        let mut check = [0u8; RECORD_LEN];
        self.flash.read(sector, slot * RECORD_LEN, &mut check)?;
        if check != record {
            return Err(FlashError::Verify);
        }
        Ok(sequence)
    }
}

/// What [`SettingsStore::migrate_from`] found and did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Migration {
    /// This journal already holds a valid record: the old location was not read.
    NotNeeded,
    /// The old location's newest record was saved here with this sequence number.
    Moved {
        /// The record's sequence number in this journal.
        sequence: u32,
    },
    /// This journal is empty and the old location holds no valid record either.
    NothingToMove,
}

impl<F: SettingsFlash> SettingsStore<F> {
    /// Moves the settings of a journal at an older location into this one, once: when this
    /// journal holds no valid record, the newest valid record of `old` (read with the same
    /// [`load`](SettingsStore::load)) is [`save`](SettingsStore::save)d here. The save is
    /// power-safe as every save: a reset before it completes leaves this journal empty, so the
    /// migration runs again at the next start. `old` is only read, never erased or written.
    ///
    /// The firmware calls it at start, before anything may erase the old location (on the
    /// STM32F446RE the old sectors become the update's DFU slot).
    pub fn migrate_from<G: SettingsFlash>(
        &mut self,
        old: &mut SettingsStore<G>,
    ) -> Result<Migration, FlashError> {
        if self.load()?.is_some() {
            return Ok(Migration::NotNeeded);
        }
        match old.load()? {
            Some(loaded) => Ok(Migration::Moved { sequence: self.save(&loaded.settings)? }),
            None => Ok(Migration::NothingToMove),
        }
    }
}

/// Two `N`-byte sectors in RAM with NOR flash semantics, and an optional power cut after a given
/// number of byte operations. It backs the host tests and the emulated board (where settings last
/// until the emulator stops).
#[derive(Clone, Debug)]
pub struct RamFlash<const N: usize> {
    sectors: [[u8; N]; 2],
    budget: Option<usize>,
}

impl<const N: usize> Default for RamFlash<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RamFlash<N> {
    /// Two erased sectors.
    pub const fn new() -> Self {
        RamFlash { sectors: [[0xFF; N]; 2], budget: None }
    }

    /// Cuts the power after `operations` more byte writes or erases (`None`: never).
    pub fn cut_power_after(&mut self, operations: Option<usize>) {
        self.budget = operations;
    }

    /// The contents of `sector`.
    pub fn sector(&self, sector: Sector) -> &[u8; N] {
        &self.sectors[sector.index()]
    }

    fn spend(&mut self) -> Result<(), FlashError> {
        match &mut self.budget {
            Some(0) => Err(FlashError::PowerLost),
            Some(n) => {
                *n -= 1;
                Ok(())
            }
            None => Ok(()),
        }
    }

    fn range(offset: usize, len: usize) -> Result<core::ops::Range<usize>, FlashError> {
        match offset.checked_add(len) {
            Some(end) if end <= N => Ok(offset..end),
            _ => Err(FlashError::OutOfBounds),
        }
    }
}

impl<const N: usize> SettingsFlash for RamFlash<N> {
    fn sector_len(&self) -> usize {
        N
    }

    fn read(&mut self, sector: Sector, offset: usize, buf: &mut [u8]) -> Result<(), FlashError> {
        let range = Self::range(offset, buf.len())?;
        buf.copy_from_slice(&self.sectors[sector.index()][range]);
        Ok(())
    }

    fn erase(&mut self, sector: Sector) -> Result<(), FlashError> {
        for i in 0..N {
            self.spend()?;
            self.sectors[sector.index()][i] = 0xFF;
        }
        Ok(())
    }

    fn program(&mut self, sector: Sector, offset: usize, data: &[u8]) -> Result<(), FlashError> {
        let range = Self::range(offset, data.len())?;
        for (i, &b) in range.zip(data) {
            self.spend()?;
            self.sectors[sector.index()][i] &= b;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    /// Three records per sector, so the tests wrap around the sectors quickly.
    type Flash = RamFlash<{ 3 * RECORD_LEN }>;

    /// Settings numbered `n`, with a 10-byte configuration image.
    fn settings(n: u8) -> Settings {
        with_image(n, 10)
    }

    /// Settings numbered `n` with an `image_len`-byte configuration image whose every byte
    /// depends on `n`, so two images never agree on a byte run long enough to hide a mixture.
    fn with_image(n: u8, image_len: usize) -> Settings {
        let image = (0..image_len).map(|i| (i as u8).wrapping_mul(31) ^ n).collect();
        Settings {
            mac_id: MacId::new(n % 64).unwrap(),
            baud_rate: BaudRate::from_attribute_value(n % 3).unwrap(),
            bus_off_interrupt: n % 2 == 1,
            last_switches: (n % 4 != 0).then_some(n),
            image,
        }
    }

    #[test]
    fn record_round_trip() {
        let s = settings(7);
        let r = s.encode(42);
        assert_eq!(&r[0..4], b"DNS2");
        assert_eq!(Settings::decode(&r), Ok((s, 42)));
        let full = with_image(1, IMAGE_CAPACITY);
        assert_eq!(Settings::decode(&full.encode(1)), Ok((full, 1)));
        let none = with_image(2, 0);
        assert_eq!(Settings::decode(&none.encode(3)), Ok((none, 3)));
    }

    #[rstest]
    #[case::erased(|r: &mut [u8; RECORD_LEN]| r.fill(0xFF), RecordError::Erased)]
    #[case::zeros(|r: &mut [u8; RECORD_LEN]| r.fill(0), RecordError::Magic)]
    #[case::bit_flip(|r: &mut [u8; RECORD_LEN]| r[20] ^= 1, RecordError::Crc)]
    #[case::torn_tail(|r: &mut [u8; RECORD_LEN]| r[100..].fill(0xFF), RecordError::Crc)]
    fn bad_records(#[case] damage: fn(&mut [u8; RECORD_LEN]), #[case] err: RecordError) {
        let mut r = settings(3).encode(9);
        damage(&mut r);
        assert_eq!(Settings::decode(&r), Err(err));
    }

    #[test]
    fn out_of_range_field_with_good_crc() {
        let mut r = settings(3).encode(9);
        r[8] = 64;
        let crc = crc32(&r[..CRC_AT]);
        r[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Settings::decode(&r), Err(RecordError::Field));
    }

    #[test]
    fn image_longer_than_the_record_with_good_crc() {
        let mut r = settings(3).encode(9);
        r[12..14].copy_from_slice(&(IMAGE_CAPACITY as u16 + 1).to_le_bytes());
        let crc = crc32(&r[..CRC_AT]);
        r[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Settings::decode(&r), Err(RecordError::Field));
    }

    #[test]
    fn earlier_layout_is_not_read() {
        let mut r = settings(3).encode(9);
        r[0..4].copy_from_slice(b"DNS1");
        assert_eq!(Settings::decode(&r), Err(RecordError::Magic));
    }

    #[test]
    fn empty_store_loads_nothing_and_defaults() {
        let mut store = SettingsStore::new(Flash::new());
        assert_eq!(store.load(), Ok(None));
        assert_eq!(store.load_or_default(), Settings::default());
    }

    #[test]
    fn newest_record_wins_across_sector_switches() {
        let mut store = SettingsStore::new(Flash::new());
        for n in 1..=10u8 {
            assert_eq!(store.save(&settings(n)), Ok(u32::from(n)));
            let loaded = store.load().unwrap().unwrap();
            assert_eq!(loaded.settings, settings(n));
            assert_eq!(loaded.sequence, u32::from(n));
        }
        // 10 records, 3 per sector: A(1-3) B(4-6) A(7-9) B(10).
        let loaded = store.load().unwrap().unwrap();
        assert_eq!((loaded.sector, loaded.slot), (Sector::B, 0));
    }

    /// Cuts the power after every possible number of byte operations during a save, then
    /// "reboots" and loads: the result is always the old or the new settings, configuration image
    /// included, never a mixture and never garbage. `image_len` is the length of every stored
    /// configuration image (about 300 bytes for a Modbus gateway's).
    #[rstest]
    #[case::first_save_ever(0, 10)]
    #[case::append_in_sector(1, 10)]
    #[case::last_slot_of_sector(2, 10)]
    #[case::sector_switch_with_erase(3, 10)]
    #[case::second_switch(6, 10)]
    #[case::first_image_ever(0, 300)]
    #[case::image_appended_in_sector(1, 300)]
    #[case::image_in_last_slot(2, 300)]
    #[case::image_with_sector_switch(3, 300)]
    #[case::full_image_with_sector_switch(3, IMAGE_CAPACITY)]
    fn power_loss_never_loses_settings(#[case] saves_before: u8, #[case] image_len: usize) {
        let mut base = SettingsStore::new(Flash::new());
        for n in 1..=saves_before {
            base.save(&with_image(n, image_len)).unwrap();
        }
        let old = (saves_before > 0).then(|| with_image(saves_before, image_len));
        let new = with_image(100, image_len);
        let mut completed = false;
        for budget in 0.. {
            let mut flash = base.flash().clone();
            flash.cut_power_after(Some(budget));
            let mut store = SettingsStore::new(flash);
            let result = store.save(&new);
            let mut flash = store.into_inner();
            flash.cut_power_after(None);
            let loaded = SettingsStore::new(flash).load().unwrap().map(|l| l.settings);
            match result {
                Ok(_) => {
                    assert_eq!(loaded.as_ref(), Some(&new), "budget {budget}");
                    completed = true;
                    break;
                }
                Err(e) => {
                    assert_eq!(e, FlashError::PowerLost);
                    assert!(loaded == old || loaded.as_ref() == Some(&new), "budget {budget}: {loaded:?}");
                }
            }
        }
        assert!(completed);
    }

    #[test]
    fn interrupted_save_then_later_saves_continue() {
        let mut store = SettingsStore::new(Flash::new());
        store.save(&settings(1)).unwrap();
        // Tear the second record half-way.
        let mut flash = store.into_inner();
        flash.cut_power_after(Some(RECORD_LEN / 2));
        let mut store = SettingsStore::new(flash);
        assert_eq!(store.save(&settings(2)), Err(FlashError::PowerLost));
        let mut flash = store.into_inner();
        flash.cut_power_after(None);
        let mut store = SettingsStore::new(flash);
        assert_eq!(store.load_or_default(), settings(1));
        // The torn slot is skipped; the next save lands after it.
        assert_eq!(store.save(&settings(3)), Ok(2));
        let loaded = store.load().unwrap().unwrap();
        assert_eq!((loaded.settings, loaded.slot), (settings(3), 2));
    }

    /// The old location's sectors: larger than the new one's, as the STM32's 128 KiB sectors are
    /// against the new journal's 16 KiB ones.
    type OldFlash = RamFlash<{ 5 * RECORD_LEN }>;

    /// An old journal whose newest record is `settings(n)` after `n` saves.
    fn old_journal(n: u8) -> SettingsStore<OldFlash> {
        let mut old = SettingsStore::new(OldFlash::new());
        for i in 1..=n {
            old.save(&with_image(i, 300)).unwrap();
        }
        old
    }

    #[test]
    fn migration_moves_the_newest_old_record() {
        let mut old = old_journal(7);
        let before = old.flash().clone();
        let mut new = SettingsStore::new(Flash::new());
        assert_eq!(new.migrate_from(&mut old), Ok(Migration::Moved { sequence: 1 }));
        assert_eq!(new.load_or_default(), with_image(7, 300));
        // The old location is read only.
        assert_eq!(old.flash().sector(Sector::A), before.sector(Sector::A));
        assert_eq!(old.flash().sector(Sector::B), before.sector(Sector::B));
        // Done once: the next start finds the new journal in use and leaves it alone.
        assert_eq!(new.migrate_from(&mut old), Ok(Migration::NotNeeded));
        assert_eq!(new.load().unwrap().map(|l| l.sequence), Some(1));
    }

    #[test]
    fn migration_with_nothing_at_the_old_location() {
        let mut old = SettingsStore::new(OldFlash::new());
        // Torn or foreign bytes there are not a record either.
        let mut flash = old.into_inner();
        flash.program(Sector::B, 0, &[0x12; RECORD_LEN]).unwrap();
        old = SettingsStore::new(flash);
        let mut new = SettingsStore::new(Flash::new());
        assert_eq!(new.migrate_from(&mut old), Ok(Migration::NothingToMove));
        assert_eq!(new.load(), Ok(None));
    }

    #[test]
    fn migration_leaves_a_journal_in_use_alone() {
        let mut old = old_journal(3);
        let mut new = SettingsStore::new(Flash::new());
        new.save(&settings(50)).unwrap();
        assert_eq!(new.migrate_from(&mut old), Ok(Migration::NotNeeded));
        assert_eq!(new.load_or_default(), settings(50));
    }

    /// A power cut after every possible number of byte operations of the migration's save, then
    /// a restart that migrates again: the new journal ends with the old record every time.
    #[test]
    fn a_cut_migration_is_repeated_at_the_next_start() {
        let mut old = old_journal(4);
        let mut cuts = 0;
        for budget in 0.. {
            let mut flash = Flash::new();
            flash.cut_power_after(Some(budget));
            let mut new = SettingsStore::new(flash);
            let first = new.migrate_from(&mut old);
            let mut flash = new.into_inner();
            flash.cut_power_after(None);
            let mut new = SettingsStore::new(flash);
            match first {
                Ok(moved) => {
                    assert_eq!(moved, Migration::Moved { sequence: 1 }, "budget {budget}");
                    assert_eq!(new.migrate_from(&mut old), Ok(Migration::NotNeeded));
                    break;
                }
                Err(e) => {
                    assert_eq!(e, FlashError::PowerLost, "budget {budget}");
                    cuts += 1;
                    // The torn record is no record: the restart migrates again, into the next slot.
                    assert_eq!(
                        new.migrate_from(&mut old),
                        Ok(Migration::Moved { sequence: 1 }),
                        "budget {budget}"
                    );
                }
            }
            assert_eq!(new.load_or_default(), with_image(4, 300), "budget {budget}");
        }
        assert_eq!(cuts, RECORD_LEN);
    }

    #[test]
    fn ram_flash_is_nor() {
        let mut f = RamFlash::<16>::new();
        f.program(Sector::A, 0, &[0x0F]).unwrap();
        f.program(Sector::A, 0, &[0xF1]).unwrap();
        assert_eq!(f.sector(Sector::A)[0], 0x01);
        assert_eq!(f.program(Sector::A, 15, &[0, 0]), Err(FlashError::OutOfBounds));
        f.erase(Sector::A).unwrap();
        assert_eq!(f.sector(Sector::A)[0], 0xFF);
    }
}
