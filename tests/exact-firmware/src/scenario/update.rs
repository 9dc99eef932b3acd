//! `firmware-update` (every board; issue 31): the whole update over the bus, as
//! `dnet-master firmware-update` runs it. `master-core`'s update client
//! (`master_core::update::run`) drives the emulated board in virtual time with the board's
//! firmware built at revision 9.8 (`DNET_FW_REVISION`; scripts/exact-firmware keeps it beside the
//! firmware ELF as `<elf>-newer`: the firmware reports the revision it was built with, so an image
//! with only its image-info block changed would not do), signed with the TEST key: Update, the Transfers, Verify, Apply; the device resets; the bootloader checks and swaps;
//! the new image comes on-line and confirms. The client must report the new revision (class 0x6A
//! attribute 2) and `confirmed`; STATE says BOOT and ACTIVE holds the new image byte for byte.
//! Then a power cycle: the new image comes up again with no flash operation at all. The FLASH
//! model runs at the datasheet's times (`FlashTiming::DATASHEET`), the core stalled through each
//! erase as code in flash is on the chip: Update's two 128 KiB erases hold back its last
//! fragment's acknowledge about 2 s (the client waits for it), and Apply's STATE erase stops the
//! firmware's clock, so its reset comes after its response has left.

use super::dfu::{active_holds, dfu_holds, newer_file, state, NewerFile, BOOT_MAGIC, TEST_PUBLIC_KEY};
use super::world::{with_master, Handle, Options};
use crate::board::BoardKind;
use crate::device::{EmulatedBoard, Firmware};
use board::flash_layout::{DFU, MAX_IMAGE_LEN};
use can_io::sim::PowerOn;
use master_core::update::{self, Outcome};
use std::cell::RefCell;
use std::rc::Rc;

/// The scenario; see the module docs.
pub fn firmware_update(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let Timed { handle, report, new, trailer, .. } = timed_update(board, elf, options)?;
    if report.outcome != Outcome::Confirmed || report.revision != trailer.revision {
        return Err(format!(
            "the client reports {} at revision {:?}, not confirmed at {:?}",
            report.outcome, report.revision, trailer.revision
        ));
    }
    if report.sent != report.chunks || report.resumed_at != 0 {
        return Err(format!(
            "{} of {} chunks sent, from chunk {}",
            report.sent, report.chunks, report.resumed_at
        ));
    }
    let state = state(&handle);
    if state != [BOOT_MAGIC; 4] || !active_holds(&handle, &new) {
        return Err(format!(
            "after the update: STATE {state:02x?} (want BOOT), ACTIVE the new image: {}",
            active_holds(&handle, &new)
        ));
    }
    let operations = handle.borrow().flash_operations();
    let info = with_master(&handle, options, PowerOn::WhenMasterOnline, |master| {
        master
            .open_explicit(options.setting.mac)
            .map_err(update::UpdateError::from)
            .and_then(|()| update::device_info(master, options.setting.mac))
            .map_err(|e| format!("after the power cycle: {e}"))
    })?;
    if info.revision != report.revision {
        return Err(format!(
            "after the power cycle the revision is {:?}, not {:?}",
            info.revision, report.revision
        ));
    }
    let after = handle.borrow().flash_operations();
    if after != operations || !active_holds(&handle, &new) {
        return Err(format!(
            "the power cycle took {} flash operations (want 0); ACTIVE the new image: {}",
            after - operations,
            active_holds(&handle, &new)
        ));
    }
    Ok(())
}

/// An update run by [`timed_update`].
pub struct Timed {
    /// The board, updated.
    pub handle: Handle,
    /// The client's report.
    pub report: update::Report,
    /// The bus time of the client's whole run (`master_core::update::run`: the device's
    /// attributes read, Update, the chunks, Verify, Apply, the device back and confirmed).
    pub elapsed: devicenet::Duration,
    /// The new image.
    pub new: Vec<u8>,
    /// Its trailer.
    pub trailer: fw_image::Trailer,
}

/// Connects to a new `board` at `options.bus_rate` and updates it to its `<elf>-newer` build over
/// the bus; the figure of the update time (benches/update_time.rs) and the scenario's first half.
pub fn timed_update(board: BoardKind, elf: &Firmware, options: &Options) -> Result<Timed, String> {
    let NewerFile { image: new, trailer, file } = newer_file(elf)?;
    let device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    let handle = Rc::new(RefCell::new(device));
    let (report, elapsed) = with_master(&handle, options, PowerOn::WhenMasterOnline, |master| {
        let start = master.session.now();
        let report = update::run(master, options.setting.mac, &file, Some(TEST_PUBLIC_KEY), &mut |_| {})
            .map_err(|e| format!("the update: {e} ({})", flash_facts(&handle, &new, &trailer.to_bytes())))?;
        Ok((report, master.session.now().saturating_duration_since(start)))
    })?;
    Ok(Timed { handle, report, elapsed, new, trailer })
}

/// What STATE, DFU and ACTIVE hold, for a failure's message.
fn flash_facts(handle: &super::world::Handle, new: &[u8], trailer: &[u8]) -> String {
    let dfu_trailer = handle.borrow().mcu_flash(DFU.base + MAX_IMAGE_LEN, trailer.len());
    format!(
        "STATE {:02x?}, DFU the new image: {}, DFU's trailer the file's: {}, ACTIVE the new image: {}, {} watchdog resets",
        state(handle),
        dfu_holds(handle, new),
        dfu_trailer == trailer,
        active_holds(handle, new),
        handle.borrow().watchdog_resets()
    )
}
