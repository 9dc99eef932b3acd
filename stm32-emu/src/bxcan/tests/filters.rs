//! The firmware's filter banks (two 16-bit mask banks, board::filters for MAC 5) and the other
//! scales and modes as the controller applies them to frames from the bus.

use super::*;
use rstest::rstest;

fn firmware() -> Driver {
    let mut d = Driver::new(PCLK1);
    d.firmware_setup();
    let _ = d.enable_non_blocking();
    d
}

#[rstest]
// Bank 0 filter 0: every Group 2 message of MAC 5 (0x428..=0x42F).
#[case::explicit_request(data(0x42C, &[]), Some(0))]
#[case::duplicate_mac_check(data(0x42F, &[]), Some(0))]
// Bank 0 filter 1: every master's bit-strobe (Group 2 message 0).
#[case::strobe_of_master_62(data(0x5F0, &[]), Some(1))]
// Bank 1 (filters 2 and 3, both the same): the Offline Connection Set requests, data only.
#[case::comm_faulted_request(data(0x7ED, &[]), Some(2))]
#[case::offline_ownership_request(data(0x7EF, &[]), Some(2))]
#[case::offline_request_as_remote_frame(Frame::new_remote(FrameId::Standard(0x7ED), 0).unwrap(), None)]
#[case::another_slaves_poll(data(0x435, &[]), None)]
#[case::group1(data(0x3C5, &[]), None)]
#[case::who_response(data(0x7EC, &[]), None)]
#[case::extended_with_matching_bits(Frame::new_data(FrameId::Extended(0x428 << 18), &[]).unwrap(), None)]
fn firmware_filters(#[case] frame: Frame, #[case] fmi: Option<u32>) {
    let mut d = firmware();
    assert_eq!(d.hear(&frame, 125_000), Response::Acknowledge, "acknowledged either way");
    match fmi {
        Some(fmi) => {
            assert_eq!(d.read(offset::RF0R) & 0b11, 1);
            assert_eq!(d.read(offset::RI0R + 4) >> 8 & 0xFF, fmi, "FMI");
            assert_eq!(d.receive(), Nb::Ok(frame));
        }
        None => assert_eq!(d.read(offset::RF0R) | d.read(offset::RF1R), 0),
    }
}

#[test]
fn set_mac_rewrites_bank_0_while_the_node_runs() {
    let mut d = firmware();
    // Can::modify_filters again (firmware set_mac): FINIT set, so the active bank is writable.
    d.modify_filters();
    let own = Mask16::frames_with_std_id(0x400 | 9 << 3, 0x7F8);
    let strobe = Mask16::frames_with_std_id(0x400, 0x607);
    d.enable_bank_mask16(0, false, [own, strobe]);
    assert_eq!(d.hear(&data(0x44C, &[]), 125_000), Response::Acknowledge);
    assert_eq!(d.read(offset::RF0R) & 0b11, 0, "nothing stored while FINIT is set");
    d.drop_filters();
    d.hear(&data(0x44C, &[]), 125_000);
    d.hear(&data(0x42C, &[]), 125_000);
    assert_eq!(d.read(offset::RF0R) & 0b11, 1, "MAC 9's frame only");
}

#[test]
fn active_bank_refuses_new_values_outside_finit() {
    let mut d = firmware();
    let before = d.read(filter::offset::F0R1);
    d.write(filter::offset::F0R1, 0);
    assert_eq!(d.read(filter::offset::F0R1), before);
    d.write(filter::offset::FM1R, 0b11);
    assert_eq!(d.read(filter::offset::FM1R), 0);
}

/// Bank 2 set up by raw register writes (as bxcan's `enable_bank` with other configurations),
/// routed to FIFO 1.
fn with_bank2(list: bool, scale32: bool, fr: [u32; 2]) -> Driver {
    let mut d = firmware();
    d.modify_filters();
    d.modify(filter::offset::FM1R, |r| if list { r | 4 } else { r & !4 });
    d.modify(filter::offset::FS1R, |r| if scale32 { r | 4 } else { r & !4 });
    d.write(filter::offset::F0R1 + 16, fr[0]);
    d.write(filter::offset::F0R1 + 20, fr[1]);
    d.modify(filter::offset::FFA1R, |r| r | 4);
    d.modify(filter::offset::FA1R, |r| r | 4);
    d.drop_filters();
    d
}

#[rstest]
// bxcan ListEntry32::data_frames_with_id(Extended): id << 3 | IDE; FIFO 1's first filters.
#[case::list32_extended(true, true, [0x1234_5678 << 3 | 4, 0x0000_0001 << 3 | 4],
    Frame::new_data(FrameId::Extended(0x0000_0001), &[]).unwrap(), Some(1))]
// Mask32::frames_with_ext_id(0x100, 0x1FFF_FF00): every extended id 0x100..=0x1FF.
#[case::mask32_extended(false, true, [0x100 << 3 | 4, 0x1FFF_FF00 << 3 | 4],
    Frame::new_data(FrameId::Extended(0x1AB), &[]).unwrap(), Some(0))]
// ListEntry16::remote_frames_with_id(0x123) in the third position.
#[case::list16_remote(true, false, [0, (0x7FF << 5) << 16 | 0x123 << 5 | 0x10],
    Frame::new_remote(FrameId::Standard(0x123), 0).unwrap(), Some(2))]
#[case::list16_data_is_not_remote(true, false, [0, (0x7FF << 5) << 16 | 0x123 << 5 | 0x10],
    data(0x123, &[]), None)]
// Mask16 second filter: identifiers 0x300..=0x30F.
#[case::mask16_second(false, false, [0xFFFF_FFFF, (0x7F0 << 5 | 8) << 16 | 0x300 << 5],
    data(0x30A, &[]), Some(1))]
fn other_scales_and_modes(
    #[case] list: bool,
    #[case] scale32: bool,
    #[case] fr: [u32; 2],
    #[case] frame: Frame,
    #[case] fmi: Option<u32>,
) {
    let mut d = with_bank2(list, scale32, fr);
    d.hear(&frame, 125_000);
    match fmi {
        Some(fmi) => {
            assert_eq!(d.read(offset::RF1R) & 0b11, 1, "FIFO 1");
            assert_eq!(d.read(offset::RI0R + 0x10 + 4) >> 8 & 0xFF, fmi);
            assert_eq!(d.receive(), Nb::Ok(frame));
        }
        None => assert_eq!(d.read(offset::RF1R) & 0b11, 0),
    }
}

#[test]
fn banks_from_can2sb_on_belong_to_can2() {
    let mut d = with_bank2(false, true, [0, 0]);
    d.modify_filters();
    d.modify(offset::FMR, |r| r & !0x3F00 | 2 << 8);
    d.drop_filters();
    d.hear(&data(0x123, &[]), 125_000);
    assert_eq!(d.read(offset::RF1R) & 0b11, 0, "bank 2 is CAN2's");
}
