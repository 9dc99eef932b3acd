//! A tiny Thumb assembler and a machine built around hand-assembled code, for the machine's
//! tests.

#![allow(dead_code)]

use stm32_emu::machine::{Chip, Stm32};

/// A tiny Thumb assembler: 16-bit encodings (ARMv7-M ARM A6/A7) and a literal pool.
pub struct Asm {
    base: u32,
    code: Vec<u16>,
    literals: Vec<(usize, u32)>,
}

impl Asm {
    pub fn new(base: u32) -> Asm {
        Asm { base, code: Vec::new(), literals: Vec::new() }
    }
    pub fn here(&self) -> u32 {
        self.base + 2 * self.code.len() as u32
    }
    pub fn op(&mut self, halfword: u16) -> &mut Asm {
        self.code.push(halfword);
        self
    }
    /// LDR Rt, =value (literal pool, T1).
    pub fn ldr_const(&mut self, rt: u16, value: u32) -> &mut Asm {
        self.literals.push((self.code.len(), value));
        self.op(0x4800 | rt << 8)
    }
    pub fn movs(&mut self, rd: u16, imm: u16) -> &mut Asm {
        self.op(0x2000 | rd << 8 | imm)
    }
    pub fn adds(&mut self, rdn: u16, imm: u16) -> &mut Asm {
        self.op(0x3000 | rdn << 8 | imm)
    }
    pub fn cmp(&mut self, rn: u16, imm: u16) -> &mut Asm {
        self.op(0x2800 | rn << 8 | imm)
    }
    pub fn lsls(&mut self, rd: u16, rm: u16, imm: u16) -> &mut Asm {
        self.op(imm << 6 | rm << 3 | rd)
    }
    /// STR Rt, [Rn, #4*words].
    pub fn str(&mut self, rt: u16, rn: u16, words: u16) -> &mut Asm {
        self.op(0x6000 | words << 6 | rn << 3 | rt)
    }
    pub fn ldr(&mut self, rt: u16, rn: u16, words: u16) -> &mut Asm {
        self.op(0x6800 | words << 6 | rn << 3 | rt)
    }
    pub fn strb(&mut self, rt: u16, rn: u16, bytes: u16) -> &mut Asm {
        self.op(0x7000 | bytes << 6 | rn << 3 | rt)
    }
    /// B to `target` (T2).
    pub fn b(&mut self, target: u32) -> &mut Asm {
        let offset = (target as i32 - (self.here() as i32 + 4)) / 2;
        self.op(0xE000 | (offset as u16 & 0x7FF))
    }
    /// BNE to `target` (T1).
    pub fn bne(&mut self, target: u32) -> &mut Asm {
        let offset = (target as i32 - (self.here() as i32 + 4)) / 2;
        self.op(0xD100 | (offset as u16 & 0xFF))
    }
    pub fn bx_lr(&mut self) -> &mut Asm {
        self.op(0x4770)
    }
    /// MSR BASEPRI, Rn.
    pub fn msr_basepri(&mut self, rn: u16) -> &mut Asm {
        self.op(0xF380 | rn).op(0x8811)
    }
    /// VMOV S0, Rt.
    pub fn vmov_s0_from(&mut self, rt: u16) -> &mut Asm {
        self.op(0xEE00).op(0x0A10 | rt << 12)
    }
    /// VMOV Rt, S0.
    pub fn vmov_from_s0(&mut self, rt: u16) -> &mut Asm {
        self.op(0xEE10).op(0x0A10 | rt << 12)
    }
    pub fn wfi(&mut self) -> &mut Asm {
        self.op(0xBF30)
    }
    /// The code, then the literal pool (word aligned), as bytes.
    pub fn finish(&mut self) -> Vec<u8> {
        if self.code.len() % 2 != 0 {
            self.op(0xBF00);
        }
        let pool = self.here();
        let literals = std::mem::take(&mut self.literals);
        for (i, &(at, value)) in literals.iter().enumerate() {
            let address = pool + 4 * i as u32;
            let pc = (self.base + 2 * at as u32 + 4) & !3;
            self.code[at] |= ((address - pc) / 4) as u16;
            self.code.extend([value as u16, (value >> 16) as u16]);
        }
        self.code.iter().flat_map(|h| h.to_le_bytes()).collect()
    }
}

pub const FLASH: u32 = 0x0800_0000;
pub const STACK_TOP: u32 = 0x2000_1000;
pub const RESET: u32 = FLASH + 0x200;
pub const COUNTER: u32 = 0x2000_0000;
pub const SYSTICK: u16 = 15;
pub const EXTI2: u16 = 16 + 8;
pub const EXTI3: u16 = 16 + 9;
pub const CAN1_RX0: u16 = 16 + 20;

/// The flash contents for `programs` (address, code) and a vector table at 0x0800_0000
/// naming `handlers` (exception number, address): (flash offset, bytes).
pub fn image(programs: &mut [(u32, Asm)], handlers: &[(u16, u32)]) -> Vec<(u32, Vec<u8>)> {
    let mut table = vec![0u32; 16 + 82];
    table[0] = STACK_TOP;
    table[1] = RESET | 1;
    for &(number, address) in handlers {
        table[usize::from(number)] = address | 1;
    }
    let mut image = vec![(0, table.iter().flat_map(|w| w.to_le_bytes()).collect())];
    image.extend(programs.iter_mut().map(|(address, asm)| (*address - FLASH, asm.finish())));
    image
}

/// Programs `image` into `mcu`'s flash and resets it.
pub fn flash(mcu: &mut Stm32, image: &[(u32, Vec<u8>)]) {
    for (offset, bytes) in image {
        mcu.program_flash(*offset, bytes).expect("program");
    }
    mcu.power_on_reset().expect("reset");
}

/// A machine running `programs` with `handlers` (see [`image`]).
pub fn machine(programs: &mut [(u32, Asm)], handlers: &[(u16, u32)]) -> Stm32 {
    let mut mcu = Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine");
    flash(&mut mcu, &image(programs, handlers));
    mcu
}

pub fn word(mcu: &Stm32, address: u32) -> u32 {
    let mut b = [0; 4];
    assert!(mcu.read_memory(address, &mut b));
    u32::from_le_bytes(b)
}
