//! Register facts of the USART, driven as `board::hw::Usart` drives it (open: BRR, CR2, CR1
//! written once after the RCC enable and reset; `try_write`: SR read, DR write; `read`: SR read,
//! DR read until no flag is left; `is_transmission_complete`: SR.TC), with the register values of
//! `board::uart::LineFormat::registers`.

use super::*;
use crate::gpio::tests::TestMachine;
use crate::periph::Clocks;
use rstest::rstest;

/// The real board's clocks: USART2 on PCLK1 = 42 MHz, USART1 on PCLK2 = 84 MHz.
const BOARD: Clocks = Clocks { sysclk: 168_000_000, hclk: 168_000_000, pclk1: 42_000_000, pclk2: 84_000_000 };

fn machine() -> TestMachine {
    TestMachine { clocks: Some(BOARD), ..Default::default() }
}

/// `board::uart::LineFormat::registers`: (BRR, CR1, CR2) for `baud` from `clock`, rounded to
/// the nearest divider step, 8× oversampling above a sixteenth of the clock.
fn board_registers(clock: u32, baud: u32, word: (u8, Parity), stop: StopBits) -> (u32, u32, u32) {
    let m = match word {
        (8, Parity::Even | Parity::Odd) => cr1::M,
        _ => 0,
    };
    let parity = match word.1 {
        Parity::None => 0,
        Parity::Even => cr1::PCE,
        Parity::Odd => cr1::PCE | cr1::PS,
    };
    let cr2 = if stop == StopBits::Two { 0b10 << 12 } else { 0 };
    let over8 = baud > clock / 16;
    let div = ((clock << u32::from(over8)) + baud / 2) / baud;
    let brr = if over8 { div & !0xF | (div & 0xF) >> 1 } else { div };
    let over8 = if over8 { cr1::OVER8 } else { 0 };
    (brr, cr1::UE | cr1::TE | cr1::RE | over8 | m | parity, cr2)
}

fn open(u: &mut Usart, m: &mut TestMachine, (brr, cr1, cr2): (u32, u32, u32)) {
    u.write(reg::BRR, Width::Word, brr, m);
    u.write(reg::CR2, Width::Word, cr2, m);
    u.write(reg::CR1, Width::Word, cr1, m);
}

fn try_write(u: &mut Usart, m: &mut TestMachine, byte: u8) -> bool {
    let empty = u.read(reg::SR, Width::Word, m) & sr::TXE != 0;
    if empty {
        u.write(reg::DR, Width::Word, u32::from(byte), m);
    }
    empty
}

/// `board::hw::Usart::read`: a character without error, dropping those with one.
fn board_read(u: &mut Usart, m: &mut TestMachine) -> Option<u8> {
    loop {
        let status = u.read(reg::SR, Width::Word, m);
        if status & (sr::PE | sr::FE | sr::NF | sr::ORE | sr::RXNE) == 0 {
            return None;
        }
        let byte = u.read(reg::DR, Width::Word, m) as u8;
        if status & (sr::PE | sr::FE | sr::NF | sr::ORE) == 0 {
            return Some(byte);
        }
    }
}

fn settings(baud: f64, word_bits: u8, parity: Parity, stop_bits: StopBits) -> LineSettings {
    LineSettings { baud, word_bits, parity, stop_bits }
}

#[test]
fn reset_values() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    let regs = [(reg::SR, 0xC0), (reg::DR, 0), (reg::BRR, 0), (reg::CR1, 0), (reg::CR2, 0), (reg::CR3, 0)];
    for (offset, value) in regs {
        assert_eq!(u.read(offset, Width::Word, &mut m), value, "offset {offset:#x}");
    }
}

#[rstest]
#[case::usart1(UsartId::Usart1, 0x4001_1000, 37, ClockGate::Apb2(4))]
#[case::usart2(UsartId::Usart2, 0x4000_4400, 38, ClockGate::Apb1(17))]
#[case::usart6(UsartId::Usart6, 0x4001_1400, 71, ClockGate::Apb2(5))]
fn instances(#[case] id: UsartId, #[case] base: u32, #[case] irq: u16, #[case] gate: ClockGate) {
    assert_eq!((id.base(), id.irq(), id.clock_gate()), (base, irq, gate));
}

/// BRR against RM0090 §30.3.4: with OVER8 = 0 baud = f / BRR; with OVER8 = 1 the fraction has
/// three bits (bit 3 ignored) and baud = f / (8 × mantissa + fraction).
#[rstest]
#[case::x16_19200_at_42mhz(0x88C, false, 42_000_000, 42e6 / 2188.0)]
#[case::x16_115200_at_84mhz(0x2D9, false, 84_000_000, 84e6 / 729.0)]
#[case::x8_fraction(0x12, true, 16_000_000, 16e6 / 10.0)]
#[case::x8_fraction_bit_3_ignored(0x1A, true, 16_000_000, 16e6 / 10.0)]
#[case::zero(0, false, 16_000_000, 0.0)]
fn baud_from_brr(#[case] brr: u32, #[case] over8: bool, #[case] fck: u32, #[case] baud: f64) {
    let mut m = TestMachine {
        clocks: Some(Clocks { sysclk: fck, hclk: fck, pclk1: fck, pclk2: fck }),
        ..Default::default()
    };
    let mut u = Usart::new(UsartId::Usart2);
    u.write(reg::BRR, Width::Word, brr, &mut m);
    u.write(reg::CR1, Width::Word, if over8 { cr1::OVER8 } else { 0 }, &mut m);
    assert!((u.baud() - baud).abs() < 1e-6, "{} vs {baud}", u.baud());
}

/// The instrument port opened with the serial profile's format, bytes written as the firmware
/// writes them: an idle frame first (TE), then each character after the last, TC at the end.
#[rstest]
#[case::b9600_8n1(9600, (8, Parity::None), StopBits::One, 10.0)]
#[case::b19200_8e1(19200, (8, Parity::Even), StopBits::One, 11.0)]
#[case::b19200_7o2(19200, (7, Parity::Odd), StopBits::Two, 11.0)]
#[case::b115200_8n2(115_200, (8, Parity::None), StopBits::Two, 11.0)]
fn transmits_with_the_configured_format(
    #[case] baud: u32,
    #[case] word: (u8, Parity),
    #[case] stop: StopBits,
    #[case] frame_bits: f64,
) {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    open(&mut u, &mut m, board_registers(42_000_000, baud, word, stop));
    let frame = (frame_bits * 1e9 / u.baud()).round() as u64;
    assert!((u.baud() / f64::from(baud) - 1.0).abs() < 0.005, "the divider's rounding");
    let mut sent = Vec::new();
    for byte in [0x41u8, 0x7E] {
        while !try_write(&mut u, &mut m, byte) {
            m.now += 1_000;
        }
    }
    while u.read(reg::SR, Width::Word, &mut m) & sr::TC == 0 {
        m.now += 1_000;
    }
    while let Some(t) = u.pop_transmitted() {
        sent.push(t);
    }
    assert_eq!(sent.len(), 2);
    assert_eq!(sent[0].end, 2 * frame, "one idle frame, then the first character");
    assert_eq!(sent[1].end, 3 * frame, "back to back");
    let data_bits = word.0;
    for (t, byte) in sent.iter().zip([0x41u16, 0x7E]) {
        assert_eq!(t.character.data(), byte & ((1 << data_bits) - 1));
        assert_eq!(t.character.settings.data_bits(), data_bits);
        assert_eq!(t.character.settings.parity, word.1);
        assert_eq!(t.character.settings.stop_bits, stop);
        assert!(line::parity_ok(t.character.word, t.character.settings.word_bits, word.1));
    }
}

#[test]
fn tc_cleared_by_sr_read_then_dr_write_or_by_writing_zero() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    open(&mut u, &mut m, board_registers(42_000_000, 19200, (8, Parity::None), StopBits::One));
    assert!(try_write(&mut u, &mut m, 1));
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & sr::TC, 0, "the sequence cleared TC");
    m.now += 10_000_000;
    assert_ne!(u.read(reg::SR, Width::Word, &mut m) & sr::TC, 0);
    u.write(reg::SR, Width::Word, !sr::TC, &mut m);
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::TC | sr::TXE), sr::TXE, "TXE ignores writes");
}

/// A character from a sender at the same rate and format arrives whole; with the sender's
/// rate off by more than the tolerance of RM0090 §30.3.5, it is garbled.
#[rstest]
#[case::same_rate(1.0, 0x55, Some(0x55))]
#[case::sender_3_percent_fast(1.03, 0x55, Some(0x55))]
#[case::sender_3_percent_slow(0.97, 0xA6, Some(0xA6))]
#[case::sender_5_percent_fast(1.05, 0x55, Some(0x95))]
#[case::sender_5_percent_slow_framing_error(0.95, 0x55, None)]
#[case::half_rate(0.5, 0x55, None)]
#[case::double_rate(2.0, 0x0F, Some(0xF9))]
fn rate_mismatch(#[case] ratio: f64, #[case] sent: u16, #[case] got: Option<u8>) {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    open(&mut u, &mut m, board_registers(42_000_000, 19200, (8, Parity::None), StopBits::One));
    let sender = LineSettings::new_8n1(u.baud() * ratio);
    u.receive(Character::encode(sent, sender), m.now);
    m.now += sender.frame_ns();
    assert_ne!(u.read(reg::SR, Width::Word, &mut m) & sr::RXNE, 0);
    assert_eq!(board_read(&mut u, &mut m), got);
}

#[rstest]
#[case::m0_x16(false, 8, 0.0375)]
#[case::m1_x16(false, 9, 0.375 / 11.0)]
#[case::m0_x8(true, 8, 0.025)]
#[case::m1_x8(true, 9, 0.25 / 11.0)]
fn tolerance_of_section_30_3_5(#[case] over8: bool, #[case] word_bits: u8, #[case] tolerance: f64) {
    let settings = settings(9600.0, word_bits, Parity::None, StopBits::One);
    let receiver = Receiver { settings, over8, one_bit: false };
    assert!((receiver.tolerance() - tolerance).abs() < 1e-9);
    let inside =
        Character::encode(0x55, LineSettings { baud: 9600.0 * (1.0 + tolerance * 0.99), ..settings });
    assert_eq!(receiver.sample(&inside).word, 0x55);
}

/// Parity and format: a parity mismatch sets PE (with RXNE); a 9-bit word read as 8N1 has its
/// parity bit where the stop bit should be.
#[rstest]
#[case::parity_ok(settings(1.0, 9, Parity::Even, StopBits::One), 0x31, 0, 0x131)]
#[case::odd_sender_even_receiver(settings(1.0, 9, Parity::Odd, StopBits::One), 0x31, sr::PE, 0x031)]
#[case::seven_bit_sender_reads_the_idle_level_as_ninth_bit(
    settings(1.0, 8, Parity::Even, StopBits::One),
    0x31,
    sr::PE,
    0x1B1
)]
fn parity_and_format(#[case] sender: LineSettings, #[case] data: u16, #[case] errors: u32, #[case] dr: u32) {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    open(&mut u, &mut m, board_registers(42_000_000, 19200, (8, Parity::Even), StopBits::One));
    let sender = LineSettings { baud: u.baud(), ..sender };
    u.receive(Character::encode(data, sender), 0);
    m.now = sender.frame_ns();
    let status = u.read(reg::SR, Width::Word, &mut m);
    assert_eq!(status & (sr::PE | sr::FE | sr::RXNE), errors | sr::RXNE);
    assert_eq!(u.read(reg::DR, Width::Word, &mut m), dr, "DR holds the parity bit as its MSB");
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::PE | sr::RXNE), 0, "SR then DR read clears");
}

#[test]
fn nine_bit_sender_into_8n1_is_a_framing_error_when_its_parity_bit_is_low() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart1);
    open(&mut u, &mut m, board_registers(84_000_000, 115_200, (8, Parity::None), StopBits::One));
    let sender = settings(u.baud(), 9, Parity::Even, StopBits::One);
    u.receive(Character::encode(0x03, sender), 0);
    m.now = sender.frame_ns();
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::FE | sr::RXNE), sr::FE | sr::RXNE);
    assert_eq!(u.read(reg::DR, Width::Word, &mut m), 0x03);
}

#[test]
fn overrun_loses_the_new_character() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    open(&mut u, &mut m, board_registers(42_000_000, 19200, (8, Parity::None), StopBits::One));
    u.write(reg::CR1, Width::Word, u.cr1 | cr1::RXNEIE, &mut m);
    let sender = LineSettings::new_8n1(u.baud());
    u.receive(Character::encode(b'a'.into(), sender), 0);
    u.receive(Character::encode(b'b'.into(), sender), 0);
    m.now = 2 * sender.frame_ns();
    let status = u.read(reg::SR, Width::Word, &mut m);
    assert_eq!(status & (sr::ORE | sr::RXNE), sr::ORE | sr::RXNE);
    assert_eq!(m.irqs.get(&38), Some(&true));
    assert_eq!(u.read(reg::DR, Width::Word, &mut m), u32::from(b'a'), "RDR keeps the first");
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::ORE | sr::RXNE), 0);
    assert_eq!(m.irqs.get(&38), Some(&false));
}

#[test]
fn idle_after_a_frame_of_silence() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    open(&mut u, &mut m, board_registers(42_000_000, 19200, (8, Parity::None), StopBits::One));
    let sender = LineSettings::new_8n1(u.baud());
    let frame = sender.frame_ns();
    u.receive(Character::encode(1, sender), 0);
    u.receive(Character::encode(2, sender), frame);
    m.now = frame;
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::IDLE | sr::RXNE), sr::RXNE);
    assert_eq!(u.read(reg::DR, Width::Word, &mut m), 1);
    m.now = 2 * frame;
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::IDLE | sr::RXNE), sr::RXNE, "back to back");
    assert_eq!(u.read(reg::DR, Width::Word, &mut m), 2);
    assert_eq!(u.next_event(), Some(3 * frame));
    m.now = 3 * frame;
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::IDLE | sr::RXNE), sr::IDLE);
    assert_eq!(u.read(reg::DR, Width::Word, &mut m), 2, "DR keeps the last character");
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & sr::IDLE, 0, "SR then DR read clears");
}

#[test]
fn receiver_disabled_drops_characters() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    let (brr, cr1, cr2) = board_registers(42_000_000, 19200, (8, Parity::None), StopBits::One);
    open(&mut u, &mut m, (brr, cr1 & !cr1::RE, cr2));
    u.receive(Character::encode(1, LineSettings::new_8n1(u.baud())), 0);
    m.now = 1_000_000;
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & sr::RXNE, 0);
}

#[rstest]
#[case::txe(cr1::TXEIE, true)]
#[case::tc(cr1::TCIE, true)]
#[case::rxne(cr1::RXNEIE, false)]
#[case::idle(cr1::IDLEIE, false)]
fn interrupt_line_is_enable_and_flag(#[case] enable: u32, #[case] level: bool) {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart1);
    open(&mut u, &mut m, board_registers(84_000_000, 115_200, (8, Parity::None), StopBits::One));
    assert_eq!(m.irqs.get(&37), Some(&false));
    u.write(reg::CR1, Width::Word, u.cr1 | enable, &mut m);
    assert_eq!(m.irqs.get(&37), Some(&level));
}

#[test]
fn cr3_has_no_driver_enable_bit() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    u.write(reg::CR3, Width::Word, 1 << 14 | CR3_ONEBIT, &mut m);
    assert_eq!(u.read(reg::CR3, Width::Word, &mut m), CR3_ONEBIT, "bit 14 (DEM elsewhere) reserved");
}

#[test]
fn unclocked_usart_ignores_writes() {
    let mut m = TestMachine { closed: vec![ClockGate::Apb1(17)], ..machine() };
    let mut u = Usart::new(UsartId::Usart2);
    u.write(reg::BRR, Width::Word, 0x88C, &mut m);
    m.closed.clear();
    assert_eq!(u.read(reg::BRR, Width::Word, &mut m), 0);
}

/// The machine as the USART sees it on the board: clocks and gates from the RCC model.
struct OnRcc<'a> {
    rcc: &'a crate::rcc::Rcc,
    now: Nanos,
}

impl Machine for OnRcc<'_> {
    fn clocks(&self) -> Clocks {
        self.rcc.current_clocks()
    }
    fn clock_enabled(&self, gate: ClockGate) -> bool {
        self.rcc.clock_enabled(gate)
    }
    fn set_irq(&mut self, _irq: u16, _level: bool) {}
    fn now(&self) -> Nanos {
        self.now
    }
}

/// A USART2 divider computed for the board's 42 MHz PCLK1 works once RCC runs the PLL; on the
/// reset clocks (16 MHz HSI) the same BRR makes 2.6 times too slow a line and the instrument
/// gets garbage.
#[rstest]
#[case::clocks_set_up(true, true)]
#[case::clocks_left_at_reset(false, false)]
fn brr_for_the_wrong_clock_garbles(#[case] freeze: bool, #[case] delivered: bool) {
    use crate::rcc::{Hse, Rcc};
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    let rmw = |rcc: &mut Rcc, m: &mut TestMachine, offset: u32, set: u32| {
        let v = rcc.read(offset, Width::Word, m);
        rcc.write(offset, Width::Word, v | set, m);
    };
    if freeze {
        rcc.write(0x04, Width::Word, 0x2000_0000 | 7 << 24 | 1 << 22 | 168 << 6 | 4, &mut m);
        rmw(&mut rcc, &mut m, 0x00, 1 << 16 | 1 << 24);
        m.now += 1_000_000;
        rmw(&mut rcc, &mut m, 0x08, 0b100 << 13 | 0b101 << 10 | 2);
    }
    rmw(&mut rcc, &mut m, 0x40, 1 << 17); // APB1ENR.USART2EN
    m.now += 1_000_000;
    let _ = rcc.read(0x08, Width::Word, &mut m);
    let mut on = OnRcc { rcc: &rcc, now: m.now };
    let mut u = Usart::new(UsartId::Usart2);
    let (brr, cr1, cr2) = board_registers(42_000_000, 19200, (8, Parity::None), StopBits::One);
    u.write(reg::BRR, Width::Word, brr, &mut on);
    u.write(reg::CR2, Width::Word, cr2, &mut on);
    u.write(reg::CR1, Width::Word, cr1, &mut on);
    u.write(reg::DR, Width::Word, u32::from(b'U'), &mut on);
    on.now += 10_000_000;
    let sent = u.read(reg::SR, Width::Word, &mut on);
    assert_ne!(sent & sr::TC, 0);
    let character = u.pop_transmitted().unwrap().character;
    let instrument = Receiver { settings: LineSettings::new_8n1(19200.0), over8: false, one_bit: false };
    let got = instrument.sample(&character);
    let clean = !got.framing_error && !got.parity_error;
    assert_eq!(clean && got.word == u16::from(b'U'), delivered, "{got:?}");
}

/// An error flag stays until its clear sequence: RXNE cleared by writing 0 leaves FE set for
/// the next, clean character (RM0090 §30.6.1).
#[test]
fn error_flags_stay_until_the_sequence() {
    let mut m = machine();
    let mut u = Usart::new(UsartId::Usart2);
    open(&mut u, &mut m, board_registers(42_000_000, 19200, (8, Parity::None), StopBits::One));
    let good = LineSettings::new_8n1(u.baud());
    let slow = LineSettings::new_8n1(u.baud() * 0.9);
    u.receive(Character::encode(0x00, slow), 0);
    m.now = slow.frame_ns();
    assert_ne!(u.read(reg::SR, Width::Word, &mut m) & sr::FE, 0);
    u.write(reg::SR, Width::Word, !sr::RXNE, &mut m);
    u.receive(Character::encode(0x42, good), m.now);
    m.now += good.frame_ns();
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::FE | sr::RXNE), sr::FE | sr::RXNE);
    assert_eq!(board_read(&mut u, &mut m), None, "the firmware drops it: FE still set");
    assert_eq!(u.read(reg::SR, Width::Word, &mut m) & (sr::FE | sr::RXNE), 0);
}
