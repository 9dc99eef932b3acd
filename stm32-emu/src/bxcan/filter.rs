//! The filter module shared by CAN1 and CAN2 (RM0090 §32.7.4 "Identifier filtering", registers
//! §32.9.4): 28 banks, each two 32-bit registers, configured by `CAN_FMR` (FINIT, CAN2SB),
//! `CAN_FM1R` (mask or list), `CAN_FS1R` (16 or 32 bits), `CAN_FFA1R` (FIFO 0 or 1) and
//! `CAN_FA1R` (active).
//!
//! Write protection (RM0090 §32.9.1 "Register access protection" and the notes of §32.9.4):
//! `CAN_FM1R`, `CAN_FS1R` and `CAN_FFA1R` are written only while FINIT is set; a bank's
//! `CAN_FiR1`/`CAN_FiR2` only while FINIT is set or the bank is inactive. Other writes are
//! ignored. `CAN_FA1R` and `CAN_FMR` are writable at any time.

/// `CAN_FMR` (RM0090 §32.9.4): FINIT bit 0, CAN2SB bits 13:8; the reset value 0x2A1C_0E01
/// (CAN2SB = 14, FINIT = 1) keeps 0x2A1C in its reserved upper half, which the model reads back.
const FMR_RESERVED: u32 = 0x2A1C_0000;
/// FINIT in `CAN_FMR`.
pub const FINIT: u32 = 1 << 0;
/// The number of filter banks of a dual-CAN STM32F4 (RM0090 §32.3.4).
pub const BANKS: usize = 28;
/// The valid bits of `CAN_FM1R`, `CAN_FS1R`, `CAN_FFA1R`, `CAN_FA1R`: one per bank.
const BANK_BITS: u32 = (1 << BANKS) - 1;

/// Register offsets within the CAN1 block (RM0090 §32.9.5 "bxCAN register map").
pub mod offset {
    /// `CAN_FMR`.
    pub const FMR: u32 = 0x200;
    /// `CAN_FM1R`.
    pub const FM1R: u32 = 0x204;
    /// `CAN_FS1R`.
    pub const FS1R: u32 = 0x20C;
    /// `CAN_FFA1R`.
    pub const FFA1R: u32 = 0x214;
    /// `CAN_FA1R`.
    pub const FA1R: u32 = 0x21C;
    /// `CAN_F0R1`; bank n's `CAN_FnR1` is at `F0R1 + 8n`, `CAN_FnR2` 4 bytes later.
    pub const F0R1: u32 = 0x240;
    /// One past `CAN_F27R2`.
    pub const END: u32 = F0R1 + 8 * super::BANKS as u32;
}

/// Where a frame that passed the filters goes: its FIFO and filter match index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Match {
    /// Receive FIFO 0 or 1.
    pub fifo: usize,
    /// The filter match index (FMI) stored in `CAN_RDTxR` (RM0090 §32.7.4 "Filter match index").
    pub fmi: u8,
}

/// The filter banks and their configuration registers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FilterModule {
    finit: bool,
    can2sb: u32,
    fm1r: u32,
    fs1r: u32,
    ffa1r: u32,
    fa1r: u32,
    banks: [[u32; 2]; BANKS],
}

impl Default for FilterModule {
    fn default() -> Self {
        FilterModule::new()
    }
}

impl FilterModule {
    /// The filter module at reset (RM0090 §32.9.4): FINIT set, CAN2SB 14, every bank a
    /// deactivated 16-bit mask filter for FIFO 0. The bank registers are undefined at reset;
    /// the model starts them at 0 (no source gives a value).
    pub const fn new() -> FilterModule {
        FilterModule { finit: true, can2sb: 14, fm1r: 0, fs1r: 0, ffa1r: 0, fa1r: 0, banks: [[0; 2]; BANKS] }
    }

    /// Whether the filters are in initialisation mode (FINIT). While they are, the model stores
    /// no received frame: RM0090 §32.9.4 names FINIT = 0 "active filters mode", so with FINIT
    /// set no filter is active. No source says outright what the hardware does with a frame
    /// that arrives meanwhile; dropping it is the model's choice.
    pub const fn in_init(&self) -> bool {
        self.finit
    }

    /// The first bank that belongs to CAN2 (CAN2SB; values above 28 count as 28, every bank to
    /// CAN1: the model's choice, RM0090 names 28 as the largest meaningful value).
    pub fn can2_start_bank(&self) -> usize {
        (self.can2sb as usize).min(BANKS)
    }

    /// Reads a filter register at `offset` within the CAN1 block (0 for reserved addresses).
    pub fn read(&self, offset: u32) -> u32 {
        match offset {
            offset::FMR => FMR_RESERVED | (self.can2sb << 8) | u32::from(self.finit),
            offset::FM1R => self.fm1r,
            offset::FS1R => self.fs1r,
            offset::FFA1R => self.ffa1r,
            offset::FA1R => self.fa1r,
            o if (offset::F0R1..offset::END).contains(&o) => {
                let (bank, reg) = bank_register(o);
                self.banks[bank][reg]
            }
            _ => 0,
        }
    }

    /// Writes a filter register; what the hardware refuses (module docs) is ignored.
    pub fn write(&mut self, offset: u32, value: u32) {
        match offset {
            offset::FMR => {
                self.finit = value & FINIT != 0;
                self.can2sb = (value >> 8) & 0x3F;
            }
            offset::FM1R if self.finit => self.fm1r = value & BANK_BITS,
            offset::FS1R if self.finit => self.fs1r = value & BANK_BITS,
            offset::FFA1R if self.finit => self.ffa1r = value & BANK_BITS,
            offset::FA1R => self.fa1r = value & BANK_BITS,
            o if (offset::F0R1..offset::END).contains(&o) => {
                let (bank, reg) = bank_register(o);
                if self.finit || self.fa1r & (1 << bank) == 0 {
                    self.banks[bank][reg] = value;
                }
            }
            _ => {}
        }
    }

    /// The filters a bank holds: 1 (32-bit mask), 2 (32-bit list, 16-bit mask) or 4 (16-bit
    /// list) (RM0090 §32.7.4 "Filter bank scale and mode configuration").
    fn filters_in(&self, bank: usize) -> u32 {
        match (self.is_32_bit(bank), self.is_list(bank)) {
            (true, false) => 1,
            (true, true) | (false, false) => 2,
            (false, true) => 4,
        }
    }

    fn is_32_bit(&self, bank: usize) -> bool {
        self.fs1r & (1 << bank) != 0
    }

    fn is_list(&self, bank: usize) -> bool {
        self.fm1r & (1 << bank) != 0
    }

    fn fifo_of(&self, bank: usize) -> usize {
        usize::from(self.ffa1r & (1 << bank) != 0)
    }

    /// The filter number of a bank's first filter in its FIFO's numbering (RM0090 §32.7.4
    /// "Filter match index": one numbering per FIFO, counting every bank of that FIFO whether
    /// active or not). `first_bank` is the first bank of the controller: 0 for CAN1; for CAN2,
    /// CAN2SB (no source says whether CAN2's numbering starts at its first bank; the model's
    /// choice).
    fn first_number(&self, first_bank: usize, bank: usize) -> u32 {
        let fifo = self.fifo_of(bank);
        (first_bank..bank).filter(|&b| self.fifo_of(b) == fifo).map(|b| self.filters_in(b)).sum()
    }

    /// The positions (0-based within the bank) of the bank's filters that `frame` passes.
    fn matches_in(&self, bank: usize, word32: u32, word16: u16) -> Option<u32> {
        let [r1, r2] = self.banks[bank];
        let halves = [r1 as u16, (r1 >> 16) as u16, r2 as u16, (r2 >> 16) as u16];
        match (self.is_32_bit(bank), self.is_list(bank)) {
            // One filter: FR1 identifier, FR2 mask (1 = must match).
            (true, false) => ((word32 ^ r1) & r2 == 0).then_some(0),
            // Two identifiers. Bit 0 (TXRQ's place, reserved in received frames) is ignored:
            // the model's choice, RM0090 maps no identifier bit there.
            (true, true) => [r1, r2].iter().position(|&r| (word32 ^ r) & !1 == 0).map(|p| p as u32),
            // Two filters: FR1[15:0] identifier with FR1[31:16] mask, then FR2 likewise.
            (false, false) => {
                let pairs = [(halves[0], halves[1]), (halves[2], halves[3])];
                pairs.iter().position(|&(id, mask)| (word16 ^ id) & mask == 0).map(|p| p as u32)
            }
            // Four identifiers: FR1[15:0], FR1[31:16], FR2[15:0], FR2[31:16].
            (false, true) => halves.iter().position(|&id| id == word16).map(|p| p as u32),
        }
    }

    /// Where a received frame goes, or `None` when no active filter of banks
    /// `first_bank..end_bank` passes it.
    ///
    /// When several filters pass a frame, RM0090 §32.7.4 "Filter priority rules" decide: a
    /// 32-bit filter before a 16-bit one, then identifier list before identifier mask, then the
    /// lower filter number. Filter numbers are counted per FIFO; between equal numbers of the
    /// two FIFOs the model takes the lower bank (no source covers that case).
    pub fn route(&self, word32: u32, word16: u16, first_bank: usize, end_bank: usize) -> Option<Match> {
        let mut best: Option<((bool, bool, u32, usize), Match)> = None;
        for bank in first_bank..end_bank.min(BANKS) {
            if self.fa1r & (1 << bank) == 0 {
                continue;
            }
            let Some(position) = self.matches_in(bank, word32, word16) else { continue };
            let number = self.first_number(first_bank, bank) + position;
            // Lower key wins: 32-bit first, list first, lower number, lower bank.
            let key = (!self.is_32_bit(bank), !self.is_list(bank), number, bank);
            let found = Match { fifo: self.fifo_of(bank), fmi: number.min(255) as u8 };
            if best.as_ref().is_none_or(|(k, _)| key < *k) {
                best = Some((key, found));
            }
        }
        best.map(|(_, m)| m)
    }
}

/// The bank and register (0 = FR1, 1 = FR2) of a filter bank register offset.
fn bank_register(offset: u32) -> (usize, usize) {
    let index = ((offset - offset::F0R1) / 4) as usize;
    (index / 2, index % 2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    /// Banks configured as RM0090 §32.7.4's numbering example begins: bank 0 32-bit list
    /// (FIFO 0), bank 1 32-bit mask (FIFO 1), bank 2 16-bit list (FIFO 0), bank 3 16-bit mask
    /// (FIFO 1), bank 4 16-bit mask (FIFO 0, inactive), bank 5 32-bit mask (FIFO 0).
    fn example() -> FilterModule {
        let mut f = FilterModule::new();
        f.write(offset::FM1R, 0b00_0101);
        f.write(offset::FS1R, 0b10_0011);
        f.write(offset::FFA1R, 0b00_1010);
        f.write(offset::FA1R, 0b10_1111);
        f
    }

    #[rstest]
    // FIFO 0: bank 0 holds 0 and 1, bank 2 holds 2..=5, bank 4 (inactive, still counted) 6 and
    // 7, bank 5 is 8. FIFO 1: bank 1 is 0, bank 3 holds 1 and 2.
    #[case::bank0(0, 0)]
    #[case::bank2(2, 2)]
    #[case::bank4_inactive_counts(4, 6)]
    #[case::bank5(5, 8)]
    #[case::bank1_fifo1(1, 0)]
    #[case::bank3_fifo1(3, 1)]
    fn filter_numbering(#[case] bank: usize, #[case] first: u32) {
        assert_eq!(example().first_number(0, bank), first);
    }

    #[rstest]
    #[case::mask32_passes(false, true, [0x428 << 21, 0x7F8 << 21 | 0b110], 0x42B << 21, true)]
    #[case::mask32_refuses_ide(false, true, [0x428 << 21, 0x7F8 << 21 | 0b100], 0x42B << 21 | 0b100, false)]
    #[case::list32_second(true, true, [0x100 << 21, 0x200 << 21], 0x200 << 21, true)]
    #[case::list32_exact_only(true, true, [0x100 << 21, 0x200 << 21], 0x201 << 21, false)]
    fn thirty_two_bit(
        #[case] list: bool,
        #[case] scale32: bool,
        #[case] regs: [u32; 2],
        #[case] word: u32,
        #[case] passes: bool,
    ) {
        let mut f = FilterModule::new();
        f.write(offset::FM1R, u32::from(list));
        f.write(offset::FS1R, u32::from(scale32));
        f.write(offset::F0R1, regs[0]);
        f.write(offset::F0R1 + 4, regs[1]);
        f.write(offset::FA1R, 1);
        f.write(offset::FMR, 0x0E00);
        assert_eq!(f.route(word, 0, 0, 14).is_some(), passes);
    }

    #[test]
    fn sixteen_bit_list_positions() {
        let mut f = FilterModule::new();
        f.write(offset::FM1R, 1);
        f.write(offset::F0R1, (0x101 << 5) << 16 | 0x100 << 5);
        f.write(offset::F0R1 + 4, (0x103 << 5) << 16 | 0x102 << 5);
        f.write(offset::FA1R, 1);
        for (i, id) in (0x100u16..=0x103).enumerate() {
            assert_eq!(f.route(0, id << 5, 0, 14), Some(Match { fifo: 0, fmi: i as u8 }));
        }
        assert_eq!(f.route(0, 0x104 << 5, 0, 14), None);
    }

    #[test]
    fn priority_32_bit_over_16_bit_and_list_over_mask() {
        let mut f = FilterModule::new();
        // Bank 0: 16-bit mask accepting everything; bank 1: 32-bit mask accepting everything;
        // bank 2: 32-bit list with 0x123. All FIFO 0.
        f.write(offset::FS1R, 0b110);
        f.write(offset::FM1R, 0b100);
        f.write(offset::F0R1 + 16, 0x123 << 21);
        f.write(offset::F0R1 + 20, 0x123 << 21);
        f.write(offset::FA1R, 0b111);
        let word32 = 0x123 << 21;
        let word16 = 0x123 << 5;
        // Numbers: bank 0 holds 0, 1; bank 1 is 2; bank 2 holds 3, 4.
        assert_eq!(f.route(word32, word16, 0, 14), Some(Match { fifo: 0, fmi: 3 }));
        assert_eq!(f.route(0x124 << 21, 0x124 << 5, 0, 14), Some(Match { fifo: 0, fmi: 2 }));
    }

    #[rstest]
    #[case::fm1r(offset::FM1R)]
    #[case::fs1r(offset::FS1R)]
    #[case::ffa1r(offset::FFA1R)]
    fn configuration_refused_outside_finit(#[case] reg: u32) {
        let mut f = FilterModule::new();
        f.write(offset::FMR, 0x0E00);
        f.write(reg, 0xFFFF_FFFF);
        assert_eq!(f.read(reg), 0);
        f.write(offset::FMR, 0x0E01);
        f.write(reg, 0xFFFF_FFFF);
        assert_eq!(f.read(reg), BANK_BITS);
    }

    #[test]
    fn bank_registers_writable_when_inactive_or_in_finit() {
        let mut f = FilterModule::new();
        f.write(offset::FMR, 0x0E00);
        f.write(offset::F0R1, 0x1234);
        assert_eq!(f.read(offset::F0R1), 0x1234, "inactive bank, FINIT clear: written");
        f.write(offset::FA1R, 1);
        f.write(offset::F0R1, 0x5678);
        assert_eq!(f.read(offset::F0R1), 0x1234, "active bank, FINIT clear: refused");
        f.write(offset::FMR, 0x0E01);
        f.write(offset::F0R1, 0x5678);
        assert_eq!(f.read(offset::F0R1), 0x5678, "FINIT set: written");
    }

    #[test]
    fn reset_values_and_split() {
        let mut f = FilterModule::new();
        assert_eq!(f.read(offset::FMR), 0x2A1C_0E01);
        f.write(offset::FMR, 28 << 8 | 1);
        assert_eq!(f.can2_start_bank(), 28);
        // Banks at or above CAN2SB are CAN2's: CAN1 does not see them.
        f.write(offset::FMR, 1 << 8 | 1);
        f.write(offset::FA1R, 0b10);
        assert_eq!(f.route(0, 0, 0, f.can2_start_bank()), None);
        assert_eq!(f.route(0, 0, 1, 28), Some(Match { fifo: 0, fmi: 0 }));
    }
}
