//! `dnet-master sign-firmware ELF-or-BIN --key SECRET --board NAME [-o FILE]`: the signed file
//! that `firmware-update` sends (`scripts/sign-firmware` runs it). The input is the firmware's ELF
//! (its loadable segments laid out by physical address, the gaps filled with 0xFF, as
//! `objcopy -O binary` lays them out) or an already flat binary; the output is that binary followed
//! by `fw_image`'s 128-byte trailer, signed with the 32-byte Ed25519 seed in SECRET. A binary
//! without an image-info block at 0x200, or whose block names another board than NAME, is refused.

use crate::options::GlobalOptions;
use clap::Args;
use fw_image::{ImageInfo, MAX_IMAGE_LEN};
use harness_common::error::HarnessError;
use object::elf::PT_LOAD;
use object::read::elf::{FileHeader, ProgramHeader};
use object::Endianness;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The boards and their board IDs (issue 31's decision; `board::boards::BoardSpec::board_id`).
pub const BOARDS: [(&str, u16); 5] =
    [("reference", 1), ("olimex-p405", 2), ("olimex-p405-rs485", 3), ("nucleo-f446re", 4), ("emulated", 5)];

/// What `sign-firmware` was asked.
#[derive(Args, Clone, Debug)]
pub struct SignFirmwareArgs {
    /// The firmware: its ELF, or a flat binary.
    pub input: PathBuf,
    /// The signing key: the 32-byte Ed25519 seed (contrib/keys/test-ed25519.secret is the TEST key).
    #[arg(long, value_name = "SECRET")]
    pub key: PathBuf,
    /// The board the image is for: reference, olimex-p405, olimex-p405-rs485, nucleo-f446re or
    /// emulated; the image-info block must name it.
    #[arg(long, value_name = "NAME")]
    pub board: String,
    /// Where to write the signed file [default: the input's name with `.signed.bin`].
    #[arg(short = 'o', long, value_name = "FILE")]
    pub output: Option<PathBuf>,
}

/// Why a file cannot be signed.
#[derive(Debug, thiserror::Error)]
pub enum SignFirmwareError {
    /// A file cannot be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        error: std::io::Error,
    },
    /// An unknown board name.
    #[error(
        "--board {0}: expected one of reference, olimex-p405, olimex-p405-rs485, nucleo-f446re, emulated"
    )]
    Board(String),
    /// The key file is not 32 bytes.
    #[error("--key: an Ed25519 seed is 32 raw bytes, this file has {len}")]
    Key {
        /// Its length.
        len: usize,
    },
    /// The ELF cannot be read.
    #[error("{path}: not a readable 32-bit ELF: {detail}")]
    Elf {
        /// The file.
        path: String,
        /// The reader's reason.
        detail: String,
    },
    /// The ELF has nothing to load.
    #[error("{path}: no loadable segment with contents")]
    Empty {
        /// The file.
        path: String,
    },
    /// The laid-out image is too large.
    #[error("{path}: the image spans {len} bytes; a device takes at most {MAX_IMAGE_LEN}")]
    TooLarge {
        /// The file.
        path: String,
        /// The span.
        len: u64,
    },
    /// No valid image-info block.
    #[error("{path}: {source}")]
    Info {
        /// The file.
        path: String,
        /// Why.
        source: fw_image::InfoError,
    },
    /// The block names another board.
    #[error("{path}: the image-info block names board {found}, --board {board} is board {expected}")]
    AnotherBoard {
        /// The file.
        path: String,
        /// `--board`.
        board: String,
        /// Its ID.
        expected: u16,
        /// The block's.
        found: u16,
    },
    /// Signing refused the image.
    #[error("{path}: {source}")]
    Sign {
        /// The file.
        path: String,
        /// Why.
        source: fw_image::SignError,
    },
}

/// Runs `sign-firmware`; returns the exit status: 0 signed, 2 when an input is refused (printed
/// on `err`, or as `{"ok": false, "error": …}` with `--json`).
pub fn execute(
    opts: &GlobalOptions,
    args: &SignFirmwareArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let output = args.output.clone().unwrap_or_else(|| args.input.with_extension("signed.bin"));
    let (signed, info) = match sign_files(args, &output) {
        Ok(done) => done,
        Err(e) => {
            if opts.json {
                writeln!(out, "{}", json!({ "ok": false, "error": e.to_string() })).map_err(werr)?;
            }
            writeln!(err, "error: {e}").map_err(werr)?;
            return Ok(2);
        }
    };
    let image_len = signed.len() - fw_image::TRAILER_LEN;
    if opts.json {
        let v = json!({
            "ok": true,
            "output": output.display().to_string(),
            "bytes": image_len,
            "board_id": info.board_id,
            "revision": info.revision.to_string(),
        });
        writeln!(out, "{v}").map_err(werr)?;
    } else {
        writeln!(
            out,
            "{}: {image_len} bytes for board {} (ID {}), revision {}, signed",
            output.display(),
            args.board,
            info.board_id,
            info.revision
        )
        .map_err(werr)?;
    }
    Ok(0)
}

/// Reads the input and the key, signs, writes `output`.
fn sign_files(args: &SignFirmwareArgs, output: &Path) -> Result<(Vec<u8>, ImageInfo), SignFirmwareError> {
    let read = |path: &Path| {
        std::fs::read(path).map_err(|e| SignFirmwareError::Io { path: path.display().to_string(), error: e })
    };
    let input = read(&args.input)?;
    let key = read(&args.key)?;
    let name = args.input.display().to_string();
    let (signed, info) = sign(&name, &input, &key, &args.board)?;
    std::fs::write(output, &signed)
        .map_err(|e| SignFirmwareError::Io { path: output.display().to_string(), error: e })?;
    Ok((signed, info))
}

/// The signed file of `input` (an ELF or a flat binary named `name`) for `board`, with the
/// seed `key`.
///
/// # Errors
///
/// [`SignFirmwareError`] naming the file and what is wrong.
pub fn sign(
    name: &str,
    input: &[u8],
    key: &[u8],
    board: &str,
) -> Result<(Vec<u8>, ImageInfo), SignFirmwareError> {
    let expected = BOARDS
        .iter()
        .find(|(n, _)| *n == board)
        .map(|(_, id)| *id)
        .ok_or_else(|| SignFirmwareError::Board(board.into()))?;
    let seed = <[u8; 32]>::try_from(key).map_err(|_| SignFirmwareError::Key { len: key.len() })?;
    let mut image = if input.starts_with(b"\x7fELF") { flat_binary(name, input)? } else { input.to_vec() };
    if image.len() > MAX_IMAGE_LEN {
        return Err(SignFirmwareError::TooLarge { path: name.into(), len: image.len() as u64 });
    }
    let info =
        ImageInfo::parse(&image).map_err(|source| SignFirmwareError::Info { path: name.into(), source })?;
    if info.board_id != expected {
        return Err(SignFirmwareError::AnotherBoard {
            path: name.into(),
            board: board.into(),
            expected,
            found: info.board_id,
        });
    }
    let trailer = fw_image::sign(&image, &seed)
        .map_err(|source| SignFirmwareError::Sign { path: name.into(), source })?;
    image.extend_from_slice(&trailer.to_bytes());
    Ok((image, info))
}

/// The loadable segments of an ELF with contents (PT_LOAD, file size > 0) laid out from the lowest
/// physical address, the gaps 0xFF (erased flash).
fn flat_binary(name: &str, input: &[u8]) -> Result<Vec<u8>, SignFirmwareError> {
    let elf_err = |e: object::Error| SignFirmwareError::Elf { path: name.into(), detail: e.to_string() };
    let header = object::elf::FileHeader32::<Endianness>::parse(input).map_err(elf_err)?;
    let endian = header.endian().map_err(elf_err)?;
    let mut parts: Vec<(u64, &[u8])> = Vec::new();
    for ph in header.program_headers(endian, input).map_err(elf_err)? {
        if ph.p_type(endian) != PT_LOAD || ph.p_filesz(endian) == 0 {
            continue;
        }
        let data = ph.data(endian, input).map_err(|()| SignFirmwareError::Elf {
            path: name.into(),
            detail: "a segment's contents lie outside the file".into(),
        })?;
        parts.push((u64::from(ph.p_paddr(endian)), data));
    }
    let start =
        parts.iter().map(|(a, _)| *a).min().ok_or_else(|| SignFirmwareError::Empty { path: name.into() })?;
    let end = parts.iter().map(|(a, d)| a + d.len() as u64).max().unwrap_or(start);
    if end - start > MAX_IMAGE_LEN as u64 {
        return Err(SignFirmwareError::TooLarge { path: name.into(), len: end - start });
    }
    let mut image = vec![0xFFu8; (end - start) as usize];
    for (addr, data) in parts {
        let at = (addr - start) as usize;
        image[at..at + data.len()].copy_from_slice(data);
    }
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEED: [u8; 32] = [9; 32];

    fn binary(board: u16) -> Vec<u8> {
        let mut image = vec![0x11u8; 0x300];
        let info = ImageInfo { board_id: board, revision: fw_image::Revision { major: 3, minor: 1 } };
        image[0x200..0x210].copy_from_slice(&info.to_bytes());
        image
    }

    #[test]
    fn a_flat_binary_is_signed_with_its_board_checked() {
        let (signed, info) = sign("fw.bin", &binary(4), &SEED, "nucleo-f446re").unwrap();
        assert_eq!(info.board_id, 4);
        assert_eq!(signed.len(), 0x300 + 128);
        let file = master_core::update::UpdateFile::parse("fw.bin", signed).unwrap();
        let public = salty_public(&SEED);
        assert_eq!(fw_image::verify(file.image(), &file.trailer, &public), Ok(()));
    }

    fn salty_public(seed: &[u8; 32]) -> [u8; 32] {
        *salty::Keypair::from(seed).public.as_bytes()
    }

    #[test]
    fn another_board_a_missing_block_and_a_bad_key_are_refused() {
        assert!(matches!(
            sign("fw.bin", &binary(1), &SEED, "nucleo-f446re"),
            Err(SignFirmwareError::AnotherBoard { expected: 4, found: 1, .. })
        ));
        assert!(matches!(
            sign("fw.bin", &[0u8; 0x300], &SEED, "reference"),
            Err(SignFirmwareError::Info { .. })
        ));
        assert!(matches!(
            sign("fw.bin", &binary(1), &SEED[..31], "reference"),
            Err(SignFirmwareError::Key { .. })
        ));
        assert!(matches!(sign("fw.bin", &binary(1), &SEED, "nucleo"), Err(SignFirmwareError::Board(_))));
    }

    /// A little-endian ELF32 (ARM) with one PT_LOAD segment per `(paddr, bytes)` and a PT_LOAD
    /// without contents (`.bss`), as a linker writes them.
    fn elf(segments: &[(u32, &[u8])]) -> Vec<u8> {
        let phnum = segments.len() + 1;
        let data_at = 52 + 32 * phnum;
        let mut out = vec![0x7F, b'E', b'L', b'F', 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        let half = |v: u16| v.to_le_bytes().to_vec();
        let word = |v: u32| v.to_le_bytes().to_vec();
        for part in [half(2), half(40), word(1), word(0x0800_0000), word(52), word(0), word(0)] {
            out.extend(part);
        }
        for part in [half(52), half(32), half(phnum as u16), half(40), half(0), half(0)] {
            out.extend(part);
        }
        let mut offset = data_at as u32;
        for (paddr, bytes) in segments {
            let len = bytes.len() as u32;
            // p_type, p_offset, p_vaddr, p_paddr, p_filesz, p_memsz, p_flags, p_align
            for v in [1, offset, *paddr, *paddr, len, len, 5, 4] {
                out.extend(word(v));
            }
            offset += len;
        }
        for v in [1, offset, 0x2000_0000, 0x2000_0000, 0, 0x100, 6, 4] {
            out.extend(word(v));
        }
        for (_, bytes) in segments {
            out.extend_from_slice(bytes);
        }
        out
    }

    #[test]
    fn an_elf_is_laid_out_by_physical_address_with_the_gaps_erased() {
        let image = binary(1);
        let (head, tail) = image.split_at(0x280);
        // The second segment first, and 16 bytes of gap between the two.
        let elf = elf(&[(0x0802_0290, tail), (0x0802_0000, head)]);
        let (signed, info) = sign("fw.elf", &elf, &SEED, "reference").unwrap();
        assert_eq!(info.board_id, 1);
        let flat = &signed[..signed.len() - 128];
        assert_eq!(flat.len(), 0x290 + tail.len());
        assert_eq!(&flat[..0x280], head);
        assert!(flat[0x280..0x290].iter().all(|&b| b == 0xFF), "the gap is erased flash");
        assert_eq!(&flat[0x290..], tail);
    }

    #[test]
    fn an_elf_without_contents_is_refused() {
        assert!(matches!(
            sign("fw.elf", &elf(&[]), &SEED, "reference"),
            Err(SignFirmwareError::Empty { .. })
        ));
    }
}
