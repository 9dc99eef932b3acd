//! The objects: explicit services, connection and identity attributes, application objects.

use super::*;

#[rstest]
#[case::vendor(&[0x0E, 0x01, 0x01, 0x01], &[0x8E, 0x34, 0x12])]
#[case::device_type(&[0x0E, 0x01, 0x01, 0x02], &[0x8E, 0x0C, 0x00])]
#[case::product_code(&[0x0E, 0x01, 0x01, 0x03], &[0x8E, 0x01, 0x00])]
#[case::revision(&[0x0E, 0x01, 0x01, 0x04], &[0x8E, 0x01, 0x01])]
#[case::status_owned_no_io(&[0x0E, 0x01, 0x01, 0x05], &[0x8E, 0x31, 0x00])]
#[case::serial(&[0x0E, 0x01, 0x01, 0x06], &[0x8E, 0x78, 0x56, 0x34, 0x12])]
#[case::state(&[0x0E, 0x01, 0x01, 0x08], &[0x8E, 0x03])]
#[case::identity_class_revision(&[0x0E, 0x01, 0x00, 0x01], &[0x8E, 0x01, 0x00])]
#[case::identity_class_attr_2(&[0x0E, 0x01, 0x00, 0x02], &[0x94, 0x14, 0xFF])]
#[case::identity_unknown_attr(&[0x0E, 0x01, 0x01, 0x63], &[0x94, 0x14, 0xFF])]
#[case::identity_set_vendor(&[0x10, 0x01, 0x01, 0x01, 0x00, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::identity_instance_2(&[0x0E, 0x01, 0x02, 0x01], &[0x94, 0x16, 0xFF])]
#[case::identity_reset_bad_type(&[0x05, 0x01, 0x01, 0x02], &[0x94, 0x20, 0xFF])]
#[case::identity_unsupported_service(&[0x06, 0x01, 0x01], &[0x94, 0x08, 0xFF])]
#[case::get_without_attribute(&[0x0E, 0x01, 0x01], &[0x94, 0x13, 0xFF])]
#[case::router_class_revision(&[0x0E, 0x02, 0x00, 0x01], &[0x8E, 0x01, 0x00])]
#[case::router_instance_attr(&[0x0E, 0x02, 0x01, 0x01], &[0x94, 0x14, 0xFF])]
#[case::router_instance_set(&[0x10, 0x02, 0x01, 0x01, 0x00], &[0x94, 0x08, 0xFF])]
#[case::unknown_class(&[0x0E, 0x64, 0x01, 0x01], &[0x94, 0x16, 0xFF])]
#[case::dnet_mac(&[0x0E, 0x03, 0x01, 0x01], &[0x8E, 0x05])]
#[case::dnet_baud(&[0x0E, 0x03, 0x01, 0x02], &[0x8E, 0x01])]
#[case::dnet_boi(&[0x0E, 0x03, 0x01, 0x03], &[0x8E, 0x00])]
#[case::dnet_bus_off_counter(&[0x0E, 0x03, 0x01, 0x04], &[0x8E, 0x00])]
#[case::dnet_allocation(&[0x0E, 0x03, 0x01, 0x05], &[0x8E, 0x01, 0x00])]
#[case::dnet_mac_switch_changed(&[0x0E, 0x03, 0x01, 0x06], &[0x8E, 0x00])]
#[case::dnet_baud_switch_changed(&[0x0E, 0x03, 0x01, 0x07], &[0x8E, 0x00])]
#[case::dnet_no_mac_switch(&[0x0E, 0x03, 0x01, 0x08], &[0x94, 0x14, 0xFF])]
#[case::dnet_class_revision(&[0x0E, 0x03, 0x00, 0x01], &[0x8E, 0x02, 0x00])]
#[case::dnet_set_mac_not_programmable(&[0x10, 0x03, 0x01, 0x01, 0x07], &[0x94, 0x0E, 0xFF])]
#[case::dnet_set_boi(&[0x10, 0x03, 0x01, 0x03, 0x01], &[0x90])]
#[case::dnet_clear_boi(&[0x10, 0x03, 0x01, 0x03, 0x00], &[0x90])]
#[case::dnet_set_boi_invalid(&[0x10, 0x03, 0x01, 0x03, 0x02], &[0x94, 0x09, 0xFF])]
#[case::dnet_clear_bus_off_counter(&[0x10, 0x03, 0x01, 0x04, 0x00], &[0x90])]
#[case::dnet_bus_off_counter_nonzero(&[0x10, 0x03, 0x01, 0x04, 0x05], &[0x94, 0x09, 0xFF])]
#[case::dnet_set_allocation_info(&[0x10, 0x03, 0x01, 0x05, 0x01, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::dnet_set_boi_too_long(&[0x10, 0x03, 0x01, 0x03, 0x01, 0x00], &[0x94, 0x15, 0xFF])]
#[case::dnet_unsupported_service(&[0x05, 0x03, 0x01], &[0x94, 0x08, 0xFF])]
#[case::assembly_input_size(&[0x0E, 0x04, 0x64, 0x04], &[0x8E, 0x12, 0x00])]
#[case::assembly_set_input(&[0x10, 0x04, 0x64, 0x03, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::assembly_set_size(&[0x10, 0x04, 0x96, 0x04, 0x08, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::assembly_unknown_instance(&[0x0E, 0x04, 0x01, 0x03], &[0x94, 0x16, 0xFF])]
#[case::assembly_set_output_short(&[0x10, 0x04, 0x96, 0x03, 0x01], &[0x94, 0x13, 0xFF])]
#[case::connection_class_revision(&[0x0E, 0x05, 0x00, 0x01], &[0x8E, 0x01, 0x00])]
#[case::poll_not_allocated(&[0x0E, 0x05, 0x02, 0x01], &[0x94, 0x16, 0xFF])]
#[case::bit_strobe_instance(&[0x0E, 0x05, 0x03, 0x01], &[0x94, 0x16, 0xFF])]
fn explicit_services(#[case] body: &[u8], #[case] response: &[u8]) {
    let mut rig = Rig::explicit();
    let mut request = std::vec![0x00];
    request.extend_from_slice(body);
    let mut expected = std::vec![0x00];
    expected.extend_from_slice(response);
    assert_eq!(rig.send(0x42C, &request), tx(0x42B, &expected));
}

#[rstest]
// Explicit (instance 1), protocol §5.1.
#[case::e_state(1, 1, &[0x03])]
#[case::e_instance_type(1, 2, &[0x00])]
#[case::e_transport(1, 3, &[0x83])]
#[case::e_produced_id(1, 4, &[0x2B, 0x04])]
#[case::e_consumed_id(1, 5, &[0x2C, 0x04])]
#[case::e_comm_characteristics(1, 6, &[0x21])]
// MAX_EXPLICIT_SIZE, 140: a firmware update's Transfer request fits (config.rs).
#[case::e_produced_size(1, 7, &[0x8C, 0x00])]
#[case::e_consumed_size(1, 8, &[0x8C, 0x00])]
#[case::e_epr(1, 9, &[0xC4, 0x09])]
#[case::e_watchdog(1, 12, &[0x01])]
#[case::e_produced_path_len(1, 13, &[0x00, 0x00])]
#[case::e_produced_path(1, 14, &[])]
#[case::e_consumed_path_len(1, 15, &[0x00, 0x00])]
#[case::e_consumed_path(1, 16, &[])]
#[case::e_inhibit(1, 17, &[0x00, 0x00])]
// Poll (instance 2), after EPR set.
#[case::p_state(2, 1, &[0x03])]
#[case::p_instance_type(2, 2, &[0x01])]
#[case::p_transport(2, 3, &[0x82])]
#[case::p_produced_id(2, 4, &[0xC5, 0x03])]
#[case::p_consumed_id(2, 5, &[0x2D, 0x04])]
#[case::p_comm_characteristics(2, 6, &[0x01])]
#[case::p_produced_size(2, 7, &[0x12, 0x00])]
#[case::p_consumed_size(2, 8, &[0x08, 0x00])]
#[case::p_epr(2, 9, &[0x64, 0x00])]
#[case::p_watchdog(2, 12, &[0x00])]
#[case::p_produced_path_len(2, 13, &[0x06, 0x00])]
#[case::p_produced_path(2, 14, &[0x20, 0x04, 0x24, 0x64, 0x30, 0x03])]
#[case::p_consumed_path(2, 16, &[0x20, 0x04, 0x24, 0x96, 0x30, 0x03])]
#[case::p_inhibit(2, 17, &[0x00, 0x00])]
fn connection_attributes(#[case] instance: u8, #[case] attr: u8, #[case] value: &[u8]) {
    let mut rig = Rig::established();
    let resp = rig.send(0x42C, &[0x00, 0x0E, 0x05, instance, attr]);
    let mut expected = std::vec![0x00, 0x8E];
    expected.extend_from_slice(value);
    assert_eq!(resp, tx(0x42B, &expected));
}

#[rstest]
#[case::explicit_deferred_delete(1, 3, &[0x90])]
#[case::explicit_auto_delete(1, 1, &[0x90])]
#[case::explicit_timed_out_invalid(1, 0, &[0x94, 0x09, 0xFF])]
#[case::explicit_auto_reset_invalid(1, 2, &[0x94, 0x09, 0xFF])]
#[case::poll_timed_out(2, 0, &[0x90])]
#[case::poll_auto_delete(2, 1, &[0x90])]
#[case::poll_auto_reset(2, 2, &[0x90])]
#[case::poll_deferred_invalid(2, 3, &[0x94, 0x09, 0xFF])]
#[case::out_of_range(2, 9, &[0x94, 0x09, 0xFF])]
fn watchdog_action_values(#[case] instance: u8, #[case] value: u8, #[case] response: &[u8]) {
    let mut rig = Rig::established();
    let mut expected = std::vec![0x00];
    expected.extend_from_slice(response);
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x05, instance, 0x0C, value]), tx(0x42B, &expected));
}

#[rstest]
#[case::state(1, &[0x03], &[0x94, 0x0E, 0xFF])]
#[case::produced_size(7, &[0x12, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::path(14, &[0x00], &[0x94, 0x0E, 0xFF])]
#[case::cip_connection_id(10, &[0, 0], &[0x94, 0x14, 0xFF])]
#[case::unknown(40, &[0x00], &[0x94, 0x14, 0xFF])]
#[case::epr_too_short(9, &[0x64], &[0x94, 0x13, 0xFF])]
#[case::epr_too_long(9, &[0x64, 0x00, 0x00], &[0x94, 0x15, 0xFF])]
#[case::epr_above_65000(9, &[0xE9, 0xFD], &[0x94, 0x09, 0xFF])]
#[case::epr_max(9, &[0xE8, 0xFD], &[0x90, 0xE8, 0xFD])]
fn connection_set_rules(#[case] attr: u8, #[case] value: &[u8], #[case] response: &[u8]) {
    let mut rig = Rig::established();
    let mut req = std::vec![0x00, 0x10, 0x05, 0x02, attr];
    req.extend_from_slice(value);
    let mut expected = std::vec![0x00];
    expected.extend_from_slice(response);
    assert_eq!(rig.send(0x42C, &req), tx(0x42B, &expected));
}

#[rstest]
#[case::exact(10, 100, 100)]
#[case::rounded_up(10, 95, 100)]
#[case::icp_example(100, 3594, 3600)]
#[case::one_ms(1, 3594, 3594)]
#[case::zero_disables(10, 0, 0)]
fn expected_packet_rate_rounding(#[case] resolution: u16, #[case] requested: u16, #[case] applied: u16) {
    let mut config = DeviceConfig::reference();
    config.epr_resolution_ms = resolution;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    let [lo, hi] = requested.to_le_bytes();
    let [alo, ahi] = applied.to_le_bytes();
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, lo, hi]), tx(0x42B, &[0x00, 0x90, alo, ahi]));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::Established);
}

#[rstest]
#[case::configured(ApplicationStatus { configured: true, ..ApplicationStatus::default() }, [0x35, 0x00])]
#[case::minor_recoverable(ApplicationStatus { minor_recoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x01])]
#[case::minor_unrecoverable(ApplicationStatus { minor_unrecoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x02])]
#[case::major_recoverable(ApplicationStatus { major_recoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x04])]
#[case::major_unrecoverable(ApplicationStatus { major_unrecoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x08])]
fn identity_status_carries_each_application_flag_in_its_bit(
    #[case] status: ApplicationStatus,
    #[case] word: [u8; 2],
) {
    // Identity attribute 5 (protocol §6.2): owned (bit 0), configured (bit 2), extended status
    // 0b0011 "no I/O connection established" (bits 4–7), faults in bits 8–11.
    let mut rig = Rig::explicit();
    rig.node.set_application_status(status, rig.now);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x05]), tx(0x42B, &[0x00, 0x8E, word[0], word[1]]));
}

#[test]
fn identity_get_attributes_all_answers_attributes_1_to_7_in_fragments() {
    // Get_Attributes_All (protocol §3.2): the reply exceeds one frame, so it goes out in acknowledged
    // fragments (protocol §4.1); the master reassembles and acks each one.
    let mut rig = Rig::explicit();
    let mut master = crate::fragment::ExplicitReassembler::<MAX_EXPLICIT_SIZE>::new();
    let mut frames = rig.send(0x42C, &[0x00, 0x01, 0x01, 0x01]);
    // Header and 39 body bytes: 7 fragments of up to 6 body bytes.
    for _ in 0..7 {
        let [(0x42B, frame)] = frames.as_slice() else { panic!("one response fragment: {frames:02X?}") };
        match master.receive(frame) {
            crate::fragment::ExplicitReceive::Ack(ack) => frames = rig.send(0x42C, &ack),
            crate::fragment::ExplicitReceive::Complete(ack) => {
                assert_eq!(rig.send(0x42C, &ack), Tx::new());
                break;
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    let mut expected = std::vec![0x00, 0x81, 0x34, 0x12, 0x0C, 0x00, 0x01, 0x00, 0x01, 0x01, 0x31, 0x00];
    expected.extend_from_slice(&[0x78, 0x56, 0x34, 0x12, 23]);
    expected.extend_from_slice(b"Serial-DeviceNet Bridge");
    assert_eq!(master.message(), expected);
}

#[test]
fn configuration_consistency_is_unsupported_until_the_application_keeps_one() {
    // Identity attribute 9 is optional (protocol §6.2): without a value the node answers
    // "attribute not supported" to Get and Set alike.
    let mut rig = Rig::explicit();
    assert_eq!(rig.node.configuration_consistency(), None);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x09]), tx(0x42B, &[0x00, 0x94, 0x14, 0xFF]));
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x09, 0x01, 0x00]),
        tx(0x42B, &[0x00, 0x94, 0x14, 0xFF])
    );
}

#[rstest]
#[case::first(0xBEEF, [0xEF, 0xBE])]
#[case::changed(0x1234, [0x34, 0x12])]
#[case::zero(0x0000, [0x00, 0x00])]
fn configuration_consistency_is_served_as_set_and_not_settable(#[case] ccv: u16, #[case] wire: [u8; 2]) {
    // UINT, little-endian (protocol §II.5.3); a tool changes it only by changing the
    // configuration, so Set answers "attribute not settable" and leaves it alone.
    let mut rig = Rig::explicit();
    rig.node.set_configuration_consistency(0x5555);
    rig.node.set_configuration_consistency(ccv);
    assert_eq!(rig.node.configuration_consistency(), Some(ccv));
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x09]), tx(0x42B, &[0x00, 0x8E, wire[0], wire[1]]));
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x09, 0x01, 0x00]),
        tx(0x42B, &[0x00, 0x94, 0x0E, 0xFF])
    );
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x09]), tx(0x42B, &[0x00, 0x8E, wire[0], wire[1]]));
}

#[rstest]
#[case::power_cycle(&[0x00, 0x05, 0x01, 0x01], 0)]
#[case::out_of_box(&[0x00, 0x05, 0x01, 0x01, 0x01], 1)]
fn identity_reset_reports_an_event_after_queueing_the_response(#[case] request: &[u8], #[case] kind: u8) {
    let mut rig = Rig::explicit();
    // The response, then the shutdown message: class 1, instance 1, code 4 (LIM, §II.5.2).
    assert_eq!(
        rig.send(0x42C, request),
        std::vec![
            (0x42B, std::vec![0x00, 0x85]),
            (0x42B, std::vec![0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00])
        ]
    );
    assert_eq!(rig.events(), std::vec![Event::ResetRequested(kind)]);
}

#[test]
fn programmable_mac_and_baud() {
    let mut config = DeviceConfig::reference();
    config.switches.programmable = true;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    rig.events();
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x01, 0x40]), tx(0x42B, &[0x00, 0x94, 0x09, 0xFF]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x01, 0x07]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x02, 0x02]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x02, 0x03]), tx(0x42B, &[0x00, 0x94, 0x09, 0xFF]));
    assert_eq!(
        rig.events(),
        std::vec![
            Event::SettingChanged(SettingChanged::MacId(MacId::new(7).unwrap())),
            Event::SettingChanged(SettingChanged::BaudRate(BaudRate::Kbps500)),
        ]
    );
    // The stored values are reported; the node keeps running at MAC 5 until reset.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x07]));
    assert_eq!(rig.node.mac_id().as_raw(), 5);
}

#[test]
fn switch_attributes() {
    let mut config = DeviceConfig::reference();
    config.switches = Switches {
        mac_id: Some(5),
        baud_rate: Some(1),
        mac_id_changed: true,
        baud_rate_changed: false,
        programmable: false,
    };
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x06]), tx(0x42B, &[0x00, 0x8E, 0x01]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x08]), tx(0x42B, &[0x00, 0x8E, 0x05]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x09]), tx(0x42B, &[0x00, 0x8E, 0x01]));
}

#[test]
fn application_objects_are_served() {
    struct Stats;
    impl ObjectHandler for Stats {
        fn handle(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Option<Result<(), ServiceError>> {
            (req.class == 0x64).then(|| match (req.service, req.data) {
                (ServiceCode::GetAttributeSingle, [1]) => reply.u32(0xDEAD_BEEF),
                _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
            })
        }
    }
    let mut rig = Rig::explicit();
    let frame = CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x64, 0x01, 0x01]).unwrap();
    rig.node.handle_frame_with(&frame, rig.now, &mut Stats);
    assert_eq!(rig.drain(), tx(0x42B, &[0x00, 0x8E, 0xEF, 0xBE, 0xAD, 0xDE]));
    let frame = CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x65, 0x01, 0x01]).unwrap();
    rig.node.handle_frame_with(&frame, rig.now, &mut Stats);
    assert_eq!(rig.drain(), tx(0x42B, &[0x00, 0x94, 0x16, 0xFF]));
}
