//! Per-unit health and the data-valid bits, driven through the master by the test slave.

use super::*;
use crate::serial::modbus::{UnitRow, UnitState};

/// 0: unit 1 holding 0..2 → input 0..4; 1: unit 2 holding 5 → input 4..6;
/// 2: unit 1 registers 10..12 ← output 0..4; data-valid bits at input byte 6.
fn two_units() -> ModbusConfig {
    let scan = Vec::from_slice(&[
        entry(1, Function::ReadHoldingRegisters, 0, 2, 0),
        entry(2, Function::ReadHoldingRegisters, 5, 1, 4),
        entry(1, Function::WriteMultipleRegisters, 10, 2, 0),
    ])
    .unwrap();
    let mut c = ModbusConfig::new(scan);
    c.serial = SerialSettings::new_8e1(38400);
    c.response_timeout_ms = 100;
    c.retries = 2;
    c.poll_period_ms = 500;
    c.input_len = 7;
    c.valid_bits_offset = Some(6);
    c.health.stale_timeout_ms = 2000;
    c
}

/// [`run`], with unit `mute` not answering.
fn run_muted(m: &mut ModbusMaster, slave: &mut Slave, mute: u8, now: &mut Instant, until: Instant) {
    run_unless(m, slave, Some(mute), now, until);
}

fn row(m: &ModbusMaster, r: usize, now: Instant) -> UnitRow {
    m.unit_row(r, now).unwrap()
}

#[test]
fn one_row_per_distinct_unit_in_scan_order() {
    let m = master(two_units());
    assert_eq!(m.units().len(), 2);
    assert_eq!((row(&m, 0, ms(0)).unit, row(&m, 1, ms(0)).unit), (1, 2));
    assert_eq!(m.unit_row(2, ms(0)), None);
    let r = row(&m, 0, ms(0));
    assert_eq!(
        (r.state, r.lost_data, r.retries, r.exceptions, r.since_answer_ms),
        (UnitState::Starting, 0, 0, 0, None)
    );
    assert_eq!(m.input_image()[6], 0, "no bit before an answer");
}

#[test]
fn answered_reads_and_writes_set_their_bits() {
    let mut m = master(two_units());
    let mut s = Slave::default();
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(100));
    assert_eq!(m.input_image()[6], 0b011, "both reads; the write not sent yet");
    m.set_outputs(&[1, 2, 3, 4], now);
    run(&mut m, &mut s, &mut now, ms(200));
    assert_eq!(m.input_image()[6], 0b111);
    assert_eq!(m.units().valid_bits(), 0b111);
    let r = row(&m, 1, ms(200));
    assert_eq!(r.state, UnitState::Ok);
    assert!(r.since_answer_ms.is_some_and(|t| t < 200), "{r:?}");
}

#[test]
fn a_silent_unit_loses_its_bits_and_counts_for_itself_only() {
    let mut m = master(two_units());
    let mut s = Slave::default();
    let mut now = ms(0);
    m.set_outputs(&[1, 2, 3, 4], now);
    run(&mut m, &mut s, &mut now, ms(400));
    assert_eq!(m.input_image()[6], 0b111);
    // Unit 2 stops answering: one read per cycle, each tried 1 + 2 times.
    run_muted(&mut m, &mut s, 2, &mut now, ms(1900));
    assert_eq!(m.input_image()[6], 0b101, "unit 2's read bit cleared, unit 1's read and write kept");
    let (one, two) = (row(&m, 0, now), row(&m, 1, now));
    assert_eq!((one.state, one.lost_data, one.retries), (UnitState::Ok, 0, 0));
    assert_eq!(two.state, UnitState::Lost);
    // Cycles at 500, 1000, 1500 ms (and the one at 0 answered).
    assert_eq!((two.lost_data, two.retries), (3, 6));
    assert_eq!(m.stats().commands_retried, 0, "reads are not commands");
    // Unit 2 answers again: its bit comes back, its counters stay.
    run(&mut m, &mut s, &mut now, ms(2100));
    assert_eq!(m.input_image()[6], 0b111);
    let two = row(&m, 1, now);
    assert_eq!((two.state, two.lost_data, two.retries), (UnitState::Ok, 3, 6));
}

#[test]
fn a_retry_that_succeeds_counts_a_retry_but_no_lost_data() {
    let mut m = master(two_units());
    let mut s = Slave { corrupt_next: true, ..Slave::default() };
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(300));
    let r = row(&m, 0, now);
    assert_eq!((r.state, r.retries, r.lost_data), (UnitState::Ok, 1, 0));
    assert_eq!(m.input_image()[6], 0b011);
}

#[test]
fn an_exception_clears_the_bit_and_counts_for_the_unit() {
    let mut m = master(two_units());
    let mut s = Slave::default();
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(400));
    s.exception = Some(ExceptionCode::IllegalDataAddress);
    run(&mut m, &mut s, &mut now, ms(600));
    assert_eq!(m.input_image()[6], 0);
    for r in 0..2 {
        let u = row(&m, r, now);
        assert_eq!((u.state, u.exceptions, u.lost_data), (UnitState::Exception, 1, 0), "{u:?}");
    }
}

#[test]
fn bits_run_out_after_the_stale_timeout_without_a_read() {
    let mut c = two_units();
    // A cycle every 10 s: the bits of one cycle's reads run out after 2 s.
    c.poll_period_ms = 10_000;
    let mut m = master(c);
    let mut s = Slave::default();
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(1000));
    assert_eq!(m.input_image()[6], 0b011);
    assert!(m.poll_at().is_some_and(|t| t <= ms(2100)), "the master wakes for the bits");
    run(&mut m, &mut s, &mut now, ms(2500));
    assert_eq!(m.input_image()[6], 0);
    assert_eq!(row(&m, 0, now).state, UnitState::Lost, "no answer within the stale timeout");
}

#[test]
fn without_the_key_the_image_is_untouched() {
    let mut c = two_units();
    c.valid_bits_offset = None;
    let mut m = master(c);
    let mut s = Slave::default();
    s.holding[2][5] = 0x0102;
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(100));
    assert_eq!(m.input_image(), &[0, 0, 0, 0, 0x02, 0x01, 0]);
    assert_eq!(m.units().valid_bits(), 0b011, "the table still runs");
}

#[test]
fn nine_entries_take_two_bytes_of_bits() {
    // Nine reads of one register each: bits in two bytes.
    let scan: Vec<ScanEntry, SCAN_LIST_CAPACITY> =
        (0..9).map(|k| entry(1 + k as u8 % 2, Function::ReadHoldingRegisters, 0, 1, 2 * k)).collect();
    let mut c = ModbusConfig::new(scan);
    c.input_len = 20;
    c.valid_bits_offset = Some(18);
    let mut m = master(c);
    assert_eq!(m.units().len(), 2);
    let mut s = Slave::default();
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(100));
    assert_eq!(&m.input_image()[18..], &[0xFF, 0x01]);
}

#[rstest]
#[case::past_the_image(|c: &mut ModbusConfig| c.valid_bits_offset = Some(7), "valid_bits_offset: 7 is outside the allowed range 0..=6")]
#[case::over_a_read(|c: &mut ModbusConfig| c.valid_bits_offset = Some(5), "valid_bits_offset: overlaps the image bytes of entry 1")]
#[case::image_too_short(|c: &mut ModbusConfig| { c.input_len = 0; c.scan.truncate(0); c.scan.push(entry(1, Function::WriteSingleCoil, 0, 1, 0)).unwrap(); }, "input_len: 0 is outside the allowed range 1..=64")]
fn validation_names_the_key(#[case] f: fn(&mut ModbusConfig), #[case] message: &str) {
    let mut c = two_units();
    f(&mut c);
    assert_eq!(c.validate().unwrap_err().to_string(), message);
}
