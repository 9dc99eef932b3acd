//! Reading the firmware ELF: its loadable segments at their load (physical) addresses, as a
//! debug probe programs them, and its symbols.

use object::elf::{FileHeader32, PT_LOAD};
use object::read::elf::{FileHeader, ProgramHeader};
use object::{LittleEndian, Object, ObjectSymbol};

/// Why an ELF file cannot be loaded (the machine reports it as `Fault::Elf`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ElfError {
    /// Not a 32-bit little-endian ELF file, or its program headers cannot be read.
    #[error("{0}")]
    Format(object::read::Error),
    /// An ELF file for another machine than ARM.
    #[error("not an ARM executable")]
    NotArm,
    /// A loadable segment whose contents lie outside the file.
    #[error("segment outside the file")]
    SegmentOutsideFile,
}

/// The loadable segments of `elf` with file contents: (load address, bytes). The `.bss` part
/// of a segment (memory size beyond file size) is not loaded: the start-up code clears it.
pub fn load_segments(elf: &[u8]) -> Result<Vec<(u32, &[u8])>, ElfError> {
    let header = FileHeader32::<LittleEndian>::parse(elf).map_err(ElfError::Format)?;
    let endian = header.endian().map_err(ElfError::Format)?;
    if header.e_machine(endian) != object::elf::EM_ARM {
        return Err(ElfError::NotArm);
    }
    let segments = header.program_headers(endian, elf).map_err(ElfError::Format)?;
    let mut loads = Vec::new();
    for segment in segments.iter().filter(|s| s.p_type(endian) == PT_LOAD) {
        let data = segment.data(endian, elf).map_err(|_| ElfError::SegmentOutsideFile)?;
        if !data.is_empty() {
            loads.push((segment.p_paddr(endian), data));
        }
    }
    Ok(loads)
}

/// The address of the first symbol whose (mangled) name contains `part`, Thumb bit cleared.
pub fn symbol_address(elf: &[u8], part: &str) -> Option<u32> {
    let file = object::File::parse(elf).ok()?;
    let symbol = file.symbols().find(|s| s.name().is_ok_and(|n| n.contains(part)))?;
    Some(symbol.address() as u32 & !1)
}
