//! Register facts of the independent watchdog (RM0090 §21), driven as stm32f4xx-hal's
//! `IndependentWatchdog` drives it (`start`: 0x5555, PR, RLR, wait for SR 0, 0xAAAA, 0xCCCC;
//! `feed`: 0xAAAA).

use super::*;
use crate::periph::{ClockGate, Clocks};
use rstest::rstest;

/// A machine with a settable time that records the resets asked of it.
#[derive(Default)]
struct ResetMachine {
    now: Nanos,
    resets: Vec<(Nanos, ResetCause)>,
}

impl Machine for ResetMachine {
    fn clocks(&self) -> Clocks {
        Clocks::RESET
    }
    fn clock_enabled(&self, _: ClockGate) -> bool {
        true
    }
    fn set_irq(&mut self, _: u16, _: bool) {}
    fn now(&self) -> Nanos {
        self.now
    }
    fn system_reset(&mut self, cause: ResetCause) {
        self.resets.push((self.now, cause));
    }
}

const MS: Nanos = 1_000_000;

/// The HAL's `start` with `pr` and `rlr`: 0x5555, PR, RLR, 0xAAAA, 0xCCCC, no wait for SR.
fn start(w: &mut Iwdg, m: &mut ResetMachine, pr: u32, rlr: u32) {
    w.write(reg::KR, Width::Word, key::ACCESS, m);
    w.write(reg::PR, Width::Word, pr, m);
    w.write(reg::RLR, Width::Word, rlr, m);
    w.write(reg::KR, Width::Word, key::RELOAD, m);
    w.write(reg::KR, Width::Word, key::START, m);
}

/// Advances to `at`, in 1 ms steps as the machine's slices would, and returns the resets.
fn run_to(w: &mut Iwdg, m: &mut ResetMachine, at: Nanos) -> Vec<(Nanos, ResetCause)> {
    while m.now < at {
        m.now = (m.now + MS).min(at);
        w.advance(m.now, m);
    }
    m.resets.clone()
}

#[rstest]
// RM0090 table 107 at 32 kHz: (RL + 1) × prescaler / 32 kHz.
#[case::div4_min(0, 0, 125_000)]
#[case::div4_max(0, 0xFFF, 512 * MS)]
#[case::div32_max(3, 0xFFF, 4_096 * MS)]
#[case::div256_min(6, 0, 8 * MS)]
#[case::pr7_is_div256_too(7, 0, 8 * MS)]
#[case::div64_1000(4, 999, 2_000 * MS)]
fn the_timeout_is_table_107s(#[case] pr: u32, #[case] rlr: u32, #[case] timeout: Nanos) {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new();
    start(&mut w, m, pr, rlr);
    assert_eq!(w.reset_at(), Some(timeout));
    w.advance(timeout - 1, m);
    assert!(m.resets.is_empty(), "not before the timeout");
    m.now = timeout;
    w.advance(timeout, m);
    assert_eq!(m.resets, [(timeout, ResetCause::IndependentWatchdog)]);
}

#[test]
fn a_program_that_never_feeds_is_reset_once_and_one_that_feeds_is_not() {
    // PR 1 (/8), RLR 399: 400 × 8 / 32 kHz = 100 ms.
    let m = &mut ResetMachine::default();
    let mut fed = Iwdg::new();
    start(&mut fed, m, 1, 399);
    while m.now < 1_000 * MS {
        let next = m.now + 50 * MS;
        run_to(&mut fed, m, next);
        fed.write(reg::KR, Width::Word, key::RELOAD, m);
    }
    assert!(m.resets.is_empty(), "fed every 50 ms: no reset, {:?}", m.resets);

    let m = &mut ResetMachine::default();
    let mut starved = Iwdg::new();
    start(&mut starved, m, 1, 399);
    assert_eq!(run_to(&mut starved, m, 1_000 * MS), [(100 * MS, ResetCause::IndependentWatchdog)], "once");
    assert_eq!(starved.watchdog_resets(), 1);
}

#[test]
fn started_without_a_reload_it_counts_from_0xfff() {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new();
    w.write(reg::KR, Width::Word, key::ACCESS, m);
    w.write(reg::RLR, Width::Word, 10, m);
    w.write(reg::KR, Width::Word, key::START, m);
    assert_eq!(w.counter(), 0xFFF);
    assert_eq!(w.reset_at(), Some(512 * MS));
    m.now = 100 * MS;
    w.advance(m.now, m);
    assert_eq!(w.counter(), 0xFFF - 800, "one count per 125 µs");
}

#[test]
fn no_key_stops_it_and_a_reset_does() {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new();
    start(&mut w, m, 0, 0xFFF);
    for value in [0, 0x5555, 0x1234, 0xCCCC] {
        w.write(reg::KR, Width::Word, value, m);
    }
    assert!(w.running());
    w.reset(ResetKind::System);
    assert!(!w.running(), "a software-started watchdog is stopped by a reset");
    assert_eq!(w.next_event(), None);
    assert_eq!(run_to(&mut w, m, 2_000 * MS), []);
}

#[rstest]
#[case::system(ResetKind::System)]
#[case::power_on(ResetKind::PowerOn)]
fn the_hardware_watchdog_runs_from_every_reset(#[case] kind: ResetKind) {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new().with_hardware_watchdog();
    assert!(w.running());
    m.now = 300 * MS;
    w.advance(m.now, m);
    w.reset(kind);
    assert_eq!(w.reset_at(), Some(300 * MS + 512 * MS), "from 0xFFF at /4 again");
}

#[test]
fn pr_and_rlr_need_the_access_key_and_lose_it_to_any_other() {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new();
    w.write(reg::PR, Width::Word, 3, m);
    w.write(reg::RLR, Width::Word, 7, m);
    assert_eq!((w.read(reg::PR, Width::Word, m), w.read(reg::RLR, Width::Word, m)), (0, 0xFFF));
    w.write(reg::KR, Width::Word, key::ACCESS, m);
    w.write(reg::KR, Width::Word, key::RELOAD, m);
    w.write(reg::PR, Width::Word, 3, m);
    assert_eq!(w.read(reg::PR, Width::Word, m), 0, "0xAAAA protects them again (§21.3.2)");
    w.write(reg::KR, Width::Word, key::ACCESS, m);
    w.write(reg::PR, Width::Word, 0xFF, m);
    w.write(reg::RLR, Width::Word, 0xFFFF, m);
    assert_eq!(
        (w.read(reg::PR, Width::Word, m), w.read(reg::RLR, Width::Word, m)),
        (7, 0xFFF),
        "field widths"
    );
}

#[test]
fn pvu_and_rvu_stay_set_for_five_lsi_cycles_and_block_a_second_write() {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new();
    w.write(reg::KR, Width::Word, key::ACCESS, m);
    w.write(reg::PR, Width::Word, 2, m);
    w.write(reg::RLR, Width::Word, 100, m);
    assert_eq!(w.read(reg::SR, Width::Word, m), sr::PVU | sr::RVU);
    w.write(reg::PR, Width::Word, 5, m);
    w.write(reg::RLR, Width::Word, 200, m);
    assert_eq!((w.read(reg::PR, Width::Word, m), w.read(reg::RLR, Width::Word, m)), (2, 100));
    // 5 cycles at 32 kHz: 156.25 µs.
    m.now = 156_249;
    assert_eq!(w.read(reg::SR, Width::Word, m), sr::PVU | sr::RVU);
    assert_eq!(w.next_event(), Some(156_250));
    m.now = 156_250;
    assert_eq!(w.read(reg::SR, Width::Word, m), 0);
}

#[test]
fn the_lsi_frequency_scales_the_timeout() {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new().with_lsi_hz(40_000);
    w.write(reg::KR, Width::Word, key::START, m);
    // 4096 × 4 / 40 kHz = 409.6 ms.
    assert_eq!(w.reset_at(), Some(409_600_000));
}

#[test]
fn a_half_word_key_write_starts_it() {
    let m = &mut ResetMachine::default();
    let mut w = Iwdg::new();
    w.write(reg::KR, Width::Half, key::START, m);
    assert!(w.running());
    assert_eq!(w.read(reg::KR, Width::Word, m), 0, "KR reads 0");
}
