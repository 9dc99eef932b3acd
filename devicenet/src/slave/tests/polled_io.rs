//! Polled I/O (protocol §4.2, §5).

use super::*;

#[test]
fn poll_ignored_until_epr_is_set() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]);
    assert_eq!(rig.node.poll_connection().state, ConnectionState::Configuring);
    assert_eq!(rig.send(0x42D, &[0; 8]), Tx::new());
    assert_eq!(rig.node.stats().polls_ignored, 1);
}

#[test]
fn poll_answered_at_once_with_three_fragments() {
    let mut rig = Rig::established();
    let resp = rig.send(0x42D, &[1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(
        resp,
        std::vec![
            (0x3C5, std::vec![0x00, 0, 0, 0, 0, 0, 0, 0]),
            (0x3C5, std::vec![0x41, 0, 0, 0x0F, 0, 0, 0, 0]),
            (0x3C5, std::vec![0x82, 0, 0, 0, 0]),
        ]
    );
    assert_eq!(rig.node.output(), &[1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(rig.events(), std::vec![Event::OutputReceived]);
    assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0110);
}

#[test]
fn fragments_as_io_fragments() {
    // Every fragmented produced size: the poll response is the frames of `io_fragments` (the
    // transmit queue holds the first TX_QUEUE_LEN of them).
    for size in 9..=MAX_IO_SIZE as u16 {
        let mut config = DeviceConfig::reference();
        config.produced_size = size;
        let mut rig = Rig::new(config);
        let input: Vec<u8> = (0..size).map(|i| i as u8 ^ 0xA5).collect();
        rig.node.set_input(&input).unwrap();
        rig.node.power_on(Instant::ZERO);
        rig.advance(Duration::from_secs(2));
        rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
        rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
        let expected: Tx =
            crate::fragment::io_fragments(&input).take(TX_QUEUE_LEN).map(|p| (0x3C5, p.to_vec())).collect();
        assert_eq!(rig.send(0x42D, &[0; 8]), expected, "produced size {size}");
    }
}

#[test]
fn idle_poll_is_reported_and_answered() {
    let mut rig = Rig::established();
    rig.send(0x42D, &[9; 8]);
    rig.events();
    assert_eq!(rig.send(0x42D, &[]).len(), 3);
    assert_eq!(rig.events(), std::vec![Event::Idle]);
    assert!(rig.node.is_idle());
    assert_eq!(rig.node.output(), &[9; 8], "idle keeps the last outputs");
    assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0111);
}

#[test]
fn short_poll_accepted_long_poll_ignored() {
    let mut config = DeviceConfig::reference();
    config.consumed_size = 4;
    config.produced_size = 2;
    let mut rig = Rig::new(config);
    rig.node.set_input(&[0xAA, 0xBB]).unwrap();
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    assert_eq!(rig.send(0x42D, &[1, 2]), tx(0x3C5, &[0xAA, 0xBB]), "produced size <= 8: not fragmented");
    assert_eq!(rig.send(0x42D, &[1, 2, 3, 4, 5]), Tx::new());
}

#[test]
fn poll_with_data_after_an_idle_poll_ends_idle() {
    let mut rig = Rig::established();
    assert!(!rig.node.is_idle());
    rig.send(0x42D, &[]);
    assert!(rig.node.is_idle());
    rig.send(0x42D, &[3; 8]);
    assert!(!rig.node.is_idle());
    assert_eq!(rig.events(), std::vec![Event::Idle, Event::OutputReceived]);
}

#[test]
fn eight_byte_poll_response_is_one_unfragmented_frame() {
    // I/O fragmentation starts above 8 bytes (protocol §4.2).
    let mut config = DeviceConfig::reference();
    config.produced_size = 8;
    let mut rig = Rig::new(config);
    rig.node.set_input(&[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    assert_eq!(rig.send(0x42D, &[0; 8]), tx(0x3C5, &[1, 2, 3, 4, 5, 6, 7, 8]));
}

#[test]
fn fragmented_poll_command_up_to_the_consumed_size_is_accepted() {
    // Consumed size 10: the command comes in I/O fragments (protocol §4.2); a longer one is ignored.
    let mut config = DeviceConfig::reference();
    config.consumed_size = 10;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    rig.events();
    assert_eq!(rig.send(0x42D, &[0x00, 1, 2, 3, 4, 5, 6, 7]), Tx::new());
    assert_eq!(rig.send(0x42D, &[0x81, 8, 9, 10]).len(), 3, "answered with the 18-byte input");
    assert_eq!(rig.node.output(), &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
    assert_eq!(rig.events(), std::vec![Event::OutputReceived]);
    // 14 bytes: one fragment more than the consumed size allows.
    assert_eq!(rig.send(0x42D, &[0x00, 9, 9, 9, 9, 9, 9, 9]), Tx::new());
    assert_eq!(rig.send(0x42D, &[0x81, 9, 9, 9, 9, 9, 9, 9]), Tx::new());
    assert_eq!(rig.node.output(), &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
    assert_eq!(rig.node.stats().polls_ignored, 1);
    assert_eq!(rig.events(), Vec::<Event>::new());
}

#[test]
fn set_input_checks_the_size() {
    let mut rig = Rig::established();
    assert_eq!(rig.node.set_input(&[0; 3]), Err(18));
    let mut image = [0u8; 18];
    image[0] = 0x42;
    rig.node.set_input(&image).unwrap();
    assert_eq!(rig.send(0x42D, &[0; 8])[0].1, std::vec![0x00, 0x42, 0, 0, 0, 0, 0, 0]);
}

#[test]
fn input_mut_writes_the_image_in_place() {
    let mut rig = Rig::established();
    assert_eq!(rig.node.input_mut().len(), 18, "exactly the produced size");
    rig.node.input_mut()[1] = 0x42;
    assert_eq!(rig.node.input()[..3], [0, 0x42, 0]);
    assert_eq!(rig.send(0x42D, &[0; 8])[0].1, std::vec![0x00, 0, 0x42, 0, 0, 0, 0, 0]);
}

#[test]
fn assembly_output_set_refused_while_polling() {
    let mut config = DeviceConfig::reference();
    config.consumed_size = 2;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    // Configuring: the outputs may be set explicitly.
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.node.output(), &[1, 2]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    // Established: the poll connection owns them.
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]), tx(0x42B, &[0x00, 0x94, 0x10, 0xFF]));
}

#[test]
fn setting_the_poll_epr_establishes_it_once() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]);
    rig.events();
    // Configuring -> Established when the EPR is set (protocol §5.2); a second Set changes nothing.
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    assert_eq!(rig.events(), std::vec![Event::ConnectionEstablished(ConnectionKind::Poll)]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0xC8, 0x00]);
    assert_eq!(rig.events(), Vec::<Event>::new());
}
