//! A minimal ELF32 writer for the machine's tests: an ARM executable with one PT_LOAD program
//! header per segment and no sections (what `Stm32::load_elfs` reads: the System V ABI's ELF
//! header and program headers, "ELF for the Arm Architecture" e_machine 40, EABI version 5).

#![allow(dead_code)]

const HEADER: usize = 52;
const PROGRAM_HEADER: usize = 32;

/// An executable whose `segments` (load address, contents) follow the headers in the file.
pub fn executable(entry: u32, segments: &[(u32, &[u8])]) -> Vec<u8> {
    let mut file = Vec::new();
    file.extend([0x7F, b'E', b'L', b'F', 1, 1, 1, 0]); // ELFCLASS32, ELFDATA2LSB, EV_CURRENT
    file.extend([0; 8]);
    let half = |file: &mut Vec<u8>, v: u16| file.extend(v.to_le_bytes());
    let word = |file: &mut Vec<u8>, v: u32| file.extend(v.to_le_bytes());
    half(&mut file, 2); // ET_EXEC
    half(&mut file, 40); // EM_ARM
    word(&mut file, 1);
    word(&mut file, entry);
    word(&mut file, HEADER as u32); // e_phoff
    word(&mut file, 0); // e_shoff
    word(&mut file, 0x0500_0400); // EF_ARM_EABI_VER5 | EF_ARM_ABI_FLOAT_HARD
    half(&mut file, HEADER as u16);
    half(&mut file, PROGRAM_HEADER as u16);
    half(&mut file, segments.len() as u16);
    half(&mut file, 40); // e_shentsize
    half(&mut file, 0); // e_shnum
    half(&mut file, 0); // e_shstrndx
    let mut offset = HEADER + PROGRAM_HEADER * segments.len();
    for &(address, data) in segments {
        word(&mut file, 1); // PT_LOAD
        word(&mut file, offset as u32);
        word(&mut file, address); // p_vaddr
        word(&mut file, address); // p_paddr
        word(&mut file, data.len() as u32); // p_filesz
        word(&mut file, data.len() as u32); // p_memsz
        word(&mut file, 5); // PF_R | PF_X
        word(&mut file, 4);
        offset += data.len();
    }
    for &(_, data) in segments {
        file.extend(data);
    }
    file
}
