//! `update-object` (every board; issue 31): the firmware serves the update object, class 0x6A
//! instance 1, over the master's explicit connection, with the values of its board and its
//! bootloader: attribute 5 the chunk size (128), 6 the largest image (130,944 bytes: ACTIVE's
//! 128 KiB less the 128-byte trailer), 7 the board's ID (`board::boards`), 8 the key ID of the
//! public key in the bootloader's key block, here the repository's TEST key (the runner's
//! bootloader is built with `--test-key`). A quick check that the object is wired in; the update
//! itself is the update scenarios'.

use super::dfu::TEST_PUBLIC_KEY;
use super::world::{machine_fault, master_checks, world, Options, MAC};
use crate::board::BoardKind;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use fw_image::KeyId;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;

/// The update object's class (the design page, "The update object, class 0x6A").
const UPDATE_CLASS: u16 = 0x6A;
/// Attribute 5: the bytes of one Transfer.
const CHUNK_SIZE: u16 = 128;
/// Attribute 6: ACTIVE's 128 KiB less the 128-byte trailer.
const MAX_IMAGE_LEN: u32 = 128 * 1024 - 128;

/// The scenario; see the module docs.
pub fn update_object(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let opened = master.open_explicit(MAC);
    machine_fault(&handle)?;
    opened.map_err(|e| format!("open the explicit connection: {e}"))?;
    let want: [(u8, Vec<u8>); 4] = [
        (5, CHUNK_SIZE.to_le_bytes().to_vec()),
        (6, MAX_IMAGE_LEN.to_le_bytes().to_vec()),
        (7, board.spec.board_id.to_le_bytes().to_vec()),
        (8, KeyId::of(TEST_PUBLIC_KEY).0.to_vec()),
    ];
    for (attribute, want) in want {
        let got = master.get(MAC, UPDATE_CLASS, 1, attribute);
        machine_fault(&handle)?;
        let (got, _) = got.map_err(|e| format!("class 0x6A attribute {attribute}: {e}"))?;
        if got != want {
            return Err(format!("class 0x6A attribute {attribute} is {got:02x?}, not {want:02x?}"));
        }
    }
    master_checks(master.session)
}
