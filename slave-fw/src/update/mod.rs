//! The firmware update object, vendor class [`UPDATE_CLASS`] 0x6A, instance 1: a master sends a
//! signed image in 128-byte chunks over the explicit connection, the device checks it, and
//! Apply hands it to the bootloader. Ours, not a spec object; the design and the reasons are
//! `docs/src/development/firmware-update.md` ("The update object, class 0x6A"), the reference
//! is protocol §6.5 (`docs/src/protocol/objects.md`).
//!
//! [`UpdateObject`] is generic over the DFU flash (`embedded_storage`'s `NorFlash`, offset 0 =
//! the start of DFU: the image in the first 128 KiB page, the chunk log in the second) and over
//! [`MarkUpdated`], what Apply does: the firmware marks the image for embassy-boot's swap, the
//! soft slave writes files. The old firmware keeps running, and serving its master, until Apply.
//!
//! | service | request | response | refused with |
//! |---|---|---|---|
//! | 0x0E Get_Attribute_Single | attribute | the value ([`UpdateObject`] lists them) | 0x14, 0x13, 0x15 |
//! | 0x4B Update | size UDINT, board ID UINT, revision 2 × USINT, image ID 8 bytes | transfer size UINT (128), next chunk UDINT | 0x10, 0x15, 0x20, 0xD0/2, 0x19 |
//! | 0x4D Transfer | chunk number UDINT, the chunk | chunk number UDINT, state UINT | 0x10, 0x0C, 0x20, 0x13, 0x19 |
//! | 0x4C Verify | the 128-byte trailer | state UINT | 0x10, 0x0C, 0x20, 0xD0/1–5, 0x19 |
//! | 0x4E Apply | none | none; the reset follows [`RESET_DELAY`] later ([`UpdateObject::poll_reset`]) | 0x10, 0x0C, 0x19 |
//!
//! Only the master that owns the explicit connection reaches the object: the node passes only
//! requests of the Predefined Master/Slave explicit connection to the converter's objects (the
//! Group 2 Only port serves the DeviceNet object alone). The session belongs to that
//! connection: its release or deletion ([`UpdateObject::on_event`]) ends it, keeping the flash
//! and the log for a resume.
//!
//! No input can make it panic: every request field is checked, every flash access is bounded.

mod dfu;
#[cfg(test)]
mod tests;

pub use dfu::GeometryError;

use crate::converter::{ApplicationObject, RESET_DELAY};
use devicenet::explicit::{GeneralStatus, Request, ServiceCode};
use devicenet::messages::AllocationChoice;
use devicenet::slave::{ConnectionKind, Event, Reply, ServiceError};
use devicenet::Instant;
use dfu::{Dfu, DfuError, LogHeader};
use embedded_storage::nor_flash::NorFlash;
use fw_image::{verify_digest, ImageInfo, KeyId, Revision, Trailer, VerifyError, INFO_LEN, INFO_OFFSET};

/// The update object's vendor-specific class.
pub const UPDATE_CLASS: u16 = 0x6A;
/// The bytes of one Transfer (the last one carries the rest).
pub const CHUNK_SIZE: usize = 128;
/// One DFU page: a 128 KiB flash sector.
pub const PAGE_SIZE: usize = 128 * 1024;
/// The largest image (attribute 6): the page less the trailer.
pub const MAX_IMAGE_LEN: u32 = fw_image::MAX_IMAGE_LEN as u32;
/// The highest instance attribute.
pub const LAST_ATTRIBUTE: u8 = 10;

/// Service codes of the object (0x4B–0x4E are object-specific; protocol §3.2).
pub mod service {
    /// Update: announce an image.
    pub const UPDATE: u8 = 0x4B;
    /// Verify: check the received image against its trailer.
    pub const VERIFY: u8 = 0x4C;
    /// Transfer: one chunk.
    pub const TRANSFER: u8 = 0x4D;
    /// Apply: mark the image for the bootloader and reset.
    pub const APPLY: u8 = 0x4E;
}

/// The class-specific general status of the object's refusals.
pub const CLASS_SPECIFIC: u8 = 0xD0;

/// The additional codes with [`CLASS_SPECIFIC`] (attribute 9 keeps the last).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Refusal {
    /// The signature does not match the image.
    BadSignature = 1,
    /// The image is for another board.
    AnotherBoard = 2,
    /// The trailer's length is not the announced size.
    LengthMismatch = 3,
    /// The image has no valid image-info block.
    NoImageInfo = 4,
    /// The image is signed with another key than the bootloader's.
    AnotherKey = 5,
}

impl Refusal {
    /// The error response.
    pub const fn error(self) -> ServiceError {
        ServiceError::with_additional(GeneralStatus::Unknown(CLASS_SPECIFIC), self as u8)
    }
}

/// Attribute 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum UpdateState {
    /// No update under way.
    Idle = 0,
    /// An image is announced and chunks are arriving.
    Receiving = 1,
    /// Every chunk arrived.
    Complete = 2,
    /// The image passed Verify: ready to apply.
    Verified = 3,
    /// The last Update or Verify was refused (attribute 9 says why).
    Refused = 4,
    /// Running an image on trial, not confirmed yet.
    Trial = 5,
    /// The last image never confirmed and was rolled back.
    RolledBack = 6,
}

/// How the running image was started (the bootloader's STATE, read at start).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BootState {
    /// A confirmed image (also: no bootloader).
    Confirmed,
    /// A new image on trial: it confirms once on-line ([`UpdateObject::confirm`]).
    Trial,
    /// The bootloader rolled the last image back.
    RolledBack,
}

/// What the device tells the object about itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Platform {
    /// The board ID this device accepts (attribute 7).
    pub board_id: u16,
    /// The running firmware's revision (attribute 2).
    pub running: Revision,
    /// The bootloader's public key (attribute 8 is its [`KeyId`]).
    pub public_key: [u8; 32],
    /// The bootloader's revision (attribute 10).
    pub bootloader: Revision,
    /// How the running image was started.
    pub boot: BootState,
}

/// Apply's work: mark the verified image in DFU for the bootloader. The reset follows.
pub trait MarkUpdated {
    /// Marks the image of `trailer.image_len` bytes, which Verify accepted, for the swap (the
    /// firmware: embassy-boot's `mark_updated`; the bootloader checks the image again before it
    /// swaps it in).
    ///
    /// # Errors
    /// Anything that failed; the master gets 0x19 and the old image keeps running.
    fn mark_updated(&mut self, trailer: &Trailer) -> Result<(), MarkError>;
}

/// Apply could not mark the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MarkError;

/// The session of one announced image.
#[derive(Clone, Copy, Debug)]
struct Session {
    header: LogHeader,
    /// The next chunk expected.
    next: u32,
    /// The trailer Verify accepted.
    verified: Option<Trailer>,
}

impl Session {
    fn chunks(&self) -> u32 {
        self.header.size.div_ceil(CHUNK_SIZE as u32)
    }
}

/// The update object. See the [module docs](self).
///
/// Instance attributes (Get only; Set answers 0x0E for 1–10, 0x14 otherwise):
///
/// | attr | type | value |
/// |---|---|---|
/// | 1 | USINT | [`UpdateState`] |
/// | 2 | USINT, USINT | the running firmware's revision |
/// | 3 | UDINT | the announced size (0 without a session) |
/// | 4 | UDINT | the next chunk expected |
/// | 5 | UINT | 128 |
/// | 6 | UDINT | [`MAX_IMAGE_LEN`] |
/// | 7 | UINT | the board ID accepted |
/// | 8 | 8 × USINT | the key ID of the bootloader's public key |
/// | 9 | USINT, USINT | the last refusal: service, additional code (0, 0 before any) |
/// | 10 | USINT, USINT | the bootloader's revision |
pub struct UpdateObject<F, M> {
    dfu: Dfu<F>,
    mark: M,
    platform: Platform,
    session: Option<Session>,
    /// The last class-specific refusal made the state [`UpdateState::Refused`].
    refused: bool,
    last_refusal: (u8, u8),
    /// A torn chunk was found: the next Update starts the image over.
    restart: bool,
    /// Apply succeeded: reset at this time.
    reset_at: Option<Instant>,
}

impl<F: NorFlash, M: MarkUpdated> UpdateObject<F, M> {
    /// The object over the DFU `flash` (offset 0 = the start of DFU).
    ///
    /// # Errors
    /// [`GeometryError`] when the flash's sizes do not fit the layout.
    pub fn new(flash: F, mark: M, platform: Platform) -> Result<Self, GeometryError> {
        Ok(Self {
            dfu: Dfu::new(flash)?,
            mark,
            platform,
            session: None,
            refused: false,
            last_refusal: (0, 0),
            restart: false,
            reset_at: None,
        })
    }

    /// The flash and the Apply hook back.
    pub fn into_parts(self) -> (F, M) {
        (self.dfu.into_flash(), self.mark)
    }

    /// The Apply hook.
    pub fn mark(&self) -> &M {
        &self.mark
    }

    /// Attribute 1.
    pub fn state(&self) -> UpdateState {
        match self.session {
            Some(Session { verified: Some(_), .. }) => UpdateState::Verified,
            Some(s) if s.next >= s.chunks() => UpdateState::Complete,
            Some(_) => UpdateState::Receiving,
            None if self.refused => UpdateState::Refused,
            None => match self.platform.boot {
                BootState::Confirmed => UpdateState::Idle,
                BootState::Trial => UpdateState::Trial,
                BootState::RolledBack => UpdateState::RolledBack,
            },
        }
    }

    /// The running image confirmed itself (on-line): a trial ends.
    pub fn confirm(&mut self) {
        if self.platform.boot == BootState::Trial {
            self.platform.boot = BootState::Confirmed;
        }
    }

    /// Ends the session when the explicit connection goes (its release or deletion); the flash
    /// and the log stay for a resume.
    pub fn on_event(&mut self, event: &Event) {
        let explicit_gone = match event {
            Event::Released { choice, .. } => choice.contains(AllocationChoice::EXPLICIT),
            Event::ConnectionDeleted(kind) | Event::ConnectionTimedOut(kind) => {
                *kind == ConnectionKind::Explicit
            }
            _ => false,
        };
        if explicit_gone {
            self.session = None;
        }
    }

    /// `true` once, when an accepted Apply's reset is due.
    pub fn poll_reset(&mut self, now: Instant) -> bool {
        match self.reset_at {
            Some(at) if now >= at => {
                self.reset_at = None;
                true
            }
            _ => false,
        }
    }

    /// When [`UpdateObject::poll_reset`] will next say `true`.
    pub fn poll_at(&self) -> Option<Instant> {
        self.reset_at
    }

    /// Serves a request to instance 1 (class instance 0 is the node's).
    pub fn serve(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        io_established: bool,
        now: Instant,
    ) -> Result<(), ServiceError> {
        if req.instance != 1 {
            return Err(ServiceError::OBJECT_DOES_NOT_EXIST);
        }
        let raw = req.service.as_raw();
        let result = match (raw, req.service) {
            (_, ServiceCode::GetAttributeSingle) => return self.get_attribute(req.data, reply),
            (_, ServiceCode::SetAttributeSingle) => {
                return Err(match req.data.first() {
                    Some(1..=LAST_ATTRIBUTE) => ServiceError::ATTRIBUTE_NOT_SETTABLE,
                    Some(_) => ServiceError::ATTRIBUTE_NOT_SUPPORTED,
                    None => ServiceError::NOT_ENOUGH_DATA,
                })
            }
            (service::UPDATE | service::TRANSFER | service::VERIFY | service::APPLY, _) if io_established => {
                // protocol §6.5: no update while an I/O connection runs the device.
                Err(ServiceError::DEVICE_STATE_CONFLICT)
            }
            (service::UPDATE, _) => self.update(req.data, reply),
            (service::TRANSFER, _) => self.transfer(req.data, reply),
            (service::VERIFY, _) => self.verify(req.data, reply),
            (service::APPLY, _) => self.apply(req.data, now),
            _ => return Err(ServiceError::SERVICE_NOT_SUPPORTED),
        };
        if let Err(e) = result {
            self.last_refusal = (raw, e.additional);
            if e.general == GeneralStatus::Unknown(CLASS_SPECIFIC) {
                self.refused = true;
                self.session = None;
            }
        }
        result
    }

    fn get_attribute(&self, data: &[u8], reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let &[id] = data else { return Err(ServiceError::wrong_length(data, 1)) };
        let p = &self.platform;
        let session = self.session.as_ref();
        match id {
            1 => reply.u8(self.state() as u8),
            2 => reply.bytes(&[p.running.major, p.running.minor]),
            3 => reply.u32(session.map_or(0, |s| s.header.size)),
            4 => reply.u32(session.map_or(0, |s| s.next)),
            5 => reply.u16(CHUNK_SIZE as u16),
            6 => reply.u32(MAX_IMAGE_LEN),
            7 => reply.u16(p.board_id),
            8 => reply.bytes(&KeyId::of(&p.public_key).0),
            9 => reply.bytes(&[self.last_refusal.0, self.last_refusal.1]),
            10 => reply.bytes(&[p.bootloader.major, p.bootloader.minor]),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    fn update(&mut self, data: &[u8], reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        if self.platform.boot == BootState::Trial {
            // The running image must confirm before another replaces it.
            return Err(ServiceError::DEVICE_STATE_CONFLICT);
        }
        let fields: &[u8; 16] = data.try_into().map_err(|_| ServiceError::wrong_length(data, 16))?;
        let [s0, s1, s2, s3, b0, b1, _major, _minor, id @ ..] = *fields;
        let header = LogHeader { size: u32::from_le_bytes([s0, s1, s2, s3]), image_id: id };
        if header.size > MAX_IMAGE_LEN {
            return Err(ServiceError::TOO_MUCH_DATA);
        }
        if header.size == 0 {
            return Err(ServiceError::INVALID_PARAMETER);
        }
        if u16::from_le_bytes([b0, b1]) != self.platform.board_id {
            return Err(Refusal::AnotherBoard.error());
        }
        self.session = None;
        let chunks = header.size.div_ceil(CHUNK_SIZE as u32);
        let resume = !self.restart && self.dfu.header().map_err(store_failure)? == Some(header);
        let next = if resume {
            self.dfu.first_unlogged(chunks).map_err(store_failure)?
        } else {
            self.dfu.start(header).map_err(store_failure)?;
            0
        };
        self.restart = false;
        self.refused = false;
        self.session = Some(Session { header, next, verified: None });
        reply.u16(CHUNK_SIZE as u16)?;
        reply.u32(next)
    }

    fn transfer(&mut self, data: &[u8], reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let Some(session) = self.session.as_mut() else {
            return Err(ServiceError::OBJECT_STATE_CONFLICT);
        };
        let Some((number, chunk)) = data.split_first_chunk::<4>() else {
            return Err(ServiceError::NOT_ENOUGH_DATA);
        };
        let n = u32::from_le_bytes(*number);
        let chunks = session.chunks();
        // Only the chunk expected next, or a repeat of the last one (its answer was lost).
        let repeat = n.checked_add(1) == Some(session.next);
        if (n != session.next && !repeat) || n >= chunks {
            return Err(ServiceError::INVALID_PARAMETER);
        }
        let start = n as usize * CHUNK_SIZE;
        let expected_len = (session.header.size as usize - start).min(CHUNK_SIZE);
        if chunk.len() != expected_len {
            return Err(ServiceError::INVALID_PARAMETER);
        }
        if !repeat {
            match self.dfu.program_chunk(n, chunk) {
                Ok(()) => session.next = n + 1,
                Err(e) => {
                    if e == DfuError::Torn {
                        self.restart = true;
                    }
                    self.session = None;
                    return Err(store_failure(e));
                }
            }
            session.verified = None;
        }
        let state = self.state() as u16;
        reply.u32(n)?;
        reply.u16(state)
    }

    fn verify(&mut self, data: &[u8], reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let Some(session) = self.session else {
            return Err(ServiceError::OBJECT_STATE_CONFLICT);
        };
        if session.next < session.chunks() {
            return Err(ServiceError::OBJECT_STATE_CONFLICT);
        }
        let trailer = match data.len() {
            n if n < fw_image::TRAILER_LEN => return Err(ServiceError::NOT_ENOUGH_DATA),
            n if n > fw_image::TRAILER_LEN => return Err(ServiceError::TOO_MUCH_DATA),
            _ => Trailer::parse(data).map_err(|_| ServiceError::INVALID_PARAMETER)?,
        };
        if trailer.image_len != session.header.size {
            return Err(Refusal::LengthMismatch.error());
        }
        let mut block = [0u8; INFO_LEN];
        if (session.header.size as usize) < INFO_OFFSET + INFO_LEN {
            return Err(Refusal::NoImageInfo.error());
        }
        self.dfu.read(INFO_OFFSET as u32, &mut block).map_err(store_failure)?;
        let info = ImageInfo::from_bytes(&block).map_err(|_| Refusal::NoImageInfo.error())?;
        if info.board_id != self.platform.board_id || trailer.board_id != info.board_id {
            return Err(Refusal::AnotherBoard.error());
        }
        if trailer.revision != info.revision {
            return Err(ServiceError::INVALID_PARAMETER);
        }
        let (digest, len) = self.dfu.hash(session.header.size).map_err(store_failure)?;
        verify_digest(&digest, len, &trailer, &self.platform.public_key).map_err(|e| match e {
            VerifyError::LengthMismatch { .. } => Refusal::LengthMismatch.error(),
            VerifyError::AnotherKey { .. } => Refusal::AnotherKey.error(),
            VerifyError::BadPublicKey | VerifyError::BadSignature => Refusal::BadSignature.error(),
        })?;
        self.dfu.store_trailer(&trailer).map_err(store_failure)?;
        self.session = Some(Session { verified: Some(trailer), ..session });
        reply.u16(UpdateState::Verified as u16)
    }

    fn apply(&mut self, data: &[u8], now: Instant) -> Result<(), ServiceError> {
        if !data.is_empty() {
            return Err(ServiceError::TOO_MUCH_DATA);
        }
        let Some(Session { verified: Some(trailer), .. }) = self.session else {
            return Err(ServiceError::OBJECT_STATE_CONFLICT);
        };
        self.mark.mark_updated(&trailer).map_err(|MarkError| store_failure(DfuError::Flash))?;
        self.reset_at = Some(now + RESET_DELAY);
        Ok(())
    }
}

/// 0x19 store operation failure.
fn store_failure(_: DfuError) -> ServiceError {
    ServiceError::new(GeneralStatus::StoreOperationFailure)
}

impl<F: NorFlash, M: MarkUpdated> ApplicationObject for UpdateObject<F, M> {
    fn handle(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        io_established: bool,
        now: Instant,
    ) -> Option<Result<(), ServiceError>> {
        (req.class == UPDATE_CLASS).then(|| self.serve(req, reply, io_established, now))
    }

    fn class_revision(&self, class: u16) -> Option<u16> {
        (class == UPDATE_CLASS).then_some(1)
    }
}
