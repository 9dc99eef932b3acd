//! Code in flash that changes under the CPU (a bootloader's swap or revert rewrites the sectors
//! the old image ran from): after the change the CPU runs the new bytes, not the code Unicorn
//! translated from the old ones.

mod elf32;
mod thumb;

use stm32_emu::machine::{Chip, Stm32};
use thumb::{Asm, FLASH};
use unicorn_engine::RegisterARM;

const STACK: u32 = 0x2000_1000;
const CODE: u32 = FLASH + 0x200;

/// `MOVS R4, #value` then a branch to itself, at CODE.
fn code(value: u16) -> Vec<u8> {
    let mut main = Asm::new(CODE);
    main.movs(4, value);
    let here = main.here();
    main.b(here);
    main.finish()
}

#[test]
fn code_rewritten_in_flash_runs_new_after_a_reset() {
    let mut mcu = Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine");
    let table: Vec<u8> = [STACK, CODE | 1].iter().flat_map(|w| w.to_le_bytes()).collect();
    mcu.load_elf(&elf32::executable(CODE | 1, &[(FLASH, &table), (CODE, &code(42))])).expect("load");
    mcu.run_for(10_000).expect("runs");
    assert_eq!(mcu.register(RegisterARM::R4), 42);
    mcu.program_flash(CODE - FLASH, &code(7)).expect("rewrite");
    mcu.system_reset().expect("reset");
    mcu.run_for(10_000).expect("runs");
    assert_eq!(mcu.register(RegisterARM::R4), 7, "the new code ran, not the translation of the old");
}
