//! The settings flash in a file: the two settings sectors of the board (board crate,
//! `FlashLayout::settings_bases`), sector A then sector B, exactly as the flash array holds them.
//!
//! Only the settings sectors are kept: the program comes from the ELF at each start, as a probe
//! that flashes a new program leaves the sectors it does not write alone. A power cycle is a
//! stop and a start on the same file.

use crate::board::BoardKind;
use std::path::{Path, PathBuf};

/// Why the flash file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum FlashFileError {
    /// Reading or writing it failed.
    #[error("flash file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// It is not the size of the board's two settings sectors (another board's, or not one).
    #[error("flash file {path}: {len} bytes, but the {board} board's two settings sectors are {want} bytes (a file of another board, or not a flash file)")]
    Size {
        /// The file.
        path: PathBuf,
        /// Its size.
        len: usize,
        /// The board.
        board: &'static str,
        /// The sectors' size.
        want: usize,
    },
}

/// The two settings sectors: each one's offset from the start of flash and its bytes.
pub type Sectors = [(u32, Vec<u8>); 2];

/// The file and where its bytes go in the flash array.
#[derive(Clone, Debug)]
pub struct FlashFile {
    path: PathBuf,
    board: &'static str,
    /// Offsets of sectors A and B from the start of flash.
    offsets: [usize; 2],
    sector: usize,
}

impl FlashFile {
    /// The file at `path` for `kind`'s settings sectors.
    pub fn new(path: &Path, kind: BoardKind) -> FlashFile {
        let layout = kind.spec.flash;
        FlashFile {
            path: path.to_path_buf(),
            board: kind.name,
            offsets: layout.settings_bases.map(|b| (b - board::memory::FLASH_BASE) as usize),
            sector: layout.settings_sector_size as usize,
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The sectors, `(offset from the start of flash, bytes)`, from the file; `None` when there is
    /// no file yet (a new board).
    pub fn load(&self) -> Result<Option<Sectors>, FlashFileError> {
        let bytes = match std::fs::read(&self.path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(FlashFileError::Io { path: self.path.clone(), source }),
        };
        if bytes.len() != 2 * self.sector {
            return Err(FlashFileError::Size {
                path: self.path.clone(),
                len: bytes.len(),
                board: self.board,
                want: 2 * self.sector,
            });
        }
        let (a, b) = bytes.split_at(self.sector);
        Ok(Some([(self.offsets[0] as u32, a.to_vec()), (self.offsets[1] as u32, b.to_vec())]))
    }

    /// The erased sectors (all 0xFF), `(offset, bytes)` as [`FlashFile::load`] gives them.
    pub fn erased(&self) -> Sectors {
        self.offsets.map(|o| (o as u32, vec![0xFF; self.sector]))
    }

    /// The sectors' bytes of `flash` (the whole array, from offset 0).
    pub fn sectors_of(&self, flash: &[u8]) -> Vec<u8> {
        let mut out = Vec::with_capacity(2 * self.sector);
        for o in self.offsets {
            out.extend_from_slice(flash.get(o..o + self.sector).unwrap_or_default());
        }
        out
    }

    /// Writes the sectors of `flash` to the file: a temporary file renamed over it, so that a
    /// stop during the write leaves the old file or the new one.
    pub fn save(&self, flash: &[u8]) -> Result<(), FlashFileError> {
        let bytes = self.sectors_of(flash);
        let mut tmp = self.path.clone().into_os_string();
        tmp.push(".tmp");
        let tmp = PathBuf::from(tmp);
        std::fs::write(&tmp, &bytes)
            .and_then(|()| std::fs::rename(&tmp, &self.path))
            .map_err(|source| FlashFileError::Io { path: self.path.clone(), source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sectors_round_trip_through_the_file_and_a_wrong_size_is_refused() {
        let kind = BoardKind::by_name("reference").expect("reference");
        let dir = std::env::temp_dir().join(format!("flash-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = FlashFile::new(&dir.join("settings.bin"), kind);
        assert!(file.load().unwrap().is_none(), "no file: a new board");
        let mut flash = vec![0u8; 1 << 20];
        let [(a, _), (b, _)] = file.erased();
        flash[a as usize] = 0xA5;
        flash[b as usize + 7] = 0x5A;
        file.save(&flash).unwrap();
        let [(oa, sa), (ob, sb)] = file.load().unwrap().expect("saved");
        assert_eq!((oa, ob), (a, b));
        assert_eq!((sa[0], sa[1], sb[7], sb.len()), (0xA5, 0, 0x5A, 16 * 1024));
        std::fs::write(file.path(), [0u8; 10]).unwrap();
        let err = file.load().unwrap_err().to_string();
        assert!(err.contains("10 bytes, but the reference board's two settings sectors are 32768"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
