//! Register facts of the flash interface, driven as stm32f4xx-hal 0.23's `flash` module drives
//! it for `board::hw::InternalFlash` (unlock, `UnlockedFlash::erase`, `UnlockedFlash::program`,
//! lock on drop).

use super::*;
use crate::gpio::tests::TestMachine;
use crate::periph::Clocks;
use rstest::rstest;

const SECTOR_10: usize = 0xC_0000;
const SECTOR_11: usize = 0xE_0000;

fn modify_cr(f: &mut Flash, m: &mut TestMachine, clear: u32, set: u32) {
    let v = f.read(reg::CR, Width::Word, m);
    f.write(reg::CR, Width::Word, v & !clear | set, m);
}

/// `unlock`: KEY1, KEY2, then the HAL asserts LOCK is clear.
fn hal_unlock(f: &mut Flash, m: &mut TestMachine) -> bool {
    f.write(reg::KEYR, Width::Word, KEY1, m);
    f.write(reg::KEYR, Width::Word, KEY2, m);
    f.read(reg::CR, Width::Word, m) & cr::LOCK == 0
}

/// `wait_ready` (1 µs a poll), then `Error::read`: the SR error flags.
fn hal_wait(f: &mut Flash, m: &mut TestMachine) -> u32 {
    while f.read(reg::SR, Width::Word, m) & sr::BSY != 0 {
        m.now += 1_000;
    }
    f.read(reg::SR, Width::Word, m) & (sr::PGSERR | sr::PGPERR | sr::PGAERR | sr::WRPERR | sr::OPERR)
}

/// `UnlockedFlash::erase(sector)`: one CR modify with STRT, PSIZE x8, SNB, SER, PG clear.
fn hal_erase(f: &mut Flash, m: &mut TestMachine, sector: u32) -> u32 {
    modify_cr(f, m, cr::PSIZE | cr::SNB | cr::PG, cr::STRT | sector << 3 | cr::SER);
    hal_wait(f, m)
}

/// `UnlockedFlash::program(offset, bytes)`: per 128-bit row a CR modify (PSIZE x8, SER clear,
/// PG set), byte writes, wait; PG cleared at the end.
fn hal_program(f: &mut Flash, m: &mut TestMachine, mut offset: usize, data: &[u8]) -> u32 {
    let mut bytes = data.iter();
    loop {
        modify_cr(f, m, cr::PSIZE | cr::SER, cr::PG);
        let mut written = 0;
        for _ in 0..16 - offset % 16 {
            let Some(&b) = bytes.next() else { break };
            f.array_write(offset as u32, Width::Byte, u32::from(b), m);
            offset += 1;
            written += 1;
        }
        let errors = hal_wait(f, m);
        if errors != 0 {
            return errors;
        }
        if written == 0 {
            break;
        }
    }
    modify_cr(f, m, cr::PG, 0);
    0
}

fn hal_lock(f: &mut Flash, m: &mut TestMachine) {
    modify_cr(f, m, 0, cr::LOCK);
}

fn fast() -> Flash {
    Flash::new().with_timing(FlashTiming::FAST)
}

#[test]
fn reset_values() {
    let mut m = TestMachine::default();
    let mut f = fast();
    assert_eq!(f.read(reg::ACR, Width::Word, &mut m), 0);
    assert_eq!(f.read(reg::CR, Width::Word, &mut m), 0x8000_0000);
    assert_eq!(f.read(reg::SR, Width::Word, &mut m), 0);
    assert_eq!(f.read(reg::OPTCR, Width::Word, &mut m), 0x0FFF_AAED);
}

#[rstest]
#[case::sector_0(0, 0x0000_0000, 16 * 1024)]
#[case::sector_3(3, 0x0000_C000, 16 * 1024)]
#[case::sector_4(4, 0x0001_0000, 64 * 1024)]
#[case::sector_5(5, 0x0002_0000, 128 * 1024)]
#[case::sector_10(10, 0x000C_0000, 128 * 1024)]
#[case::sector_11(11, 0x000E_0000, 128 * 1024)]
fn sector_map(#[case] n: u8, #[case] offset: usize, #[case] len: usize) {
    assert_eq!(sector(n), Some((offset, len)));
}

#[test]
fn settings_journal_erase_then_program() {
    let mut m = TestMachine::default();
    let mut image = vec![0x00; ARRAY_SIZE];
    image[SECTOR_10 - 1] = 0x5A;
    let mut f = Flash::from_image(image).unwrap().with_timing(FlashTiming::FAST);
    assert!(hal_unlock(&mut f, &mut m));
    let started = m.now;
    assert_eq!(hal_erase(&mut f, &mut m, 10), 0);
    assert!(m.now - started >= FlashTiming::FAST.erase_128k[0], "BSY for the erase time");
    hal_lock(&mut f, &mut m);
    assert!(f.image()[SECTOR_10..SECTOR_11].iter().all(|&b| b == 0xFF));
    assert_eq!(f.image()[SECTOR_10 - 1], 0x5A, "sector 9 untouched");
    assert_eq!(f.image()[SECTOR_11], 0x00, "sector 11 untouched");

    let record: Vec<u8> = (0..40).collect();
    assert!(hal_unlock(&mut f, &mut m));
    assert_eq!(hal_program(&mut f, &mut m, SECTOR_10 + 10, &record), 0);
    hal_lock(&mut f, &mut m);
    assert_eq!(&f.image()[SECTOR_10 + 10..SECTOR_10 + 50], &record[..]);
    assert_eq!(f.read(reg::CR, Width::Word, &mut m) & (cr::LOCK | cr::PG), cr::LOCK);
    assert!(f.notes().iter().all(|n| *n == FlashNote::Stalled), "{:?}", f.notes());
}

#[test]
fn programming_only_clears_bits() {
    let mut m = TestMachine::default();
    let mut f = fast();
    assert!(hal_unlock(&mut f, &mut m));
    assert_eq!(hal_program(&mut f, &mut m, SECTOR_11, &[0x0F]), 0);
    assert_eq!(hal_program(&mut f, &mut m, SECTOR_11, &[0xF3]), 0);
    assert_eq!(f.image()[SECTOR_11], 0x03);
}

#[test]
fn locked_control_register_ignores_writes() {
    let mut m = TestMachine::default();
    let mut f = fast();
    f.write(reg::CR, Width::Word, cr::PG, &mut m);
    assert_eq!(f.read(reg::CR, Width::Word, &mut m), cr::LOCK);
    f.array_write(SECTOR_11 as u32, Width::Byte, 0, &mut m);
    assert_eq!(f.read(reg::SR, Width::Word, &mut m), sr::PGSERR, "PG is clear: a sequence error");
    assert_eq!(f.image()[SECTOR_11], 0xFF);
    modify_cr(&mut f, &mut m, 0, cr::STRT | cr::SER | 11 << 3);
    assert_eq!(f.read(reg::SR, Width::Word, &mut m) & sr::BSY, 0, "no erase while locked");
}

#[rstest]
#[case::wrong_first_key(&[KEY2])]
#[case::wrong_second_key(&[KEY1, KEY1])]
#[case::key_while_unlocked(&[KEY1, KEY2, KEY1])]
fn wrong_key_is_a_bus_error_and_locks_until_reset(#[case] keys: &[u32]) {
    let mut m = TestMachine::default();
    let mut f = fast();
    for &key in keys {
        f.write(reg::KEYR, Width::Word, key, &mut m);
    }
    assert!(f.take_bus_error());
    assert!(!f.take_bus_error(), "reported once");
    assert!(!hal_unlock(&mut f, &mut m), "locked until reset");
    f.take_bus_error();
    f.reset(ResetKind::System);
    assert!(hal_unlock(&mut f, &mut m));
    assert!(!f.take_bus_error());
}

#[rstest]
#[case::byte_with_x32(2, 0, Width::Byte, sr::PGPERR)]
#[case::word_with_x8(0, 0, Width::Word, sr::PGPERR)]
#[case::x64_without_vpp(3, 0, Width::Word, sr::PGPERR)]
#[case::word_across_a_row(2, 14, Width::Word, sr::PGAERR)]
#[case::half_word_across_a_row(1, 15, Width::Half, sr::PGAERR)]
#[case::word_in_a_row(2, 12, Width::Word, 0)]
fn width_and_alignment(#[case] psize: u32, #[case] at: u32, #[case] width: Width, #[case] error: u32) {
    let mut m = TestMachine::default();
    let mut f = fast();
    assert!(hal_unlock(&mut f, &mut m));
    modify_cr(&mut f, &mut m, cr::PSIZE, psize << 8 | cr::PG);
    f.array_write(SECTOR_11 as u32 + at, width, 0, &mut m);
    assert_eq!(hal_wait(&mut f, &mut m), error);
    let changed = f.image()[SECTOR_11..SECTOR_11 + 32].iter().any(|&b| b != 0xFF);
    assert_eq!(changed, error == 0, "refused writes change nothing");
}

#[test]
fn write_protected_sector_is_refused() {
    let mut m = TestMachine::default();
    let mut f = fast();
    f.write(reg::OPTKEYR, Width::Word, OPTKEY1, &mut m);
    f.write(reg::OPTKEYR, Width::Word, OPTKEY2, &mut m);
    let optcr = f.read(reg::OPTCR, Width::Word, &mut m);
    assert_eq!(optcr & 1, 0, "OPTLOCK clear");
    f.write(reg::OPTCR, Width::Word, optcr & !(1 << (16 + 10)) | 2, &mut m);
    assert!(hal_unlock(&mut f, &mut m));
    assert_eq!(hal_erase(&mut f, &mut m, 10), sr::WRPERR);
    f.write(reg::SR, Width::Word, sr::WRPERR, &mut m);
    assert_eq!(hal_program(&mut f, &mut m, SECTOR_10, &[0]), sr::WRPERR);
    assert_eq!(hal_erase(&mut f, &mut m, 11), sr::WRPERR, "the HAL never clears SR: stale flag");
    f.write(reg::SR, Width::Word, sr::W1C, &mut m);
    assert_eq!(hal_erase(&mut f, &mut m, 11), 0);
}

#[test]
fn missing_sector_is_a_sequence_error() {
    let mut m = TestMachine::default();
    let mut f = fast();
    assert!(hal_unlock(&mut f, &mut m));
    assert_eq!(hal_erase(&mut f, &mut m, 12), sr::PGSERR);
    assert_eq!(f.notes(), [FlashNote::NoSuchSector(12)]);
}

#[test]
fn interrupts_end_of_operation_and_error() {
    let mut m = TestMachine::default();
    let mut f = fast();
    assert!(hal_unlock(&mut f, &mut m));
    modify_cr(&mut f, &mut m, 0, cr::EOPIE | cr::ERRIE);
    modify_cr(&mut f, &mut m, cr::SNB, cr::STRT | cr::SER | 11 << 3);
    assert_eq!(f.read(reg::SR, Width::Word, &mut m), sr::BSY, "EOP at the end, not the start");
    assert_eq!(m.irqs.get(&IRQ), Some(&false));
    m.now = f.next_event().unwrap();
    f.advance(m.now, &mut m);
    assert_eq!(f.read(reg::SR, Width::Word, &mut m), sr::EOP);
    assert_eq!(m.irqs.get(&IRQ), Some(&true));
    f.write(reg::SR, Width::Word, sr::EOP, &mut m);
    assert_eq!(m.irqs.get(&IRQ), Some(&false));
    f.array_write(SECTOR_11 as u32, Width::Byte, 0, &mut m);
    assert_eq!(f.read(reg::SR, Width::Word, &mut m), sr::PGSERR | sr::OPERR);
    assert_eq!(m.irqs.get(&IRQ), Some(&true));
}

#[rstest]
#[case::hsi_16mhz(VoltageRange::V27To36, 16_000_000, 0)]
#[case::at_30mhz(VoltageRange::V27To36, 30_000_000, 0)]
#[case::above_30mhz(VoltageRange::V27To36, 30_000_001, 1)]
#[case::board_168mhz(VoltageRange::V27To36, 168_000_000, 5)]
#[case::low_voltage_144mhz(VoltageRange::V24To27, 144_000_000, 5)]
#[case::lowest_voltage_160mhz(VoltageRange::V18To21, 160_000_000, 7)]
fn wait_states_of_table_10(#[case] range: VoltageRange, #[case] hclk: u32, #[case] ws: u32) {
    assert_eq!(range.required_latency(hclk), ws);
}

/// `Rcc::flash_setup` of the HAL writes LATENCY = (sysclk - 1) / 30 MHz with the caches on
/// before switching to 168 MHz; a read at 168 MHz with 0 wait states is flagged.
#[rstest]
#[case::hal_setting(5, None)]
#[case::too_few(4, Some(FlashNote::LatencyTooLow { hclk: 168_000_000, latency: 4 }))]
fn latency_against_hclk(#[case] latency: u32, #[case] note: Option<FlashNote>) {
    let clocks = Clocks { sysclk: 168_000_000, hclk: 168_000_000, pclk1: 42_000_000, pclk2: 84_000_000 };
    let mut m = TestMachine { clocks: Some(clocks), ..Default::default() };
    let mut f = fast();
    let acr = f.read(reg::ACR, Width::Word, &mut m);
    f.write(reg::ACR, Width::Word, acr | latency | 0x700, &mut m);
    assert_eq!(f.read(reg::ACR, Width::Word, &mut m), latency | 0x700);
    assert_eq!(f.array_read(0, Width::Word, &mut m), 0xFFFF_FFFF);
    assert_eq!(f.notes().first().copied(), note);
}

#[rstest]
#[case::erase_not_started(CutKind::Before, 0x00, 0x00)]
#[case::erase_torn(CutKind::Torn, 0xFF, 0x00)]
fn power_cut_during_erase(#[case] kind: CutKind, #[case] first: u8, #[case] last: u8) {
    let mut m = TestMachine::default();
    let mut f = Flash::from_image(vec![0; ARRAY_SIZE]).unwrap().with_timing(FlashTiming::FAST);
    f.plan_power_cut(0, kind);
    assert!(hal_unlock(&mut f, &mut m));
    let _ = hal_erase(&mut f, &mut m, 11);
    assert_eq!(f.power_cut(), Some(PowerCut { operation: 0, kind, at: 0 }));
    assert_eq!((f.image()[SECTOR_11], f.image()[ARRAY_SIZE - 1]), (first, last));
    let before = f.image().to_vec();
    let _ = hal_program(&mut f, &mut m, SECTOR_11, &[0]);
    assert_eq!(f.image(), &before[..], "nothing after the cut");
    let again = Flash::from_image(f.image().to_vec()).unwrap();
    assert_eq!(again.image(), &before[..], "the contents survive the power cycle");
    assert!(again.is_locked() && again.power_cut().is_none());
}

#[rstest]
#[case::program_not_started(CutKind::Before, 0xFF)]
#[case::program_torn(CutKind::Torn, 0xF0)]
fn power_cut_during_program(#[case] kind: CutKind, #[case] byte: u8) {
    let mut m = TestMachine::default();
    let mut f = fast();
    assert!(hal_unlock(&mut f, &mut m));
    assert_eq!(hal_program(&mut f, &mut m, SECTOR_10, &[0x11, 0x22]), 0);
    assert_eq!(f.operations(), 2);
    f.plan_power_cut(3, kind);
    let _ = hal_program(&mut f, &mut m, SECTOR_10 + 2, &[0x33, 0x00, 0x44]);
    assert_eq!(&f.image()[SECTOR_10..SECTOR_10 + 5], &[0x11, 0x22, 0x33, byte, 0xFF]);
    assert_eq!(f.power_cut().map(|c| c.operation), Some(3));
}

#[test]
fn back_to_back_writes_stall_the_bus() {
    let mut m = TestMachine::default();
    let mut f = fast();
    assert!(hal_unlock(&mut f, &mut m));
    modify_cr(&mut f, &mut m, cr::PSIZE, cr::PG);
    f.array_write(SECTOR_10 as u32, Width::Byte, 1, &mut m);
    f.array_write(SECTOR_10 as u32 + 1, Width::Byte, 2, &mut m);
    assert_eq!(f.take_stall(), FlashTiming::FAST.program);
    assert_eq!(f.take_stall(), 0);
    assert_eq!(f.next_event(), Some(2 * FlashTiming::FAST.program));
}

#[test]
fn image_must_be_the_array_size() {
    assert_eq!(Flash::from_image(vec![0; 10]).unwrap_err(), WrongImageSize(10));
    let mut f = Flash::new();
    f.load(0, &[1, 2, 3]);
    assert_eq!(&f.image()[..4], &[1, 2, 3, 0xFF]);
}

/// OPTKEYR's sequence, then OPTCR = `optcr` (with OPTSTRT when `start`), as the HAL's
/// `flash::unlock_option_bytes` and a write of FLASH_OPTCR do.
fn write_options(f: &mut Flash, m: &mut TestMachine, options: OptionBytes, start: bool) {
    f.write(reg::OPTKEYR, Width::Word, OPTKEY1, m);
    f.write(reg::OPTKEYR, Width::Word, OPTKEY2, m);
    f.write(reg::OPTCR, Width::Word, options.optcr() | if start { 2 } else { 0 }, m);
}

#[test]
fn write_protection_of_sector_0_survives_a_power_cycle() {
    let mut m = TestMachine::default();
    let mut f = fast();
    let protect_0 = OptionBytes::FACTORY.with_write_protection(0, true);
    write_options(&mut f, &mut m, protect_0, true);
    // A power cycle: a new model from what the old one kept.
    let mut f = Flash::from_image(f.image().to_vec()).unwrap().with_timing(FlashTiming::FAST);
    assert_eq!(f.read(reg::OPTCR, Width::Word, &mut m), 0x0FFF_AAED, "a fresh model: factory options");
    f = f.with_option_bytes(protect_0);
    assert_eq!(f.read(reg::OPTCR, Width::Word, &mut m), 0x0FFE_AAED, "nWRP0 clear, OPTLOCK set");
    assert!(hal_unlock(&mut f, &mut m));
    assert_eq!(hal_erase(&mut f, &mut m, 0), sr::WRPERR);
    f.write(reg::SR, Width::Word, sr::W1C, &mut m);
    assert_eq!(hal_program(&mut f, &mut m, 0x100, &[0]), sr::WRPERR);
    assert_eq!(f.image()[0x100], 0xFF);
    f.write(reg::SR, Width::Word, sr::W1C, &mut m);
    assert_eq!(hal_erase(&mut f, &mut m, 1), 0, "sector 1 is not protected");
    assert_eq!(hal_program(&mut f, &mut m, 0x4000, &[0x5A]), 0);
    assert_eq!(f.image()[0x4000], 0x5A);
}

#[rstest]
#[case::programmed(true, true)]
#[case::written_without_optstrt(false, false)]
fn optcr_reloads_the_option_bytes_at_reset(#[case] start: bool, #[case] protected: bool) {
    let mut m = TestMachine::default();
    let mut f = fast();
    write_options(&mut f, &mut m, OptionBytes::FACTORY.with_write_protection(10, true), start);
    assert!(hal_unlock(&mut f, &mut m));
    let error = if protected { sr::WRPERR } else { 0 };
    assert_eq!(hal_erase(&mut f, &mut m, 10), error, "protection in force: the option bytes'");
    for kind in [ResetKind::System, ResetKind::PowerOn] {
        f.reset(kind);
        let optcr = f.read(reg::OPTCR, Width::Word, &mut m);
        assert_eq!(optcr >> 26 & 1 == 0, protected, "{kind:?}: OPTCR {optcr:#010x}");
        assert_eq!(optcr & 1, 1, "locked again");
    }
    assert_eq!(f.option_bytes().write_protected(10), protected);
}

#[test]
fn mass_erase_with_a_protected_sector_is_refused() {
    let mut m = TestMachine::default();
    let mut f = Flash::from_image(vec![0; ARRAY_SIZE]).unwrap().with_timing(FlashTiming::FAST);
    write_options(&mut f, &mut m, OptionBytes::FACTORY.with_write_protection(0, true), true);
    assert!(hal_unlock(&mut f, &mut m));
    modify_cr(&mut f, &mut m, cr::PSIZE, cr::MER | cr::STRT | 2 << 8);
    assert_eq!(hal_wait(&mut f, &mut m), sr::WRPERR);
    assert!(f.image().iter().all(|&b| b == 0), "nothing erased");
}

#[test]
fn option_bytes_fields() {
    let factory = OptionBytes::FACTORY;
    assert_eq!((factory.read_protection(), factory.read_protection_level_0()), (0xAA, true));
    assert!(!factory.hardware_watchdog());
    assert!(OptionBytes::from_optcr(factory.optcr() & !(1 << 5)).hardware_watchdog(), "WDG_SW clear");
    assert_eq!(
        OptionBytes::from_optcr(0xFFFF_FFFF).optcr(),
        0x0FFF_FFEC,
        "control and reserved bits dropped"
    );
    assert!(!factory.with_write_protection(12, true).write_protected(12), "no sector 12 bit");
}

/// The STM32F446RE's 512 KiB (RM0390 §3.3: sectors 0–7).
#[rstest]
#[case::sector_7(7, 0)]
#[case::sector_8(8, sr::PGSERR)]
#[case::sector_11(11, sr::PGSERR)]
fn f446_has_sectors_0_to_7(#[case] sector: u32, #[case] error: u32) {
    let mut m = TestMachine::default();
    let mut f = fast().with_size(ArraySize::Kib512);
    assert!(hal_unlock(&mut f, &mut m));
    assert_eq!(hal_erase(&mut f, &mut m, sector), error);
    assert_eq!(f.notes().contains(&FlashNote::NoSuchSector(sector as u8)), error != 0);
}

#[test]
fn f446_program_past_512_kib_is_a_bus_error() {
    let mut m = TestMachine::default();
    let mut f = fast().with_size(ArraySize::Kib512);
    assert!(hal_unlock(&mut f, &mut m));
    modify_cr(&mut f, &mut m, cr::PSIZE, cr::PG);
    f.array_write(0x8_0000, Width::Byte, 0, &mut m);
    assert!(f.take_bus_error());
    assert_eq!((f.image()[0x8_0000], f.operations()), (0xFF, 0));
    f.array_write(0x7_FFFF, Width::Byte, 0, &mut m);
    assert!(!f.take_bus_error());
    assert_eq!(f.image()[0x7_FFFF], 0);
}
