//! The update object over an in-memory flash (`embedded-storage-inmemory`'s `MemFlash`, which
//! panics on a write to flash that is not erased: so every test also proves that the object
//! never programs a word twice), images signed with the repository's TEST key.

use super::*;
use devicenet::explicit::ServiceCode;
use devicenet::messages::AllocationChoice;
use embedded_storage_inmemory::MemFlash;
use fw_image::{sign, ImageInfo, Trailer};
use rstest::rstest;

/// The DFU: two 128 KiB pages, 128 KiB erase, word writes (the board's driver's geometry).
type Flash = MemFlash<{ 2 * PAGE_SIZE }, PAGE_SIZE, 4>;

const PUBLIC: &[u8; 32] = include_bytes!("../../../contrib/keys/test-ed25519.public");
const SECRET: &[u8; 32] = include_bytes!("../../../contrib/keys/test-ed25519.secret");
const BOARD: u16 = 1;
const RUNNING: Revision = Revision { major: 1, minor: 0 };
const NEW: Revision = Revision { major: 1, minor: 1 };
const IMAGE_ID: [u8; 8] = *b"imageid1";
/// 39 chunks, the last of 77 bytes.
const IMAGE_LEN: usize = 38 * CHUNK_SIZE + 77;

/// Records Apply's calls; fails when told to.
#[derive(Default)]
struct Marker {
    marked: Option<Trailer>,
    fail: bool,
}

impl MarkUpdated for Marker {
    fn mark_updated(&mut self, trailer: &Trailer) -> Result<(), MarkError> {
        if self.fail {
            return Err(MarkError);
        }
        self.marked = Some(*trailer);
        Ok(())
    }
}

fn platform(boot: BootState) -> Platform {
    Platform {
        board_id: BOARD,
        running: RUNNING,
        public_key: *PUBLIC,
        bootloader: Revision { major: 0, minor: 3 },
        boot,
    }
}

/// An image of `len` bytes for `board` with its info block, and its trailer.
fn signed(len: usize, board: u16) -> (Vec<u8>, Trailer) {
    let mut image: Vec<u8> = (0..len).map(|i| (i * 31 + 7) as u8).collect();
    let info = ImageInfo { board_id: board, revision: NEW };
    image[INFO_OFFSET..INFO_OFFSET + INFO_LEN].copy_from_slice(&info.to_bytes());
    let trailer = sign(&image, SECRET).unwrap();
    (image, trailer)
}

fn flash() -> Box<Flash> {
    Box::new(Flash::new(0xFF))
}

type Object<'a> = UpdateObject<&'a mut Flash, Marker>;

fn object(flash: &mut Flash, boot: BootState) -> Object<'_> {
    UpdateObject::new(flash, Marker::default(), platform(boot)).unwrap()
}

const NOW: Instant = Instant::from_millis(1_000);

/// Sends a request; the response data or the error.
fn call(obj: &mut Object<'_>, service: u8, data: &[u8], io: bool) -> Result<Vec<u8>, ServiceError> {
    let req = Request { service: ServiceCode::from(service), class: UPDATE_CLASS, instance: 1, data };
    let mut buf = [0u8; 136];
    let mut reply = Reply::new(&mut buf);
    obj.serve(&req, &mut reply, io, NOW)?;
    let n = reply.len();
    Ok(buf[..n].to_vec())
}

fn update_request(len: usize, board: u16, id: [u8; 8]) -> Vec<u8> {
    let mut d = (len as u32).to_le_bytes().to_vec();
    d.extend_from_slice(&board.to_le_bytes());
    d.extend_from_slice(&[NEW.major, NEW.minor]);
    d.extend_from_slice(&id);
    d
}

/// Update; the next chunk it answers.
fn update(obj: &mut Object<'_>, len: usize) -> Result<u32, ServiceError> {
    let r = call(obj, service::UPDATE, &update_request(len, BOARD, IMAGE_ID), false)?;
    assert_eq!(r[..2], [128, 0], "transfer size");
    Ok(u32::from_le_bytes(r[2..6].try_into().unwrap()))
}

/// Transfer chunk `n` of `image`; the state it answers.
fn transfer(obj: &mut Object<'_>, image: &[u8], n: usize) -> Result<u16, ServiceError> {
    let end = ((n + 1) * CHUNK_SIZE).min(image.len());
    let mut d = (n as u32).to_le_bytes().to_vec();
    d.extend_from_slice(&image[n * CHUNK_SIZE..end]);
    let r = call(obj, service::TRANSFER, &d, false)?;
    assert_eq!(r[..4], (n as u32).to_le_bytes(), "chunk number echoed");
    Ok(u16::from_le_bytes([r[4], r[5]]))
}

fn chunks(len: usize) -> usize {
    len.div_ceil(CHUNK_SIZE)
}

fn get(obj: &mut Object<'_>, attr: u8) -> Vec<u8> {
    call(obj, 0x0E, &[attr], false).unwrap()
}

fn class_specific(code: Refusal) -> ServiceError {
    code.error()
}

#[test]
fn a_full_update_lands_in_dfu_and_apply_marks_it() {
    let (image, trailer) = signed(IMAGE_LEN, BOARD);
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    assert_eq!(get(&mut obj, 1), [UpdateState::Idle as u8]);
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(0));
    assert_eq!(get(&mut obj, 3), (IMAGE_LEN as u32).to_le_bytes());
    for n in 0..chunks(IMAGE_LEN) {
        let state = transfer(&mut obj, &image, n).unwrap();
        let last = n + 1 == chunks(IMAGE_LEN);
        assert_eq!(state, if last { 2 } else { 1 }, "chunk {n}");
    }
    assert_eq!(get(&mut obj, 4), (chunks(IMAGE_LEN) as u32).to_le_bytes());
    assert_eq!(call(&mut obj, service::VERIFY, &trailer.to_bytes(), false), Ok(vec![3, 0]));
    assert_eq!(call(&mut obj, service::APPLY, &[], false), Ok(vec![]));
    assert_eq!(obj.mark().marked, Some(trailer));
    assert!(!obj.poll_reset(NOW), "the response leaves first");
    assert_eq!(obj.poll_at(), Some(NOW + RESET_DELAY));
    assert!(obj.poll_reset(NOW + RESET_DELAY));
    assert!(!obj.poll_reset(NOW + RESET_DELAY), "once");
    let _ = obj.into_parts();
    assert_eq!(&flash.mem[..IMAGE_LEN], &image[..], "the image in the first page");
    assert_eq!(&flash.mem[PAGE_SIZE - 128..PAGE_SIZE], &trailer.to_bytes()[..], "the trailer at its end");
}

#[test]
fn the_largest_image_fits_beside_its_trailer() {
    let len = MAX_IMAGE_LEN as usize;
    let (image, trailer) = signed(len, BOARD);
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    assert_eq!(update(&mut obj, len), Ok(0));
    for n in 0..chunks(len) {
        transfer(&mut obj, &image, n).unwrap();
    }
    assert_eq!(call(&mut obj, service::VERIFY, &trailer.to_bytes(), false), Ok(vec![3, 0]));
    assert_eq!(update(&mut obj, len + 1), Err(ServiceError::TOO_MUCH_DATA), "one byte more is refused");
}

#[test]
fn a_dropped_session_resumes_at_the_first_unlogged_chunk() {
    let (image, trailer) = signed(IMAGE_LEN, BOARD);
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    update(&mut obj, IMAGE_LEN).unwrap();
    for n in 0..10 {
        transfer(&mut obj, &image, n).unwrap();
    }
    obj.on_event(&Event::Released { choice: AllocationChoice::EXPLICIT, owned: false });
    assert_eq!(get(&mut obj, 1), [UpdateState::Idle as u8]);
    assert_eq!(transfer(&mut obj, &image, 10), Err(ServiceError::OBJECT_STATE_CONFLICT));
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(10));
    for n in 10..chunks(IMAGE_LEN) {
        transfer(&mut obj, &image, n).unwrap();
    }
    assert_eq!(call(&mut obj, service::VERIFY, &trailer.to_bytes(), false), Ok(vec![3, 0]));
}

#[test]
fn another_image_id_starts_over() {
    let (image, _) = signed(IMAGE_LEN, BOARD);
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    update(&mut obj, IMAGE_LEN).unwrap();
    transfer(&mut obj, &image, 0).unwrap();
    let other = call(&mut obj, service::UPDATE, &update_request(IMAGE_LEN, BOARD, *b"otherimg"), false);
    assert_eq!(other.unwrap()[2..], [0, 0, 0, 0]);
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(0), "the log is the other image's now");
}

#[rstest]
#[case::after_the_log_word(true)]
#[case::between_chunk_and_log(false)]
fn a_power_cut_resumes_from_the_log(#[case] logged: bool) {
    let (image, trailer) = signed(IMAGE_LEN, BOARD);
    let mut flash = flash();
    {
        let mut obj = object(&mut flash, BootState::Confirmed);
        update(&mut obj, IMAGE_LEN).unwrap();
        for n in 0..7 {
            transfer(&mut obj, &image, n).unwrap();
        }
    }
    if !logged {
        // Chunk 7 programmed, the cut before its log word.
        flash.mem[7 * CHUNK_SIZE..8 * CHUNK_SIZE].copy_from_slice(&image[7 * CHUNK_SIZE..8 * CHUNK_SIZE]);
    }
    // Power up: a new object over the same flash.
    let mut obj = object(&mut flash, BootState::Confirmed);
    assert_eq!(get(&mut obj, 1), [UpdateState::Idle as u8]);
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(7));
    for n in 7..chunks(IMAGE_LEN) {
        transfer(&mut obj, &image, n).unwrap();
    }
    assert_eq!(call(&mut obj, service::VERIFY, &trailer.to_bytes(), false), Ok(vec![3, 0]));
}

#[test]
fn a_torn_chunk_is_refused_and_the_next_update_starts_over() {
    let (image, trailer) = signed(IMAGE_LEN, BOARD);
    let mut flash = flash();
    {
        let mut obj = object(&mut flash, BootState::Confirmed);
        update(&mut obj, IMAGE_LEN).unwrap();
        for n in 0..3 {
            transfer(&mut obj, &image, n).unwrap();
        }
    }
    // Chunk 3's program torn: its first half written.
    flash.mem[3 * CHUNK_SIZE..3 * CHUNK_SIZE + 64]
        .copy_from_slice(&image[3 * CHUNK_SIZE..3 * CHUNK_SIZE + 64]);
    let mut obj = object(&mut flash, BootState::Confirmed);
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(3));
    assert_eq!(transfer(&mut obj, &image, 3), Err(ServiceError::new(GeneralStatus::StoreOperationFailure)));
    assert_eq!(get(&mut obj, 9), [service::TRANSFER, 0xFF]);
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(0), "erased and started over");
    for n in 0..chunks(IMAGE_LEN) {
        transfer(&mut obj, &image, n).unwrap();
    }
    assert_eq!(call(&mut obj, service::VERIFY, &trailer.to_bytes(), false), Ok(vec![3, 0]));
}

#[test]
fn a_repeated_chunk_is_answered_again_not_written_again() {
    let (image, _) = signed(IMAGE_LEN, BOARD);
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    update(&mut obj, IMAGE_LEN).unwrap();
    transfer(&mut obj, &image, 0).unwrap();
    transfer(&mut obj, &image, 1).unwrap();
    // MemFlash panics on a second write: the repeat writes nothing.
    assert_eq!(transfer(&mut obj, &image, 1), Ok(1));
    assert_eq!(get(&mut obj, 4), 2u32.to_le_bytes());
    assert_eq!(transfer(&mut obj, &image, 0), Err(ServiceError::INVALID_PARAMETER), "only the last");
    assert_eq!(transfer(&mut obj, &image, 3), Err(ServiceError::INVALID_PARAMETER), "no gap");
}

/// An object with a complete image received; the trailer.
fn complete(flash: &mut Flash, len: usize, board: u16) -> (Object<'_>, Trailer) {
    let (image, trailer) = signed(len, board);
    let mut obj = object(flash, BootState::Confirmed);
    update(&mut obj, len).unwrap();
    for n in 0..chunks(len) {
        transfer(&mut obj, &image, n).unwrap();
    }
    (obj, trailer)
}

#[test]
fn a_bad_signature_is_refused_with_code_1() {
    let mut flash = flash();
    let (mut obj, mut trailer) = complete(&mut flash, IMAGE_LEN, BOARD);
    trailer.signature[0] ^= 1;
    assert_eq!(
        call(&mut obj, service::VERIFY, &trailer.to_bytes(), false),
        Err(class_specific(Refusal::BadSignature))
    );
    assert_eq!(get(&mut obj, 1), [UpdateState::Refused as u8]);
    assert_eq!(get(&mut obj, 9), [service::VERIFY, 1]);
    assert_eq!(call(&mut obj, service::APPLY, &[], false), Err(ServiceError::OBJECT_STATE_CONFLICT));
    assert_eq!(obj.mark().marked, None);
    let _ = obj.into_parts();
    assert!(flash.mem[PAGE_SIZE - 128..PAGE_SIZE].iter().all(|&b| b == 0xFF), "no trailer stored");
}

#[test]
fn an_image_for_another_board_is_refused_at_update_and_at_verify() {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    assert_eq!(
        call(&mut obj, service::UPDATE, &update_request(IMAGE_LEN, 4, IMAGE_ID), false),
        Err(class_specific(Refusal::AnotherBoard))
    );
    assert_eq!(get(&mut obj, 1), [UpdateState::Refused as u8]);
    assert_eq!(get(&mut obj, 9), [service::UPDATE, 2]);
    let _ = obj.into_parts();
    // Announced as ours, built for board 4: the image-info block tells.
    let (mut obj, trailer) = complete(&mut flash, IMAGE_LEN, 4);
    assert_eq!(
        call(&mut obj, service::VERIFY, &trailer.to_bytes(), false),
        Err(class_specific(Refusal::AnotherBoard))
    );
}

#[test]
fn a_trailer_of_another_length_is_refused_with_code_3() {
    let mut flash = flash();
    let (mut obj, _) = complete(&mut flash, IMAGE_LEN, BOARD);
    let (_, longer) = signed(IMAGE_LEN + 1, BOARD);
    assert_eq!(
        call(&mut obj, service::VERIFY, &longer.to_bytes(), false),
        Err(class_specific(Refusal::LengthMismatch))
    );
}

#[test]
fn an_image_without_info_block_is_refused_with_code_4() {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    let mut image: Vec<u8> = vec![0x5A; 1000];
    image[0] = 1;
    update(&mut obj, image.len()).unwrap();
    for n in 0..chunks(image.len()) {
        transfer(&mut obj, &image, n).unwrap();
    }
    // A trailer signed over these bytes (sign() itself refuses an image without the block).
    let (_, mut trailer) = signed(1000, BOARD);
    trailer.image_len = 1000;
    assert_eq!(
        call(&mut obj, service::VERIFY, &trailer.to_bytes(), false),
        Err(class_specific(Refusal::NoImageInfo))
    );
}

#[test]
fn an_image_signed_with_another_key_is_refused_with_code_5() {
    let mut flash = flash();
    let (mut obj, _) = complete(&mut flash, IMAGE_LEN, BOARD);
    let (image, _) = signed(IMAGE_LEN, BOARD);
    let other = sign(&image, &[9u8; 32]).unwrap();
    assert_eq!(
        call(&mut obj, service::VERIFY, &other.to_bytes(), false),
        Err(class_specific(Refusal::AnotherKey))
    );
}

#[rstest]
#[case::update(service::UPDATE)]
#[case::transfer(service::TRANSFER)]
#[case::verify(service::VERIFY)]
#[case::apply(service::APPLY)]
fn every_update_service_is_refused_while_io_runs(#[case] service: u8) {
    let mut flash = flash();
    let (mut obj, trailer) = complete(&mut flash, IMAGE_LEN, BOARD);
    let data = match service {
        service::UPDATE => update_request(IMAGE_LEN, BOARD, IMAGE_ID),
        service::VERIFY => trailer.to_bytes().to_vec(),
        service::TRANSFER => vec![0; 132],
        _ => vec![],
    };
    assert_eq!(call(&mut obj, service, &data, true), Err(ServiceError::DEVICE_STATE_CONFLICT));
    assert_eq!(get(&mut obj, 1), [UpdateState::Complete as u8], "the session stays");
}

#[test]
fn out_of_order_services_are_object_state_conflicts() {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    let (image, trailer) = signed(IMAGE_LEN, BOARD);
    let conflict = Err(ServiceError::OBJECT_STATE_CONFLICT);
    assert_eq!(
        transfer(&mut obj, &image, 0),
        Err(ServiceError::OBJECT_STATE_CONFLICT),
        "Transfer before Update"
    );
    assert_eq!(call(&mut obj, service::VERIFY, &trailer.to_bytes(), false), conflict);
    assert_eq!(call(&mut obj, service::APPLY, &[], false), conflict);
    update(&mut obj, IMAGE_LEN).unwrap();
    transfer(&mut obj, &image, 0).unwrap();
    assert_eq!(
        call(&mut obj, service::VERIFY, &trailer.to_bytes(), false),
        conflict,
        "Verify before the last chunk"
    );
    assert_eq!(call(&mut obj, service::APPLY, &[], false), conflict, "Apply before Verify");
}

#[rstest]
#[case::update_short(service::UPDATE, 15, ServiceError::NOT_ENOUGH_DATA)]
#[case::update_long(service::UPDATE, 17, ServiceError::TOO_MUCH_DATA)]
#[case::transfer_short(service::TRANSFER, 3, ServiceError::NOT_ENOUGH_DATA)]
#[case::transfer_chunk_short(service::TRANSFER, 4 + 127, ServiceError::INVALID_PARAMETER)]
#[case::transfer_chunk_long(service::TRANSFER, 4 + 129, ServiceError::INVALID_PARAMETER)]
#[case::verify_short(service::VERIFY, 127, ServiceError::NOT_ENOUGH_DATA)]
#[case::verify_long(service::VERIFY, 129, ServiceError::TOO_MUCH_DATA)]
#[case::apply_data(service::APPLY, 1, ServiceError::TOO_MUCH_DATA)]
fn requests_of_the_wrong_length(#[case] service: u8, #[case] len: usize, #[case] error: ServiceError) {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    let (image, trailer) = signed(IMAGE_LEN, BOARD);
    // A session with every chunk but the last: Transfer of chunk 0 is a repeat-free first, Verify
    // needs a complete image, so each case gets the state where only its length is wrong.
    update(&mut obj, IMAGE_LEN).unwrap();
    if service == service::VERIFY || service == service::APPLY {
        for n in 0..chunks(IMAGE_LEN) {
            transfer(&mut obj, &image, n).unwrap();
        }
    }
    if service == service::APPLY {
        call(&mut obj, service::VERIFY, &trailer.to_bytes(), false).unwrap();
    }
    let data = vec![0u8; len];
    assert_eq!(call(&mut obj, service, &data, false), Err(error));
}

#[test]
fn update_refuses_an_empty_image_and_a_trial_boot() {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    assert_eq!(update(&mut obj, 0), Err(ServiceError::INVALID_PARAMETER));
    let _ = obj.into_parts();
    let mut obj = object(&mut flash, BootState::Trial);
    assert_eq!(get(&mut obj, 1), [UpdateState::Trial as u8]);
    assert_eq!(update(&mut obj, IMAGE_LEN), Err(ServiceError::DEVICE_STATE_CONFLICT));
    obj.confirm();
    assert_eq!(get(&mut obj, 1), [UpdateState::Idle as u8]);
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(0));
}

#[test]
fn apply_that_cannot_mark_is_a_store_failure() {
    let mut flash = flash();
    let (mut obj, trailer) = complete(&mut flash, IMAGE_LEN, BOARD);
    call(&mut obj, service::VERIFY, &trailer.to_bytes(), false).unwrap();
    let (flash, _) = obj.into_parts();
    let mut obj =
        UpdateObject::new(flash, Marker { marked: None, fail: true }, platform(BootState::Confirmed))
            .unwrap();
    // After the "power cut" the session must be announced and verified again.
    assert_eq!(update(&mut obj, IMAGE_LEN), Ok(chunks(IMAGE_LEN) as u32));
    call(&mut obj, service::VERIFY, &trailer.to_bytes(), false).unwrap();
    assert_eq!(
        call(&mut obj, service::APPLY, &[], false),
        Err(ServiceError::new(GeneralStatus::StoreOperationFailure))
    );
    assert_eq!(obj.poll_at(), None, "no reset");
}

#[rstest]
#[case::revision(2, vec![1, 0])]
#[case::size_idle(3, vec![0, 0, 0, 0])]
#[case::next_idle(4, vec![0, 0, 0, 0])]
#[case::chunk_size(5, vec![128, 0])]
#[case::largest(6, 130_944u32.to_le_bytes().to_vec())]
#[case::board(7, vec![1, 0])]
#[case::key_id(8, vec![0x53, 0x6c, 0x52, 0x52, 0x7d, 0xd7, 0x67, 0x49])]
#[case::no_refusal(9, vec![0, 0])]
#[case::bootloader(10, vec![0, 3])]
fn attributes(#[case] attr: u8, #[case] value: Vec<u8>) {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::RolledBack);
    assert_eq!(get(&mut obj, attr), value);
    assert_eq!(get(&mut obj, 1), [UpdateState::RolledBack as u8]);
}

#[rstest]
#[case::unknown_attribute(0x0E, vec![11], ServiceError::ATTRIBUTE_NOT_SUPPORTED)]
#[case::get_without_attribute(0x0E, vec![], ServiceError::NOT_ENOUGH_DATA)]
#[case::set_known(0x10, vec![1, 0], ServiceError::ATTRIBUTE_NOT_SETTABLE)]
#[case::set_unknown(0x10, vec![11, 0], ServiceError::ATTRIBUTE_NOT_SUPPORTED)]
#[case::other_service(0x05, vec![], ServiceError::SERVICE_NOT_SUPPORTED)]
fn other_requests(#[case] service: u8, #[case] data: Vec<u8>, #[case] error: ServiceError) {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    assert_eq!(call(&mut obj, service, &data, false), Err(error));
}

#[test]
fn only_instance_1_exists() {
    let mut flash = flash();
    let mut obj = object(&mut flash, BootState::Confirmed);
    let req =
        Request { service: ServiceCode::GetAttributeSingle, class: UPDATE_CLASS, instance: 2, data: &[1] };
    let mut buf = [0u8; 8];
    assert_eq!(
        obj.serve(&req, &mut Reply::new(&mut buf), false, NOW),
        Err(ServiceError::OBJECT_DOES_NOT_EXIST)
    );
}

#[test]
fn a_flash_of_another_geometry_is_refused() {
    let mut small = MemFlash::<{ PAGE_SIZE }, PAGE_SIZE, 4>::new(0xFF);
    assert!(matches!(
        UpdateObject::new(&mut small, Marker::default(), platform(BootState::Confirmed)),
        Err(GeometryError::Capacity(n)) if n == PAGE_SIZE
    ));
    let mut odd = Box::new(MemFlash::<{ 2 * PAGE_SIZE }, PAGE_SIZE, 32>::new(0xFF));
    assert!(matches!(
        UpdateObject::new(&mut *odd, Marker::default(), platform(BootState::Confirmed)),
        Err(GeometryError::WriteSize(32))
    ));
}

mod through_the_converter {
    //! The object behind the converter (`Converter::handle_can_frame_with`): reached over the
    //! owner's explicit connection only.

    use super::*;
    use crate::converter::{ApplicationObject, Converter, ConverterConfig};
    use devicenet::{CanFrame, Duration};

    /// Counts the requests that reach the object.
    struct Counting<'a> {
        inner: Object<'a>,
        reached: usize,
    }

    impl ApplicationObject for Counting<'_> {
        fn handle(
            &mut self,
            req: &Request<'_>,
            reply: &mut Reply<'_>,
            io_established: bool,
            now: Instant,
        ) -> Option<Result<(), ServiceError>> {
            let r = self.inner.handle(req, reply, io_established, now);
            self.reached += usize::from(r.is_some());
            r
        }

        fn class_revision(&self, class: u16) -> Option<u16> {
            self.inner.class_revision(class)
        }
    }

    /// The replies on the node's explicit response identifier (MAC 5) to one frame.
    fn send(c: &mut Converter, obj: &mut Counting<'_>, now: Instant, id: u16, data: &[u8]) -> Vec<Vec<u8>> {
        c.handle_can_frame_with(&CanFrame::from_raw(id, data).unwrap(), now, obj);
        std::iter::from_fn(|| c.poll_can_transmit())
            .filter(|f| f.id().as_raw() == 0x42B)
            .map(|f| f.data().to_vec())
            .collect()
    }

    #[test]
    fn only_the_owners_explicit_connection_reaches_the_object() {
        let mut flash = flash();
        let mut obj = Counting { inner: object(&mut flash, BootState::Confirmed), reached: 0 };
        let mut c = Converter::new(ConverterConfig::breaker_reference(), Instant::ZERO).unwrap();
        let mut now = Instant::ZERO;
        c.power_on(now);
        let end = now + Duration::from_secs(3);
        while let Some(at) = c.poll_at().filter(|&at| at <= end) {
            now = at.max(now);
            c.handle_timeout(now);
            while c.poll_can_transmit().is_some() {}
        }
        // Before any allocation: the Group 2 Only port serves the DeviceNet object alone.
        let g2 = send(&mut c, &mut obj, now, 0x42E, &[0x00, 0x0E, 0x6A, 0x01, 0x07]);
        assert_eq!(obj.reached, 0, "Group 2 Only: {g2:02X?}");
        // Master 0 allocates the explicit connection (protocol §3.4).
        let alloc = send(&mut c, &mut obj, now, 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
        assert_eq!(alloc, [vec![0x00, 0xCB, 0x00]]);
        // Its Get of attribute 7 (the board ID) reaches the object.
        let get = send(&mut c, &mut obj, now, 0x42C, &[0x00, 0x0E, 0x6A, 0x01, 0x07]);
        assert_eq!(get, [vec![0x00, 0x8E, 0x01, 0x00]]);
        assert_eq!(obj.reached, 1);
        // Class attribute 1, the revision, answered by the node from class_revision.
        let rev = send(&mut c, &mut obj, now, 0x42C, &[0x00, 0x0E, 0x6A, 0x00, 0x01]);
        assert_eq!(rev, [vec![0x00, 0x8E, 0x01, 0x00]]);
        // Master 1 on the same identifier: not the owner, ignored.
        let other = send(&mut c, &mut obj, now, 0x42C, &[0x01, 0x0E, 0x6A, 0x01, 0x07]);
        assert_eq!(other, Vec::<Vec<u8>>::new());
        assert_eq!(obj.reached, 1);
        // Without the object the class does not exist.
        c.handle_can_frame(&CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x6A, 0x01, 0x07]).unwrap(), now);
        let plain: Vec<_> = std::iter::from_fn(|| c.poll_can_transmit()).map(|f| f.data().to_vec()).collect();
        assert_eq!(plain, [vec![0x00, 0x94, 0x16, 0xFF]]);
    }
}

mod properties {
    //! No request makes the object panic, whatever state a session is in.

    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn any_request_sequence_is_answered(
            requests in proptest::collection::vec(
                (prop_oneof![Just(0x0Eu8), Just(0x10), Just(0x4B), Just(0x4C), Just(0x4D), Just(0x4E), any::<u8>()],
                 proptest::collection::vec(any::<u8>(), 0..140),
                 any::<bool>()),
                1..12),
        ) {
            let mut flash = flash();
            let mut obj = object(&mut flash, BootState::Confirmed);
            // A session first, so that Transfer, Verify and Apply meet a state to act on.
            update(&mut obj, IMAGE_LEN).unwrap();
            for (service, data, io) in requests {
                let _ = call(&mut obj, service, &data, io);
            }
        }
    }
}
