use super::*;
use crate::serial::modbus::{Function, ModbusConfig, ModbusMaster, WordOrder};
use crate::serial::{SerialSettings, IMAGE_CAPACITY};
use rstest::rstest;
use std::string::ToString;
use std::vec::Vec as StdVec;

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

fn entry(unit: u8, function: Function, address: u16, count: u16, offset: u16) -> ScanEntry {
    ScanEntry {
        unit,
        function,
        address,
        count,
        offset,
        word_order: WordOrder::Registers,
        period_ms: None,
        write: WriteMode::Change,
        trigger_offset: None,
    }
}

fn read(address: u16, offset: u16) -> ScanEntry {
    entry(1, Function::ReadHoldingRegisters, address, 1, offset)
}

fn periodic(address: u16, offset: u16, period_ms: u32) -> ScanEntry {
    ScanEntry { period_ms: Some(period_ms), ..read(address, offset) }
}

fn write(address: u16, offset: u16) -> ScanEntry {
    entry(1, Function::WriteSingleRegister, address, 1, offset)
}

// ---- the timetable on its own ----

#[test]
fn the_cycle_reads_go_in_scan_order_then_the_cycle_is_done() {
    let scan = [read(0, 0), read(1, 2), periodic(2, 4, 500)];
    let mut t = Timetable::<4>::new(ms(0));
    assert!(t.start_cycle(&scan, ms(0)));
    t.poll(&scan, ms(0));
    let mut order = StdVec::new();
    while let Some(i) = t.next_due(&scan, true) {
        order.push(i);
        t.sent(i);
    }
    assert_eq!(order, [0, 1, 2]);
    assert!(!t.cycle_pending(&scan));
    assert_eq!(t.poll_at(&scan), Some(ms(500)));
}

#[test]
fn a_periodic_entry_is_due_once_per_period_on_a_fixed_grid() {
    let scan = [periodic(0, 0, 300)];
    let mut t = Timetable::<1>::new(ms(0));
    let mut sent = StdVec::new();
    for now in (0..=1000).step_by(50) {
        t.poll(&scan, ms(now));
        if let Some(i) = t.next_due(&scan, true) {
            sent.push(now);
            t.sent(i);
        }
    }
    assert_eq!(sent, [0, 300, 600, 900]);
}

#[test]
fn a_missed_period_sends_once_and_restarts_the_grid() {
    let scan = [periodic(0, 0, 100)];
    let mut t = Timetable::<1>::new(ms(0));
    t.poll(&scan, ms(0));
    t.sent(0);
    // The line was busy from 0 to 350: three period instants passed.
    t.poll(&scan, ms(350));
    assert_eq!(t.next_due(&scan, true), Some(0));
    t.sent(0);
    t.poll(&scan, ms(351));
    assert_eq!(t.next_due(&scan, true), None, "no burst for the missed instants");
    assert_eq!(t.poll_at(&scan), Some(ms(450)));
}

#[test]
fn the_earliest_due_goes_first_and_a_fast_entry_cannot_starve_a_slow_one() {
    // Entry 0 every 1 ms (faster than any line), entry 1 every 1000 ms; each transaction takes
    // 10 ms. Entry 1 must still be sent at every one of its period instants, within a transaction.
    let scan = [periodic(0, 0, 1), periodic(1, 2, 1000)];
    let mut t = Timetable::<2>::new(ms(0));
    let mut now = 0;
    let mut slow = StdVec::new();
    let mut fast = 0;
    while now < 5000 {
        t.poll(&scan, ms(now));
        match t.next_due(&scan, true) {
            Some(i) => {
                t.sent(i);
                if i == 1 {
                    slow.push(now);
                } else {
                    fast += 1;
                }
                now += 10;
            }
            None => now += 1,
        }
    }
    assert_eq!(slow.len(), 5, "{slow:?}");
    for (k, at) in slow.iter().enumerate() {
        assert!(*at >= 1000 * k as u64 && *at <= 1000 * k as u64 + 10, "{slow:?}");
    }
    assert!(fast > 450, "the fast entry had the rest of the line: {fast}");
}

#[test]
fn writes_wait_for_valid_outputs() {
    let scan = [ScanEntry { write: WriteMode::Cyclic, period_ms: Some(100), ..write(0, 0) }];
    let mut t = Timetable::<1>::new(ms(0));
    t.poll(&scan, ms(0));
    assert_eq!(t.next_due(&scan, false), None);
    assert_eq!(t.next_due(&scan, true), Some(0));
}

#[test]
fn a_triggered_read_is_due_from_its_trigger_until_sent() {
    let scan = [read(0, 0), ScanEntry { trigger_offset: Some(3), ..read(1, 2) }];
    let mut t = Timetable::<2>::new(ms(0));
    t.start_cycle(&scan, ms(0));
    t.trigger(1, ms(5));
    t.trigger(1, ms(7));
    assert_eq!(t.next_due(&scan, true), Some(0));
    t.sent(0);
    assert_eq!(t.next_due(&scan, true), Some(1));
    t.sent(1);
    assert_eq!(t.next_due(&scan, true), None, "two triggers before it was sent read it once");
    assert!(!t.start_cycle(&[scan[1]], ms(10)), "a triggered read is not part of the cycle");
}

#[rstest]
#[case::first_image_arms(true, [0, 0, 0, 1], false)]
#[case::trigger_changes(false, [0, 0, 0, 1], true)]
#[case::only_data_changes(false, [9, 9, 0, 0], false)]
fn a_triggered_write_is_called_for_by_its_trigger_byte_only(
    #[case] first: bool,
    #[case] new: [u8; 4],
    #[case] called: bool,
) {
    let e = ScanEntry {
        write: WriteMode::Trigger,
        trigger_offset: Some(3),
        ..entry(1, Function::WriteMultipleRegisters, 0, 1, 0)
    };
    let old = [0u8; IMAGE_CAPACITY];
    let mut image = [0u8; IMAGE_CAPACITY];
    image[..4].copy_from_slice(&new);
    assert_eq!(called_for(&e, &old, &image, first), called);
}

#[rstest]
#[case::first_image(true, [0, 0], true)]
#[case::data_changes(false, [1, 0], true)]
#[case::nothing_changes(false, [0, 0], false)]
fn a_write_on_change_is_called_for_by_its_bytes(
    #[case] first: bool,
    #[case] new: [u8; 2],
    #[case] called: bool,
) {
    for w in [WriteMode::Change, WriteMode::Cyclic] {
        let e = ScanEntry { write: w, period_ms: (w == WriteMode::Cyclic).then_some(100), ..write(0, 0) };
        let old = [0u8; IMAGE_CAPACITY];
        let mut image = [0u8; IMAGE_CAPACITY];
        image[..2].copy_from_slice(&new);
        assert_eq!(called_for(&e, &old, &image, first), called, "{w:?}");
    }
}

// ---- the keys' checks, as the description loader words them ----

fn checked(scan: &[ScanEntry]) -> Result<(), std::string::String> {
    let mut c = ModbusConfig::new(heapless::Vec::from_slice(scan).unwrap());
    // Four output bytes or the writes' end, not grown to hold a trigger byte as `new` does.
    let writes = scan.iter().filter(|e| e.function.is_write()).map(|e| e.range().end).max();
    c.output_len = writes.unwrap_or(0).max(4) as u16;
    c.validate().map_err(|e| e.to_string())
}

#[rstest]
#[case::period_zero(periodic(0, 0, 0), "scan[0].period_ms: 0 is outside the allowed range 1..=3600000")]
#[case::period_too_long(
    periodic(0, 0, 3_600_001),
    "scan[0].period_ms: 3600001 is outside the allowed range 1..=3600000"
)]
#[case::write_mode_on_a_read(ScanEntry { write: WriteMode::Cyclic, period_ms: Some(5), ..read(0, 0) }, "scan[0].write: applies to write entries (functions 5, 6, 15, 16) only")]
#[case::cyclic_without_period(ScanEntry { write: WriteMode::Cyclic, ..write(0, 0) }, "scan[0].write: write = \"cyclic\" needs period_ms")]
#[case::trigger_without_offset(ScanEntry { write: WriteMode::Trigger, ..write(0, 0) }, "scan[0].write: write = \"trigger\" needs trigger_offset")]
#[case::period_on_a_change_write(ScanEntry { period_ms: Some(5), ..write(0, 0) }, "scan[0].period_ms: a write entry takes period_ms with write = \"cyclic\" only")]
#[case::offset_on_a_change_write(ScanEntry { trigger_offset: Some(3), ..write(0, 0) }, "scan[0].trigger_offset: a write entry takes trigger_offset with write = \"trigger\" only")]
#[case::read_with_both(ScanEntry { trigger_offset: Some(3), ..periodic(0, 0, 5) }, "scan[0].trigger_offset: a read entry takes period_ms or trigger_offset, not both")]
#[case::trigger_past_the_image(ScanEntry { trigger_offset: Some(4), ..read(0, 0) }, "scan[0].trigger_offset: 4 is outside the allowed range 0..=3")]
#[case::trigger_in_its_own_bytes(ScanEntry { write: WriteMode::Trigger, trigger_offset: Some(1), ..write(0, 0) }, "scan[0].trigger_offset: overlaps the image bytes of entry 0")]
fn a_schedule_key_that_does_not_fit_is_refused(#[case] e: ScanEntry, #[case] message: &str) {
    assert_eq!(checked(&[e]), Err(message.to_string()));
}

#[test]
fn a_trigger_byte_inside_another_write_is_refused_and_one_outside_is_taken() {
    let trig = |b| ScanEntry { write: WriteMode::Trigger, trigger_offset: Some(b), ..write(0, 0) };
    assert_eq!(
        checked(&[trig(2), write(1, 2)]),
        Err("scan[0].trigger_offset: overlaps the image bytes of entry 1".to_string())
    );
    assert_eq!(checked(&[trig(3), write(1, 4)]), Ok(()));
    // A read's trigger byte may be any output byte no write sends; two entries may share one.
    let read_trig = ScanEntry { trigger_offset: Some(3), ..read(0, 0) };
    assert_eq!(checked(&[trig(3), read_trig]), Ok(()));
}

#[test]
fn a_trigger_byte_needs_an_output_image() {
    let mut c = ModbusConfig::new(
        heapless::Vec::from_slice(&[ScanEntry { trigger_offset: Some(0), ..read(0, 0) }]).unwrap(),
    );
    c.output_len = 0;
    assert_eq!(
        c.validate().map_err(|e| e.to_string()),
        Err("scan[0].trigger_offset: a trigger byte needs an output image (output_len is 0)".to_string())
    );
}

// ---- the master on a fake clock, against an instrument that answers at once ----

/// Every request the instrument saw: (ms, function code, address, the data of a write).
type Log = StdVec<(u64, u8, u16, StdVec<u8>)>;

fn master(scan: &[ScanEntry], output_len: u16) -> ModbusMaster {
    let mut c = ModbusConfig::new(heapless::Vec::from_slice(scan).unwrap());
    c.serial = SerialSettings::new_8e1(38400);
    c.poll_period_ms = 100;
    c.output_len = c.output_len.max(output_len);
    ModbusMaster::new(c, ms(0)).unwrap()
}

/// The instrument's answer to RTU request `adu`: zeros for a read, the echo for a write.
fn answer(adu: &[u8]) -> StdVec<u8> {
    let count = usize::from(u16::from_be_bytes([adu[4], adu[5]]));
    let mut r = match adu[1] {
        1 | 2 => [&adu[..2], &[count.div_ceil(8) as u8]].concat(),
        3 | 4 => [&adu[..2], &[2 * count as u8]].concat(),
        _ => adu[..6].to_vec(),
    };
    if adu[1] <= 4 {
        let n = usize::from(r[2]);
        r.extend(std::iter::repeat_n(0, n));
    }
    let crc = crate::serial::checksum::crc16_modbus(&r).to_le_bytes();
    r.extend_from_slice(&crc);
    r
}

/// Runs `m` from 0 to `until` ms in 1 ms steps, giving it the output images of `outputs` at
/// their times; returns what the instrument saw.
fn run(m: &mut ModbusMaster, outputs: &[(u64, &[u8])], until: u64) -> Log {
    let mut log = Log::new();
    for t in 0..until {
        for (_, image) in outputs.iter().filter(|(at, _)| *at == t) {
            m.set_outputs(image, ms(t));
        }
        while let Some(adu) = m.poll_transmit(ms(t)) {
            let adu = adu.to_vec();
            let address = u16::from_be_bytes([adu[2], adu[3]]);
            let data = if adu[1] >= 5 { adu[4..adu.len() - 2].to_vec() } else { StdVec::new() };
            log.push((t, adu[1], address, data));
            m.on_bytes(&answer(&adu), ms(t));
        }
    }
    log
}

fn times(log: &Log, address: u16) -> StdVec<u64> {
    log.iter().filter(|r| r.2 == address).map(|r| r.0).collect()
}

#[test]
fn a_slow_period_entry_is_read_less_often_and_delays_no_other() {
    // Entry 0 every scan cycle (100 ms), entry 1 every 1000 ms.
    let mut m = master(&[read(0, 0), periodic(1, 2, 1000)], 0);
    let log = run(&mut m, &[], 3000);
    let fast = times(&log, 0);
    let slow = times(&log, 1);
    assert_eq!(fast.len(), 30, "{fast:?}");
    for (k, t) in fast.iter().enumerate() {
        assert!(*t >= 100 * k as u64 && *t < 100 * k as u64 + 10, "cycle {k} read at {t}: {fast:?}");
    }
    assert_eq!(slow.len(), 3, "{slow:?}");
    for (k, t) in slow.iter().enumerate() {
        assert!(*t >= 1000 * k as u64 && *t < 1000 * k as u64 + 10, "{slow:?}");
    }
    assert_eq!(m.completed_cycles(), 30);
}

#[test]
fn periods_faster_than_the_line_still_leave_a_slow_entry_its_turn() {
    let mut m = master(&[periodic(0, 0, 1), periodic(1, 2, 1), periodic(2, 4, 700)], 0);
    let log = run(&mut m, &[], 2200);
    assert_eq!(times(&log, 2).len(), 4, "{:?}", times(&log, 2));
    for (k, t) in times(&log, 2).iter().enumerate() {
        assert!(*t >= 700 * k as u64 && *t < 700 * k as u64 + 15, "{:?}", times(&log, 2));
    }
    let (a, b) = (times(&log, 0).len(), times(&log, 1).len());
    assert!(a.abs_diff(b) <= 1 && a > 200, "the two fast entries share the line: {a} {b}");
}

#[test]
fn a_cyclic_write_is_resent_every_period_and_on_change() {
    let e = ScanEntry { write: WriteMode::Cyclic, period_ms: Some(500), ..write(7, 0) };
    let mut m = master(&[read(0, 0), e], 2);
    let log = run(&mut m, &[(10, &[0, 1]), (1200, &[0, 2])], 2000);
    let sent: StdVec<(u64, StdVec<u8>)> =
        log.iter().filter(|r| r.1 == 6).map(|r| (r.0 / 10 * 10, r.3.clone())).collect();
    assert_eq!(
        sent,
        [(10, vec![1, 0]), (500, vec![1, 0]), (1000, vec![1, 0]), (1200, vec![2, 0]), (1500, vec![2, 0])],
        "{log:?}"
    );
}

#[test]
fn a_triggered_write_goes_once_per_change_of_its_trigger_byte_only() {
    let e = ScanEntry { write: WriteMode::Trigger, trigger_offset: Some(2), ..write(7, 0) };
    let mut m = master(&[read(0, 4), e], 3);
    let outputs: [(u64, &[u8]); 5] = [
        (10, &[0, 1, 0]),  // the first image arms the trigger: nothing written
        (200, &[0, 2, 0]), // data only: nothing
        (400, &[0, 2, 1]), // the trigger toggles: written once, with the data of now
        (600, &[0, 3, 1]), // data only again: nothing
        (800, &[0, 3, 2]), // the trigger changes again: written
    ];
    let log = run(&mut m, &outputs, 1000);
    let sent: StdVec<(u64, StdVec<u8>)> =
        log.iter().filter(|r| r.1 == 6).map(|r| (r.0, r.3.clone())).collect();
    assert_eq!(sent.len(), 2, "{sent:?}");
    assert!((400..410).contains(&sent[0].0) && sent[0].1 == [2, 0], "{sent:?}");
    assert!((800..810).contains(&sent[1].0) && sent[1].1 == [3, 0], "{sent:?}");
}

#[test]
fn a_triggered_read_is_read_once_per_trigger_and_not_every_cycle() {
    let e = ScanEntry { trigger_offset: Some(0), ..read(9, 2) };
    let mut m = master(&[read(0, 0), e], 1);
    let log = run(&mut m, &[(10, &[5]), (300, &[6]), (350, &[6]), (700, &[7])], 1000);
    let reads = times(&log, 9);
    assert_eq!(reads.len(), 2, "{reads:?}");
    assert!((300..310).contains(&reads[0]) && (700..710).contains(&reads[1]), "{reads:?}");
    assert_eq!(times(&log, 0).len(), 10, "the cycle goes on as before");
}

#[test]
fn a_change_write_still_goes_ahead_of_due_reads() {
    let mut m = master(&[read(0, 0), read(1, 2), read(2, 4), write(7, 0)], 2);
    let log = run(&mut m, &[(100, &[0, 9])], 150);
    // At 100 the cycle's three reads and the write are all due: the write goes first.
    let at_100: StdVec<u8> = log.iter().filter(|r| r.0 >= 100).map(|r| r.1).collect();
    assert_eq!(at_100, [6, 3, 3, 3], "{log:?}");
}
