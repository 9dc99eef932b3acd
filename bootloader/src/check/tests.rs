//! The check before a swap over flash in memory, with images signed by the repository's TEST key:
//! each refusal cancels the request (BOOT magic in STATE), a good image is left to
//! `prepare_boot`, which then swaps it into ACTIVE byte for byte.

use super::*;
use board::flash_layout::{ACTIVE, DFU, LARGE_SECTOR_SIZE, SMALL_SECTOR_SIZE, STATE};
use embassy_boot::{BootLoader, BootLoaderConfig, State};
use embedded_storage::nor_flash::ReadNorFlash;
use embedded_storage_inmemory::MemFlash;
use fw_image::{ImageInfo, Revision, TRAILER_LEN};

const STATE_SIZE: usize = STATE.size as usize;
const SLOT_SIZE: usize = ACTIVE.size as usize;
const DFU_SIZE: usize = DFU.size as usize;
type StateMem = MemFlash<STATE_SIZE, { SMALL_SECTOR_SIZE as usize }, 4>;
type SlotMem = MemFlash<SLOT_SIZE, { LARGE_SECTOR_SIZE as usize }, 4>;
type DfuMem = MemFlash<DFU_SIZE, { LARGE_SECTOR_SIZE as usize }, 4>;

const TEST_SEED: &[u8; 32] = include_bytes!("../../../contrib/keys/test-ed25519.secret");
const TEST_PUBLIC: &[u8; 32] = include_bytes!("../../../contrib/keys/test-ed25519.public");
const BOARD: u16 = 1;
const BOOT_MAGIC: u8 = 0xD0;

/// An image of `len` bytes (a pattern) with an image-info block for `board`.
fn image(len: usize, board: u16) -> Vec<u8> {
    let mut image: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
    let info = ImageInfo { board_id: board, revision: Revision { major: 2, minor: 3 } }.to_bytes();
    image[INFO_OFFSET..INFO_OFFSET + INFO_LEN].copy_from_slice(&info);
    image
}

/// DFU holding `image` and `trailer`, as the firmware's update object leaves it.
fn dfu_with(image: &[u8], trailer: &[u8; TRAILER_LEN]) -> Box<DfuMem> {
    let mut dfu = Box::new(DfuMem::new(0xFF));
    dfu.mem[..image.len()].copy_from_slice(image);
    let at = TRAILER_OFFSET as usize;
    dfu.mem[at..at + TRAILER_LEN].copy_from_slice(trailer);
    dfu
}

fn signed(image: &[u8]) -> [u8; TRAILER_LEN] {
    fw_image::sign(image, TEST_SEED).unwrap().to_bytes()
}

/// STATE as `mark_updated` leaves it: the SWAP magic, everything else erased.
fn state_swap() -> Box<StateMem> {
    let mut state = Box::new(StateMem::new(0xFF));
    state.mem[..4].fill(SWAP_MAGIC);
    state
}

#[test]
fn a_good_image_is_verified_and_state_left_for_the_swap() {
    let image = image(5000, BOARD);
    let mut dfu = dfu_with(&image, &signed(&image));
    let mut state = state_swap();
    assert_eq!(guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD), Guard::Verified);
    assert_eq!(&state.mem[..4], &[SWAP_MAGIC; 4]);
    assert!(state.mem[4..].iter().all(|&b| b == 0xFF));
}

#[test]
fn then_prepare_boot_swaps_it_into_active_byte_exact() {
    let image = image(5000, BOARD);
    let trailer = signed(&image);
    let mut dfu = dfu_with(&image, &trailer);
    let mut state = state_swap();
    let mut active = Box::new(SlotMem::new(0x11));
    assert_eq!(guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD), Guard::Verified);
    let mut buffer = [0u8; 2048];
    let mut bootloader =
        BootLoader::new(BootLoaderConfig { active: &mut *active, dfu: &mut *dfu, state: &mut *state });
    assert_eq!(bootloader.prepare_boot(&mut buffer).unwrap(), State::Swap);
    assert_eq!(&active.mem[..image.len()], &image[..]);
    let at = TRAILER_OFFSET as usize;
    assert_eq!(&active.mem[at..at + TRAILER_LEN], &trailer[..], "the trailer travels with the image");
    // The old image is in DFU's second page, for a revert.
    assert!(dfu.mem[SLOT_SIZE..2 * SLOT_SIZE].iter().all(|&b| b == 0x11));
    // A swapped image is not checked again at the next start (the swap has started).
    assert_eq!(guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD), Guard::NothingToCheck);
}

fn assert_cancelled(state: &StateMem) {
    assert_eq!(&state.mem[..4], &[BOOT_MAGIC; 4], "mark_booted writes the BOOT magic");
    assert!(state.mem[4..].iter().all(|&b| b == 0xFF));
}

#[test]
fn a_flipped_image_bit_is_refused_and_cancelled() {
    let mut image = image(5000, BOARD);
    let trailer = signed(&image);
    image[3000] ^= 0x04;
    let mut dfu = dfu_with(&image, &trailer);
    let mut state = state_swap();
    assert_eq!(
        guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD),
        Guard::Cancelled(Refusal::Verify(VerifyError::BadSignature))
    );
    assert_cancelled(&state);
    // prepare_boot then leaves ACTIVE alone.
    let mut active = Box::new(SlotMem::new(0x22));
    let mut buffer = [0u8; 2048];
    let mut bootloader =
        BootLoader::new(BootLoaderConfig { active: &mut *active, dfu: &mut *dfu, state: &mut *state });
    assert_eq!(bootloader.prepare_boot(&mut buffer).unwrap(), State::Boot);
    assert!(active.mem.iter().all(|&b| b == 0x22));
}

#[test]
fn a_flipped_signature_bit_is_refused() {
    let image = image(5000, BOARD);
    let mut trailer = signed(&image);
    trailer[40] ^= 0x80;
    let mut dfu = dfu_with(&image, &trailer);
    let mut state = state_swap();
    assert_eq!(
        guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD),
        Guard::Cancelled(Refusal::Verify(VerifyError::BadSignature))
    );
    assert_cancelled(&state);
}

#[test]
fn an_image_for_another_board_is_refused_though_well_signed() {
    let image = image(5000, 4);
    let mut dfu = dfu_with(&image, &signed(&image));
    let mut state = state_swap();
    assert_eq!(
        guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD),
        Guard::Cancelled(Refusal::AnotherBoard { image: 4 })
    );
    assert_cancelled(&state);
}

#[test]
fn an_image_signed_with_another_key_is_refused() {
    let image = image(5000, BOARD);
    let other_seed = [7u8; 32];
    let trailer = fw_image::sign(&image, &other_seed).unwrap().to_bytes();
    let mut dfu = dfu_with(&image, &trailer);
    let mut state = state_swap();
    let guard = guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD);
    assert!(matches!(guard, Guard::Cancelled(Refusal::Verify(VerifyError::AnotherKey { .. }))), "{guard:?}");
    assert_cancelled(&state);
}

#[test]
fn no_trailer_is_refused() {
    let image = image(5000, BOARD);
    let mut dfu = dfu_with(&image, &[0xFF; TRAILER_LEN]);
    let mut state = state_swap();
    assert_eq!(
        guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD),
        Guard::Cancelled(Refusal::Trailer(TrailerError::BadMagic))
    );
    assert_cancelled(&state);
}

#[test]
fn nothing_is_checked_without_a_swap_request_or_once_the_swap_has_started() {
    let image = image(5000, BOARD);
    let mut bad = signed(&image);
    bad[30] ^= 1;
    let mut dfu = dfu_with(&image, &bad);
    // Erased STATE (BOOT), and BOOT written by mark_booted.
    for magic in [0xFF, BOOT_MAGIC] {
        let mut state = Box::new(StateMem::new(0xFF));
        state.mem[..4].fill(magic);
        let before = state.mem.to_vec();
        assert_eq!(guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD), Guard::NothingToCheck);
        assert_eq!(state.mem.to_vec(), before);
    }
    // SWAP with the first progress word written: a swap under way, its image checked before.
    let mut state = state_swap();
    state.mem[8..12].fill(0);
    assert_eq!(guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD), Guard::NothingToCheck);
    // SWAP with the progress invalidated (a torn mark_booted): not a new request either.
    let mut state = state_swap();
    state.mem[4..8].fill(0);
    assert_eq!(guard_swap(&mut *state, &mut *dfu, TEST_PUBLIC, BOARD), Guard::NothingToCheck);
}

#[test]
fn the_largest_image_is_checked_and_a_longer_length_refused() {
    let image = image(TRAILER_OFFSET as usize, BOARD);
    let mut dfu = dfu_with(&image, &signed(&image));
    assert_eq!(check_dfu(&mut *dfu, TEST_PUBLIC, BOARD).map(|i| i.board_id), Ok(BOARD));
    let mut trailer = signed(&image);
    trailer[8..12].copy_from_slice(&(TRAILER_OFFSET + 1).to_le_bytes());
    let mut dfu = dfu_with(&image, &trailer);
    assert!(matches!(check_dfu(&mut *dfu, TEST_PUBLIC, BOARD), Err(Refusal::Trailer(_))));
    assert_eq!(dfu.capacity(), DFU_SIZE);
}
