//! `--firmware-dir DIR`: the firmware update object (class 0x6A, [`slave_fw::update`]) served by
//! the soft slave, with files standing in for the board's flash and bootloader.
//!
//! | file | the board's |
//! |---|---|
//! | `DIR/dfu.bin` | the DFU flash, sectors 6 and 7 (256 KiB: the incoming image and its trailer, then the chunk log), created erased (0xFF) |
//! | `DIR/active.bin` | ACTIVE: the applied image followed by its 128-byte trailer |
//!
//! **How the soft slave stands in for the bootloader.** Apply writes the verified image and its
//! trailer to `active.bin` (atomically: a temporary file renamed over the old one), answers, and
//! [`slave_fw::converter::RESET_DELAY`] later the soft slave goes off-line and comes back as
//! after an Identity Reset (duplicate MAC ID check), now "running" the new image: attribute 2
//! reports its revision and attribute 1 state 5 (trial) until it is on-line again, when it
//! confirms itself (state 0) as the firmware does with `mark_booted`. The process keeps running
//! its own code throughout; only the reported revision changes. At start, the revision is that of
//! `active.bin` when the file holds a whole image (its image-info block), else the soft slave's
//! own Cargo version (major, minor). There is no swap and no rollback: a soft slave never runs
//! an image on trial across a restart.
//!
//! The public key is a file of 32 raw bytes (`--firmware-key`; the repository's TEST key is
//! `contrib/keys/test-ed25519.public`), the board ID `--firmware-board-id` (default 1, the
//! reference adapter the soft slave emulates).

use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};
use fw_image::{ImageInfo, Revision, Trailer, TRAILER_LEN};
use slave_fw::update::{BootState, MarkError, MarkUpdated, Platform, UpdateObject, PAGE_SIZE};
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// The DFU file's size: two 128 KiB pages.
pub const DFU_LEN: u64 = 2 * PAGE_SIZE as u64;

/// The board ID the soft slave accepts unless told otherwise: the reference adapter's.
pub const DEFAULT_BOARD_ID: u16 = 1;

/// What went wrong with the firmware directory.
#[derive(Debug, thiserror::Error)]
pub enum FirmwareDirError {
    /// A file could not be opened, read or written.
    #[error("firmware directory: {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The DFU file exists with another size.
    #[error("firmware directory: {path} is {len} bytes, a DFU file is 262144")]
    DfuSize {
        /// The file.
        path: PathBuf,
        /// Its size.
        len: u64,
    },
    /// The key file is not 32 bytes.
    #[error("firmware key {path}: {len} bytes, an Ed25519 public key is 32 raw bytes")]
    KeySize {
        /// The file.
        path: PathBuf,
        /// Its size.
        len: usize,
    },
    /// The DFU file's geometry does not suit the update object (a bug: it is fixed here).
    #[error("firmware directory: {0}")]
    Geometry(#[from] slave_fw::update::GeometryError),
}

/// The DFU flash as a file: NOR semantics (erase to 0xFF, a write ANDs), 128 KiB erase, word
/// writes.
pub struct FileFlash {
    file: File,
}

/// A file operation failed (the path is in the [`FirmwareDirError`] at open; the update object
/// answers 0x19 for any of these).
#[derive(Debug)]
pub struct FileFlashError;

impl NorFlashError for FileFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::Other
    }
}

impl ErrorType for FileFlash {
    type Error = FileFlashError;
}

impl ReadNorFlash for FileFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.file.read_exact_at(bytes, u64::from(offset)).map_err(|_| FileFlashError)
    }

    fn capacity(&self) -> usize {
        DFU_LEN as usize
    }
}

impl NorFlash for FileFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if to < from || u64::from(to) > DFU_LEN {
            return Err(FileFlashError);
        }
        let erased = vec![0xFFu8; (to - from) as usize];
        self.file.write_all_at(&erased, u64::from(from)).map_err(|_| FileFlashError)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        if u64::from(offset) + bytes.len() as u64 > DFU_LEN {
            return Err(FileFlashError);
        }
        // A program only clears bits (NOR flash).
        let mut have = vec![0u8; bytes.len()];
        self.read(offset, &mut have)?;
        for (h, b) in have.iter_mut().zip(bytes) {
            *h &= b;
        }
        // Synced, so that a chunk is on disk before its log word: a host crash never leaves a
        // logged chunk that is not there.
        self.file.write_all_at(&have, u64::from(offset)).map_err(|_| FileFlashError)?;
        self.file.sync_data().map_err(|_| FileFlashError)
    }
}

impl FileFlash {
    /// Opens `DIR/dfu.bin`, creating it erased.
    pub fn open(dir: &Path) -> Result<FileFlash, FirmwareDirError> {
        let path = dir.join("dfu.bin");
        let io = |source| FirmwareDirError::Io { path: path.clone(), source };
        let file =
            OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        match len {
            0 => file.write_all_at(&vec![0xFF; DFU_LEN as usize], 0).map_err(io)?,
            DFU_LEN => {}
            len => return Err(FirmwareDirError::DfuSize { path, len }),
        }
        Ok(FileFlash { file })
    }
}

/// Apply: the image from `dfu.bin` and its trailer written to `active.bin`.
pub struct FileApply {
    dir: PathBuf,
}

impl MarkUpdated for FileApply {
    fn mark_updated(&mut self, trailer: &Trailer) -> Result<(), MarkError> {
        self.write_active(trailer).map_err(|_| MarkError)
    }
}

impl FileApply {
    fn write_active(&self, trailer: &Trailer) -> std::io::Result<()> {
        let mut image = vec![0u8; trailer.image_len as usize];
        File::open(self.dir.join("dfu.bin"))?.read_exact(&mut image)?;
        image.extend_from_slice(&trailer.to_bytes());
        let tmp = self.dir.join("active.bin.tmp");
        let mut f = File::create(&tmp)?;
        f.write_all(&image)?;
        f.sync_all()?;
        std::fs::rename(&tmp, self.dir.join("active.bin"))?;
        File::open(&self.dir)?.sync_all()
    }
}

/// The update object over the firmware directory.
pub type SoftUpdate = UpdateObject<FileFlash, FileApply>;

/// The firmware directory's settings (`--firmware-dir`, `--firmware-key`, `--firmware-board-id`).
#[derive(Clone, Debug)]
pub struct FirmwareDir {
    dir: PathBuf,
    public_key: [u8; 32],
    board_id: u16,
}

impl FirmwareDir {
    /// The directory `dir` (created if missing) with the key read from `key`.
    pub fn new(dir: &Path, key: &Path, board_id: u16) -> Result<FirmwareDir, FirmwareDirError> {
        std::fs::create_dir_all(dir)
            .map_err(|source| FirmwareDirError::Io { path: dir.to_path_buf(), source })?;
        let bytes =
            std::fs::read(key).map_err(|source| FirmwareDirError::Io { path: key.to_path_buf(), source })?;
        let public_key = <[u8; 32]>::try_from(bytes.as_slice())
            .map_err(|_| FirmwareDirError::KeySize { path: key.to_path_buf(), len: bytes.len() })?;
        Ok(FirmwareDir { dir: dir.to_path_buf(), public_key, board_id })
    }

    /// The revision the soft slave runs: `active.bin`'s when it holds an image with its trailer,
    /// else the package version.
    pub fn running(&self) -> Revision {
        self.active_revision().unwrap_or_else(own_revision)
    }

    fn active_revision(&self) -> Option<Revision> {
        let mut f = File::open(self.dir.join("active.bin")).ok()?;
        let len = f.metadata().ok()?.len();
        let image_len = len.checked_sub(TRAILER_LEN as u64)?;
        f.seek(SeekFrom::Start(image_len)).ok()?;
        let mut trailer = [0u8; TRAILER_LEN];
        f.read_exact(&mut trailer).ok()?;
        let trailer = Trailer::parse(&trailer).ok()?;
        (u64::from(trailer.image_len) == image_len).then_some(())?;
        let mut head = vec![0u8; fw_image::INFO_OFFSET + fw_image::INFO_LEN];
        f.seek(SeekFrom::Start(0)).ok()?;
        f.read_exact(&mut head).ok()?;
        Some(ImageInfo::parse(&head).ok()?.revision)
    }

    /// The update object, the running image started as `boot`.
    pub fn object(&self, boot: BootState) -> Result<SoftUpdate, FirmwareDirError> {
        let platform = Platform {
            board_id: self.board_id,
            running: self.running(),
            public_key: self.public_key,
            // No bootloader.
            bootloader: Revision { major: 0, minor: 0 },
            boot,
        };
        let apply = FileApply { dir: self.dir.clone() };
        Ok(UpdateObject::new(FileFlash::open(&self.dir)?, apply, platform)?)
    }
}

/// The soft slave's own revision: its package version's major and minor.
pub fn own_revision() -> Revision {
    let part = |s: &str| s.parse::<u8>().unwrap_or(0);
    Revision { major: part(env!("CARGO_PKG_VERSION_MAJOR")), minor: part(env!("CARGO_PKG_VERSION_MINOR")) }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../contrib/keys/test-ed25519.public");

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("soft-slave-fw-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn the_dfu_file_is_created_erased_and_behaves_as_nor() {
        let d = dir("nor");
        let fw = FirmwareDir::new(&d, Path::new(KEY), 1).unwrap();
        drop(fw);
        let mut flash = FileFlash::open(&d).unwrap();
        let mut b = [0u8; 4];
        flash.read(PAGE_SIZE as u32, &mut b).unwrap();
        assert_eq!(b, [0xFF; 4]);
        flash.write(8, &[0x0F, 0xF0, 0x00, 0xFF]).unwrap();
        flash.write(8, &[0xFF, 0x3C, 0xFF, 0x00]).unwrap();
        flash.read(8, &mut b).unwrap();
        assert_eq!(b, [0x0F, 0x30, 0x00, 0x00], "a write ANDs");
        flash.erase(0, PAGE_SIZE as u32).unwrap();
        flash.read(8, &mut b).unwrap();
        assert_eq!(b, [0xFF; 4]);
        assert!(flash.erase(0, 3 * PAGE_SIZE as u32).is_err());
        std::fs::write(d.join("dfu.bin"), [0u8; 10]).unwrap();
        assert!(matches!(FileFlash::open(&d), Err(FirmwareDirError::DfuSize { len: 10, .. })));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_key_of_another_size_is_refused() {
        let d = dir("key");
        std::fs::create_dir_all(&d).unwrap();
        let key = d.join("k");
        std::fs::write(&key, [0u8; 31]).unwrap();
        let e = FirmwareDir::new(&d, &key, 1).unwrap_err();
        assert!(matches!(e, FirmwareDirError::KeySize { len: 31, .. }), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn apply_writes_active_bin_and_the_revision_follows_it() {
        let d = dir("apply");
        let fw = FirmwareDir::new(&d, Path::new(KEY), 1).unwrap();
        assert_eq!(fw.running(), own_revision(), "no active.bin yet");
        let mut image: Vec<u8> = (0..1000u32).map(|i| i as u8).collect();
        let info = ImageInfo { board_id: 1, revision: Revision { major: 7, minor: 9 } };
        image[0x200..0x210].copy_from_slice(&info.to_bytes());
        let seed: [u8; 32] =
            std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../../contrib/keys/test-ed25519.secret"))
                .unwrap()
                .try_into()
                .unwrap();
        let trailer = fw_image::sign(&image, &seed).unwrap();
        let mut flash = FileFlash::open(&d).unwrap();
        flash.write(0, &image).unwrap();
        let mut apply = FileApply { dir: d.clone() };
        apply.mark_updated(&trailer).unwrap();
        let active = std::fs::read(d.join("active.bin")).unwrap();
        assert_eq!(&active[..1000], &image[..]);
        assert_eq!(&active[1000..], &trailer.to_bytes()[..]);
        assert_eq!(fw.running(), Revision { major: 7, minor: 9 });
        // A torn active.bin (no whole trailer) is not an image: the package version again.
        std::fs::write(d.join("active.bin"), &active[..1100]).unwrap();
        assert_eq!(fw.running(), own_revision());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
