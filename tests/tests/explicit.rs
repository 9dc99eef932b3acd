//! `get`/`set`: explicit messaging with fragmentation both ways, and error responses by name.

use can_io::bus::Bitrate;
use devicenet::explicit::GeneralStatus;
use devicenet::messages::AllocationChoice;
use master_core::client::{Port, ReplyBody};
use master_core::error::MasterError;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use system_tests::{mac, sim_bus};

#[test]
fn product_name_comes_fragmented_and_is_acknowledged() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut m = Master::new(&mut session, MasterConfig::default());
    m.open_explicit(mac(5)).unwrap();
    let (data, _) = m.get(mac(5), 1, 1, 7).unwrap();
    assert_eq!(data[0], 23);
    assert_eq!(&data[1..], b"Serial-DeviceNet Bridge");
    // 26-byte message: 5 fragments of up to 6 body bytes, each acknowledged by the master.
    let acks = session
        .records()
        .iter()
        .filter(|r| r.frame.id().as_raw() == 0x42C && r.frame.data().len() == 3)
        .count();
    let fragments = session
        .records()
        .iter()
        .filter(|r| r.frame.id().as_raw() == 0x42B && r.frame.data()[0] == 0x80)
        .count();
    assert_eq!((fragments, acks), (5, 5));
    assert_eq!(session.failures(), 0);
}

#[test]
fn fragmented_request_and_response() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut m = Master::new(&mut session, MasterConfig::default());
    m.open_explicit(mac(5)).unwrap();
    let value = [1, 2, 3, 4, 5, 6, 7, 8];
    // Set output assembly 150 data: a 13-byte request, sent in two acknowledged fragments.
    let (resp, _) = m.set(mac(5), 4, 150, 3, &value).unwrap();
    assert!(resp.is_empty());
    let answer = m
        .request(
            mac(5),
            Port::Explicit,
            &devicenet::explicit::Request {
                service: devicenet::explicit::ServiceCode::GetAttributeSingle,
                class: 4,
                instance: 150,
                data: &[3],
            },
        )
        .unwrap();
    assert!(answer.reply.fragmented);
    assert_eq!(answer.reply.body, ReplyBody::Success(value.to_vec()));
    let request_fragments = session
        .records()
        .iter()
        .filter(|r| r.frame.id().as_raw() == 0x42C && r.frame.data().len() == 8)
        .count();
    assert_eq!(request_fragments, 2);
    assert_eq!(session.failures(), 0);
}

fn expect_error(r: Result<(Vec<u8>, Option<usize>), MasterError>, general: GeneralStatus, text: &str) {
    match r {
        Err(MasterError::ErrorResponse { general: g, text: t, .. }) => {
            assert_eq!(g, general);
            assert!(t.contains(text), "{t}");
        }
        other => panic!("expected an error response, got {other:?}"),
    }
}

#[test]
fn error_responses_are_named() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut m = Master::new(&mut session, MasterConfig::default());
    m.open_explicit(mac(5)).unwrap();
    expect_error(
        m.get(mac(5), 1, 1, 99),
        GeneralStatus::AttributeNotSupported,
        "attribute not supported (0x14)",
    );
    expect_error(
        m.set(mac(5), 1, 1, 1, &[0, 0]),
        GeneralStatus::AttributeNotSettable,
        "attribute not settable (0x0E)",
    );
    expect_error(
        m.get(mac(5), 0x99, 1, 1),
        GeneralStatus::ObjectDoesNotExist,
        "object does not exist (0x16)",
    );
    expect_error(
        m.set(mac(5), 5, 1, 12, &[2]),
        GeneralStatus::InvalidAttributeValue,
        "invalid attribute value (0x09)",
    );
    let err = m.get(mac(5), 1, 1, 99).unwrap_err().to_string();
    assert!(
        err.contains("Get_Attribute_Single Identity(1) inst 1 attr 99: MAC 5 answered with an error: attribute not supported (0x14)"),
        "{err}"
    );
    // The failing frames are marked in the transcript.
    assert_eq!(session.failures(), 5);
}

#[test]
fn a_second_master_gets_the_allocation_conflict_by_name() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    {
        let mut first = Master::new(&mut session, MasterConfig { mac: mac(1), ..MasterConfig::default() });
        first.open_explicit(mac(5)).unwrap();
    }
    let mut second =
        Master::new(&mut session, MasterConfig { mac: mac(2), serial_number: 7, ..MasterConfig::default() });
    second.network_access().unwrap();
    let err = second.allocate(mac(5), Port::Group2Only, AllocationChoice::EXPLICIT).unwrap_err();
    // 0x0C / 0x01, named as the conflict it is, with the owner seen on the bus (master 1's requests
    // carry its MAC in their header).
    assert!(matches!(err, MasterError::AllocationConflict { mac: 5, owner: Some(1) }), "{err}");
    assert!(err.to_string().contains("MAC 5 is allocated to another master (MAC 1)"), "{err}");
    let answer = second.session.records().last().unwrap();
    assert!(answer.verdict.label().contains("object state conflict (0x0C)"), "{}", answer.verdict.label());
}

#[test]
fn an_owned_connection_is_released_and_allocated_again() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut m = Master::new(&mut session, MasterConfig::default());
    m.open_explicit(mac(5)).unwrap();
    let before = m.session.records().len();
    // Allocating again: the device answers 0x0B already in requested state; the master releases
    // and allocates again, as a scanner coming back does, and leaves a notice.
    m.allocate(mac(5), Port::Group2Only, AllocationChoice::EXPLICIT).unwrap();
    let data: Vec<Vec<u8>> = m.session.records()[before..].iter().map(|r| r.frame.data().to_vec()).collect();
    assert_eq!(
        data,
        [
            vec![0x00, 0x4B, 0x03, 0x01, 0x01, 0x00],
            vec![0x00, 0x94, 0x0B, 0x02],
            vec![0x00, 0x4C, 0x03, 0x01, 0x01],
            vec![0x00, 0xCC],
            vec![0x00, 0x4B, 0x03, 0x01, 0x01, 0x00],
            vec![0x00, 0xCB, 0x00],
        ]
    );
    assert_eq!(m.session.failures(), 0, "the 0x0B answer is expected, not a failure");
    assert_eq!(m.notices().len(), 1, "{:?}", m.notices());
    assert_eq!(m.get_u16(mac(5), 1, 1, 1).unwrap(), Some(0x1234));
    assert_eq!(m.held(mac(5)), AllocationChoice::EXPLICIT);
    m.release_held().unwrap();
    assert_eq!(m.held(mac(5)), AllocationChoice::empty());
}
