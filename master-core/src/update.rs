//! The master's side of a firmware update over DeviceNet: the update object, vendor class 0x6A
//! (the guide's design page, `docs/src/development/firmware-update.md`, "The update object, class
//! 0x6A"), driven through the device's explicit connection.
//!
//! ## The sequence ([`run`])
//!
//! 1. The explicit connection is allocated ([`Master::open_explicit`]); only the master that holds
//!    it can update (the device refuses requests from anyone else: the object is reached only
//!    over the Predefined Master/Slave explicit connection).
//! 2. The device's attributes are read ([`DeviceInfo`]: board ID 7, largest image 6, key ID 8,
//!    state 1, revision 2) and Identity attribute 4, and the file is checked against them before
//!    anything is sent ([`check_file`]): the board ID of the trailer and of the image-info block
//!    against attribute 7, the length against attribute 6, the key ID against attribute 8, and the
//!    signature with the release's public key when one is given.
//! 3. **Update** (0x4B) announces size, board, revision and image ID; the device erases its two
//!    DFU sectors for a new image before it answers ([`UPDATE_TIMEOUT`]), and answers the chunk it
//!    expects next: 0 for a new image, the resume point for the image it already holds in part.
//! 4. **Transfer** (0x4D) carries the 128-byte chunks from there, each answered with its number; a
//!    chunk whose answer does not come is sent again ([`CHUNK_ATTEMPTS`]; the device acknowledges a
//!    repeat of its last chunk without writing it twice), a wrong number is
//!    [`UpdateError::ChunkMismatch`].
//! 5. **Verify** (0x4C) hands over the trailer; the device checks the signature.
//! 6. **Apply** (0x4E): the device answers, then resets into its bootloader, which checks the image
//!    again and swaps it in.
//! 7. The master waits for the device's duplicate MAC ID check ([`BACK_WITHIN`]), allocates the
//!    explicit connection again, reads Identity attribute 4 and class 0x6A attributes 1 and 2, and
//!    reports [`Outcome::Confirmed`], [`Outcome::Trial`] or [`Outcome::RolledBack`].
//!
//! ## Resume
//!
//! Nothing is kept on the master's side: an interrupted run (a stop, a lost device) run again
//! with the same file sends the same Update, and the device answers the first chunk it has not
//! logged; the transfer goes on from there ([`Event::Announced`] says where).
//!
//! ## Errors
//!
//! An error response keeps its general status and additional code, named as the design page names
//! them ([`refusal_text`]); 0x16 (object does not exist) on the first read is
//! [`UpdateError::NotUpdatable`]: the firmware has no update object.

mod file;

pub use file::{check_file, FileError, UpdateFile};
pub use fw_image::Revision;

use crate::client::{Port, ReplyBody};
use crate::decode;
use crate::error::MasterError;
use crate::master::Master;
use devicenet::explicit::{GeneralStatus, Request, ServiceCode};
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{Duration, Instant, MacId};

/// The update object's class (vendor-specific, design page).
pub const CLASS: u16 = 0x6A;
/// Its one instance: the application image.
pub const INSTANCE: u16 = 1;
/// Update: size, board ID, revision, image ID; answers the transfer size and the next chunk.
pub const UPDATE: u8 = 0x4B;
/// Verify: the trailer; answers the state.
pub const VERIFY: u8 = 0x4C;
/// Transfer: chunk number and data; answers the chunk number and the state.
pub const TRANSFER: u8 = 0x4D;
/// Apply: mark the image for the swap and reset.
pub const APPLY: u8 = 0x4E;
/// Bytes per chunk (attribute 5).
pub const CHUNK_SIZE: usize = 128;
/// How long the master waits for the answer to Update, Verify and Apply: Update erases two
/// 128 KiB sectors first (1 s each by the unconfirmed datasheet figures of the design page), Verify
/// hashes up to 130,944 bytes and checks the signature.
pub const UPDATE_TIMEOUT: Duration = Duration::from_secs(10);
/// How often one chunk is sent when its answer does not come in time.
pub const CHUNK_ATTEMPTS: u32 = 3;
/// How long the master waits, from Apply, for the device to come back on-line: the bootloader's
/// check (at least 1.15 s for the largest image at 16 MHz), the swap (two 128 KiB erases and
/// 65,536 word programs, about 3 s by the design page's figures), the firmware's start and its
/// duplicate MAC ID check (2 s), with room to spare.
pub const BACK_WITHIN: Duration = Duration::from_secs(30);
/// How long a device reporting a trial (state 5) is read again before the run reports it as such.
pub const TRIAL_WAIT: Duration = Duration::from_secs(3);
/// How often the master looks for the device's duplicate MAC ID check while it waits.
const WATCH_STEP: Duration = Duration::from_millis(100);
/// After the device's on-line time: a device still checking does not answer yet.
const ONLINE_MARGIN: Duration = Duration::from_millis(250);

/// The update object's attributes the master reads (design page, instance 1).
pub mod attr {
    /// USINT: the object's state ([`super::DeviceState`]).
    pub const STATE: u8 = 1;
    /// USINT, USINT: the running firmware's revision.
    pub const REVISION: u8 = 2;
    /// UDINT: the next chunk expected.
    pub const NEXT_CHUNK: u8 = 4;
    /// UDINT: the largest image.
    pub const LARGEST_IMAGE: u8 = 6;
    /// UINT: the board ID this device accepts.
    pub const BOARD_ID: u8 = 7;
    /// 8 × USINT: the key ID of the bootloader's public key.
    pub const KEY_ID: u8 = 8;
}

/// The update object's state (attribute 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceState {
    /// 0: no update in progress.
    Idle,
    /// 1: chunks arriving.
    Receiving,
    /// 2: every chunk arrived.
    Complete,
    /// 3: the signature checked, ready to apply.
    Verified,
    /// 4: the last request was refused (attribute 9 says why).
    Refused,
    /// 5: running an image not yet confirmed.
    Trial,
    /// 6: the last image never confirmed and was rolled back.
    RolledBack,
    /// A code the design does not define.
    Unknown(u8),
}

impl From<u8> for DeviceState {
    fn from(raw: u8) -> DeviceState {
        match raw {
            0 => DeviceState::Idle,
            1 => DeviceState::Receiving,
            2 => DeviceState::Complete,
            3 => DeviceState::Verified,
            4 => DeviceState::Refused,
            5 => DeviceState::Trial,
            6 => DeviceState::RolledBack,
            other => DeviceState::Unknown(other),
        }
    }
}

impl core::fmt::Display for DeviceState {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DeviceState::Idle => f.write_str("idle"),
            DeviceState::Receiving => f.write_str("receiving"),
            DeviceState::Complete => f.write_str("complete"),
            DeviceState::Verified => f.write_str("verified"),
            DeviceState::Refused => f.write_str("refused"),
            DeviceState::Trial => f.write_str("trial"),
            DeviceState::RolledBack => f.write_str("rolled back"),
            DeviceState::Unknown(c) => write!(f, "unknown state {c}"),
        }
    }
}

/// What the device says about itself before an update.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Attribute 7.
    pub board_id: u16,
    /// Attribute 6.
    pub largest_image: u32,
    /// Attribute 8.
    pub key_id: [u8; 8],
    /// Attribute 1.
    pub state: DeviceState,
    /// Attribute 2: the running firmware.
    pub revision: Revision,
    /// Identity attribute 4 (the description's revision).
    pub identity_revision: Revision,
}

/// An update step, for errors and progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Reading an attribute.
    Read(u16, u8),
    /// Update.
    Update,
    /// Transfer of a chunk.
    Transfer(u32),
    /// Verify.
    Verify,
    /// Apply.
    Apply,
}

impl core::fmt::Display for Step {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Step::Read(c, a) => write!(f, "Get_Attribute_Single class 0x{c:02X} attribute {a}"),
            Step::Update => f.write_str("Update"),
            Step::Transfer(n) => write!(f, "Transfer of chunk {n}"),
            Step::Verify => f.write_str("Verify"),
            Step::Apply => f.write_str("Apply"),
        }
    }
}

/// How an update ended, read from the device after it came back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// The new image runs and confirmed itself (state idle, the file's revision).
    Confirmed,
    /// The new image runs but has not confirmed itself yet (state 5, still after [`TRIAL_WAIT`]).
    Trial,
    /// The new image never confirmed; the bootloader put the old one back (state 6).
    RolledBack,
}

impl core::fmt::Display for Outcome {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Outcome::Confirmed => "confirmed",
            Outcome::Trial => "trial (not confirmed yet)",
            Outcome::RolledBack => "rolled back",
        })
    }
}

/// What the update did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Report {
    /// The device before.
    pub before: DeviceInfo,
    /// The chunk the device asked for first (0: a new transfer, more: resumed).
    pub resumed_at: u32,
    /// Chunks in the image.
    pub chunks: u32,
    /// Chunks sent in this run (first sends).
    pub sent: u32,
    /// Chunks sent again because their answer did not come.
    pub resent: u32,
    /// The firmware revision after (class 0x6A attribute 2).
    pub revision: Revision,
    /// Identity attribute 4 after.
    pub identity_revision: Revision,
    /// The object's state after.
    pub state: DeviceState,
    /// The verdict.
    pub outcome: Outcome,
    /// The MAC's time from Apply to on-line.
    pub back_after: Duration,
}

/// Progress of a run, as it happens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// The file checked against the device.
    Checked,
    /// Update answered: the transfer starts at `next` of `chunks`.
    Announced {
        /// The first chunk to send.
        next: u32,
        /// Chunks in the image.
        chunks: u32,
    },
    /// Chunk `chunk` acknowledged; `bytes` of the image are now at the device.
    Chunk {
        /// The chunk.
        chunk: u32,
        /// Chunks in the image.
        chunks: u32,
        /// Bytes at the device.
        bytes: u64,
    },
    /// A chunk sent again (its answer did not come).
    Resent {
        /// The chunk.
        chunk: u32,
    },
    /// Verify passed.
    Verified,
    /// Apply answered; the device resets.
    Applied,
    /// The device is on-line again.
    Back,
}

/// Why an update stopped.
#[derive(Debug, thiserror::Error)]
pub enum UpdateError {
    /// The bus, a timeout, a stop: what the master's operations give.
    #[error(transparent)]
    Master(#[from] MasterError),
    /// The firmware has no update object (0x16 on class 0x6A).
    #[error("MAC {mac}: this firmware cannot be updated over the network (class 0x6A answers {text})")]
    NotUpdatable {
        /// The device.
        mac: u8,
        /// The error response, decoded.
        text: String,
    },
    /// The file does not fit the device; nothing was sent.
    #[error("{file}: {source}")]
    File {
        /// The file's name.
        file: String,
        /// Why.
        source: FileError,
    },
    /// The device refused a step.
    #[error("{step}: MAC {mac} refused: {text}")]
    Refused {
        /// The device.
        mac: u8,
        /// The step.
        step: Step,
        /// General status.
        general: GeneralStatus,
        /// Additional code.
        additional: u8,
        /// Both by name ([`refusal_text`]).
        text: String,
    },
    /// The device acknowledged another chunk than the one sent.
    #[error("Transfer of chunk {sent}: MAC {mac} acknowledged chunk {acked}")]
    ChunkMismatch {
        /// The device.
        mac: u8,
        /// The chunk sent.
        sent: u32,
        /// The number in the answer.
        acked: u32,
    },
    /// An answer of the wrong form.
    #[error("{step}: MAC {mac} answered {} ({} bytes), expected {expected}", decode::hex(data), data.len())]
    BadAnswer {
        /// The device.
        mac: u8,
        /// The step.
        step: Step,
        /// The answer's data.
        data: Vec<u8>,
        /// What was expected.
        expected: &'static str,
    },
    /// Update answered a chunk size this master does not send, or a resume point past the end.
    #[error("Update: MAC {mac} answered transfer size {size} and next chunk {next} for an image of {chunks} chunks of {CHUNK_SIZE} bytes")]
    Announce {
        /// The device.
        mac: u8,
        /// The transfer size answered.
        size: u16,
        /// The next chunk answered.
        next: u32,
        /// Chunks in the image.
        chunks: u32,
    },
    /// The device did not come back after Apply.
    #[error("MAC {mac} did not come back on-line within {within} of Apply")]
    NotBack {
        /// The device.
        mac: u8,
        /// The bound.
        within: Duration,
    },
    /// The device came back running neither the new image nor a rolled-back old one.
    #[error("after Apply MAC {mac} runs revision {running} in state {state}: the file's revision is {expected}; the image was not applied")]
    NotApplied {
        /// The device.
        mac: u8,
        /// Its revision after.
        running: Revision,
        /// The file's.
        expected: Revision,
        /// Its state after.
        state: DeviceState,
    },
}

/// The name of an update object's refusal (design page, "Refusals"): 0xD0 with additional codes
/// 1–5, 0x16, and every other status by its CIP name: `0x10/0xFF (device state conflict)`.
pub fn refusal_text(general: GeneralStatus, additional: u8) -> String {
    let code = general.as_raw();
    let named = match (code, additional) {
        (0xD0, 1) => Some("bad signature"),
        (0xD0, 2) => Some("another board"),
        (0xD0, 3) => Some("length mismatch"),
        (0xD0, 4) => Some("no image-info block"),
        (0xD0, 5) => Some("another key"),
        (0x16, _) => Some("this firmware cannot be updated over the network"),
        _ => None,
    };
    match named {
        Some(name) => format!("0x{code:02X}/0x{additional:02X} ({name})"),
        None => format!("0x{code:02X}/0x{additional:02X} ({})", general.name().unwrap_or("unknown status")),
    }
}

/// One request to the update object through the explicit connection, an error response turned
/// into [`UpdateError::Refused`].
fn call(
    master: &mut Master<'_, '_>,
    mac: MacId,
    step: Step,
    service: u8,
    data: &[u8],
    slow: bool,
) -> Result<Vec<u8>, UpdateError> {
    let req = Request { service: ServiceCode::from(service), class: CLASS, instance: INSTANCE, data };
    let answer = if slow {
        master.request_served_first(mac, Port::Explicit, &req)?
    } else {
        master.request(mac, Port::Explicit, &req)?
    };
    match answer.reply.body {
        ReplyBody::Success(bytes) => Ok(bytes),
        ReplyBody::Error { general, additional } => {
            let text = refusal_text(general, additional);
            master.judge(answer.record, &format!("refused: {text}"), Vec::new());
            Err(UpdateError::Refused { mac: mac.as_raw(), step, general, additional, text })
        }
    }
}

/// [`call`] with the response timeout [`UPDATE_TIMEOUT`], also for the acknowledge of the
/// request's last fragment: the adapter erases flash before it answers (Update: both DFU
/// sectors, about 2 s with the CPU stalled), and its acknowledge of that fragment leaves with the
/// response ([`Master::request_served_first`]).
fn call_slow(
    master: &mut Master<'_, '_>,
    mac: MacId,
    step: Step,
    service: u8,
    data: &[u8],
) -> Result<Vec<u8>, UpdateError> {
    let usual = master.config.response_timeout;
    master.config.response_timeout = UPDATE_TIMEOUT.max(usual);
    let result = call(master, mac, step, service, data, true);
    master.config.response_timeout = usual;
    result
}

/// Get_Attribute_Single of `class_id` instance `instance`, exactly `N` bytes.
fn read<const N: usize>(
    master: &mut Master<'_, '_>,
    mac: MacId,
    class_id: u16,
    instance: u16,
    attribute: u8,
) -> Result<[u8; N], UpdateError> {
    let step = Step::Read(class_id, attribute);
    let data = [attribute];
    let req = Request { service: ServiceCode::GetAttributeSingle, class: class_id, instance, data: &data };
    let answer = master.request(mac, Port::Explicit, &req)?;
    let bytes = match answer.reply.body {
        ReplyBody::Success(bytes) => bytes,
        ReplyBody::Error { general, additional } => {
            if class_id == CLASS && general == GeneralStatus::ObjectDoesNotExist {
                let text = decode::error_text(general, additional);
                return Err(UpdateError::NotUpdatable { mac: mac.as_raw(), text });
            }
            let text = refusal_text(general, additional);
            return Err(UpdateError::Refused { mac: mac.as_raw(), step, general, additional, text });
        }
    };
    <[u8; N]>::try_from(bytes.as_slice()).map_err(|_| UpdateError::BadAnswer {
        mac: mac.as_raw(),
        step,
        data: bytes.clone(),
        expected: match N {
            1 => "1 byte",
            2 => "2 bytes",
            4 => "4 bytes",
            _ => "8 bytes",
        },
    })
}

/// Reads what the device says about itself (class 0x6A attributes 7, 6, 8, 1, 2; Identity 4).
///
/// # Errors
///
/// [`UpdateError::NotUpdatable`] when the device has no class 0x6A; the master's errors.
pub fn device_info(master: &mut Master<'_, '_>, mac: MacId) -> Result<DeviceInfo, UpdateError> {
    let board_id = u16::from_le_bytes(read::<2>(master, mac, CLASS, INSTANCE, attr::BOARD_ID)?);
    let largest_image = u32::from_le_bytes(read::<4>(master, mac, CLASS, INSTANCE, attr::LARGEST_IMAGE)?);
    let key_id = read::<8>(master, mac, CLASS, INSTANCE, attr::KEY_ID)?;
    let (state, revision, identity_revision) = after_state(master, mac)?;
    Ok(DeviceInfo { board_id, largest_image, key_id, state, revision, identity_revision })
}

/// Class 0x6A attributes 1 and 2, Identity attribute 4.
fn after_state(
    master: &mut Master<'_, '_>,
    mac: MacId,
) -> Result<(DeviceState, Revision, Revision), UpdateError> {
    let [state] = read::<1>(master, mac, CLASS, INSTANCE, attr::STATE)?;
    let [major, minor] = read::<2>(master, mac, CLASS, INSTANCE, attr::REVISION)?;
    let [imajor, iminor] = read::<2>(master, mac, class::IDENTITY, 1, 4)?;
    Ok((DeviceState::from(state), Revision { major, minor }, Revision { major: imajor, minor: iminor }))
}

/// Runs the update of `mac` with `file` (see the [module docs](self)); `progress` sees every
/// [`Event`]. `public_key`: the release's Ed25519 public key, checked against the file's signature
/// before anything is sent.
///
/// # Errors
///
/// [`UpdateError`]: the file refused before sending, the device's refusals, the master's errors
/// (a stop is [`MasterError::Interrupted`]: run again to resume).
pub fn run(
    master: &mut Master<'_, '_>,
    mac: MacId,
    file: &UpdateFile,
    public_key: Option<&[u8; 32]>,
    progress: &mut dyn FnMut(Event),
) -> Result<Report, UpdateError> {
    master.open_explicit(mac)?;
    let before = device_info(master, mac)?;
    check_file(file, &before, public_key)
        .map_err(|source| UpdateError::File { file: file.name.clone(), source })?;
    progress(Event::Checked);

    let chunks = file.chunks();
    let next = announce(master, mac, file, chunks)?;
    progress(Event::Announced { next, chunks });
    let (sent, resent) = transfer(master, mac, file, next, progress)?;

    call_slow(master, mac, Step::Verify, VERIFY, file.trailer_bytes())?;
    progress(Event::Verified);
    call_slow(master, mac, Step::Apply, APPLY, &[])?;
    let applied_at = master.session.now();
    // The reset dropped the device's connections: nothing is left to release.
    master.set_held(mac, AllocationChoice::empty());
    progress(Event::Applied);

    come_back(master, mac, applied_at)?;
    let back_after = master.session.now() - applied_at;
    progress(Event::Back);
    let deadline = master.session.now() + TRIAL_WAIT;
    let (state, revision, identity_revision) = loop {
        let read = after_state(master, mac)?;
        if read.0 != DeviceState::Trial || master.session.now() >= deadline {
            break read;
        }
        let again = master.session.now() + Duration::from_millis(500);
        master.idle_until(again)?;
    };
    let outcome = match state {
        DeviceState::Trial if revision == file.revision => Outcome::Trial,
        DeviceState::RolledBack => Outcome::RolledBack,
        DeviceState::Idle if revision == file.revision => Outcome::Confirmed,
        _ => {
            return Err(UpdateError::NotApplied {
                mac: mac.as_raw(),
                running: revision,
                expected: file.revision,
                state,
            })
        }
    };
    Ok(Report {
        before,
        resumed_at: next,
        chunks,
        sent,
        resent,
        revision,
        identity_revision,
        state,
        outcome,
        back_after,
    })
}

/// Update (0x4B): announces `file` to the device whose explicit connection `master` holds;
/// returns the chunk the device expects first (0 for a new image, the resume point for the image
/// it holds in part). [`run`]'s step 3, on its own for a test that only asks where a transfer
/// would resume.
///
/// # Errors
///
/// A refusal, a timeout, or an answer that is not the 128-byte chunk size and a chunk number
/// within `chunks` ([`UpdateError::Announce`]).
pub fn announce(
    master: &mut Master<'_, '_>,
    mac: MacId,
    file: &UpdateFile,
    chunks: u32,
) -> Result<u32, UpdateError> {
    let mut data = Vec::with_capacity(16);
    data.extend_from_slice(&file.image_len().to_le_bytes());
    data.extend_from_slice(&file.board_id.to_le_bytes());
    data.extend_from_slice(&[file.revision.major, file.revision.minor]);
    data.extend_from_slice(&file.image_id);
    let answer = call_slow(master, mac, Step::Update, UPDATE, &data)?;
    let [s0, s1, n0, n1, n2, n3] =
        <[u8; 6]>::try_from(answer.as_slice()).map_err(|_| UpdateError::BadAnswer {
            mac: mac.as_raw(),
            step: Step::Update,
            data: answer.clone(),
            expected: "6 bytes: transfer size UINT, next chunk UDINT",
        })?;
    let size = u16::from_le_bytes([s0, s1]);
    let next = u32::from_le_bytes([n0, n1, n2, n3]);
    if usize::from(size) != CHUNK_SIZE || next > chunks {
        return Err(UpdateError::Announce { mac: mac.as_raw(), size, next, chunks });
    }
    Ok(next)
}

/// Transfer of chunks `next..`; returns the chunks sent and sent again.
fn transfer(
    master: &mut Master<'_, '_>,
    mac: MacId,
    file: &UpdateFile,
    next: u32,
    progress: &mut dyn FnMut(Event),
) -> Result<(u32, u32), UpdateError> {
    let chunks = file.chunks();
    let (mut sent, mut resent) = (0, 0);
    for n in next..chunks {
        let part = file.chunk(n);
        let mut data = Vec::with_capacity(4 + part.len());
        data.extend_from_slice(&n.to_le_bytes());
        data.extend_from_slice(part);
        let mut attempt = 1;
        let answer = loop {
            match call(master, mac, Step::Transfer(n), TRANSFER, &data, false) {
                Err(UpdateError::Master(MasterError::Timeout { .. })) if attempt < CHUNK_ATTEMPTS => {
                    attempt += 1;
                    resent += 1;
                    progress(Event::Resent { chunk: n });
                }
                other => break other?,
            }
        };
        sent += 1;
        let Ok([a0, a1, a2, a3, _, _]) = <[u8; 6]>::try_from(answer.as_slice()) else {
            return Err(UpdateError::BadAnswer {
                mac: mac.as_raw(),
                step: Step::Transfer(n),
                data: answer,
                expected: "6 bytes: chunk number UDINT, state UINT",
            });
        };
        let acked = u32::from_le_bytes([a0, a1, a2, a3]);
        if acked != n {
            return Err(UpdateError::ChunkMismatch { mac: mac.as_raw(), sent: n, acked });
        }
        let bytes = (u64::from(n) * CHUNK_SIZE as u64 + part.len() as u64).min(u64::from(file.image_len()));
        progress(Event::Chunk { chunk: n, chunks, bytes });
    }
    Ok((sent, resent))
}

/// Waits until `mac`'s duplicate MAC ID check after `applied_at` has passed, then allocates its
/// explicit connection again (repeated while it still checks, until [`BACK_WITHIN`]).
fn come_back(master: &mut Master<'_, '_>, mac: MacId, applied_at: Instant) -> Result<(), UpdateError> {
    let deadline = applied_at + BACK_WITHIN;
    let not_back = UpdateError::NotBack { mac: mac.as_raw(), within: BACK_WITHIN };
    loop {
        let now = master.session.now();
        let online = master.tracker.online_at(mac.as_raw()).filter(|&at| at > applied_at);
        if online.is_some_and(|at| at <= now) {
            break;
        }
        if now >= deadline {
            return Err(not_back);
        }
        let until = online.unwrap_or(now + WATCH_STEP).min(deadline);
        master.idle_until(until)?;
    }
    let settled = master.session.now() + ONLINE_MARGIN;
    master.idle_until(settled)?;
    loop {
        match master.allocate(mac, Port::Group2Only, AllocationChoice::EXPLICIT) {
            Ok(_) => return Ok(()),
            Err(MasterError::Timeout { .. }) if master.session.now() < deadline => continue,
            Err(MasterError::Timeout { .. }) => return Err(not_back),
            Err(e) => return Err(e.into()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::master::MasterConfig;
    use crate::session::Session;
    use can_io::bus::Bitrate;
    use can_io::sim::{PowerOn, SimBus};
    use converter_sim::SoftSlave;
    use rstest::rstest;

    #[rstest]
    #[case::bad_signature(0xD0, 1, "0xD0/0x01 (bad signature)")]
    #[case::another_board(0xD0, 2, "0xD0/0x02 (another board)")]
    #[case::length(0xD0, 3, "0xD0/0x03 (length mismatch)")]
    #[case::no_info(0xD0, 4, "0xD0/0x04 (no image-info block)")]
    #[case::another_key(0xD0, 5, "0xD0/0x05 (another key)")]
    #[case::not_updatable(0x16, 0xFF, "0x16/0xFF (this firmware cannot be updated over the network)")]
    #[case::io(0x10, 0xFF, "0x10/0xFF (device state conflict)")]
    fn refusals_keep_their_codes_with_names(#[case] general: u8, #[case] additional: u8, #[case] text: &str) {
        assert_eq!(refusal_text(GeneralStatus::from(general), additional), text);
    }

    #[test]
    fn a_device_without_the_update_object_cannot_be_updated() {
        let mac = MacId::new(5).unwrap();
        let mut bus = SimBus::new(Bitrate::K250);
        bus.attach(Box::new(SoftSlave::reference(mac)), PowerOn::WhenMasterOnline);
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        let bytes = file::tests::signed(1000, 5);
        let file = UpdateFile::parse("f.bin", bytes).unwrap();
        let mut events = Vec::new();
        let err = run(&mut master, mac, &file, None, &mut |e| events.push(e)).unwrap_err();
        assert!(
            matches!(&err, UpdateError::NotUpdatable { mac: 5, text } if text.starts_with("object does not exist")),
            "{err}"
        );
        assert!(events.is_empty(), "nothing announced: {events:?}");
        assert_eq!(session.failures(), 0);
    }
}
