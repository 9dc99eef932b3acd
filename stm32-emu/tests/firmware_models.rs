//! The exact board firmware ELF on the crate's own models (RCC, FLASH, GPIO, USART, bxCAN, IWDG):
//! it reaches the point where it enables the CAN controller and runs SysTick.
//!
//! Ignored by default: it needs the thumb build (see tests/firmware_boot.rs). Run it with
//! `cargo test -p stm32-emu --test firmware_models -- --ignored`.

mod firmware_elf;

use stm32_emu::bxcan::{Bxcan, CAN1_BASE};
use stm32_emu::flash::Flash;
use stm32_emu::gpio::{Gpio, Port};
use stm32_emu::machine::{Chip, Stm32};
use stm32_emu::rcc::{Hse, Rcc, BASE as RCC_BASE};
use stm32_emu::usart::{Usart, UsartId};

const SYSTICK: u16 = 15;

#[test]
#[ignore = "needs the thumb build of slave-fw-firmware (see tests/firmware_boot.rs)"]
fn the_board_firmware_boots_on_the_models() -> Result<(), Box<dyn std::error::Error>> {
    let (_, elf) = firmware_elf::board_elf()?;
    let mut mcu = Stm32::new(Chip::Stm32F405, *b"stm32-emu-id")?;
    // The reference board's 8 MHz crystal (board/src/boards/reference.rs).
    mcu.add_peripheral(RCC_BASE, 0x400, Box::new(Rcc::new(Hse::Crystal(8_000_000))))?;
    mcu.add_flash(Flash::new())?;
    for port in [Port::A, Port::B, Port::C] {
        mcu.add_peripheral(port.base(), 0x400, Box::new(Gpio::new(port)))?;
    }
    for usart in [UsartId::Usart1, UsartId::Usart2] {
        mcu.add_peripheral(usart.base(), 0x400, Box::new(Usart::new(usart)))?;
    }
    mcu.add_peripheral(CAN1_BASE, 0x400, Box::new(Bxcan::new()))?;
    mcu.add_peripheral(stm32_emu::iwdg::BASE, 0x400, Box::new(stm32_emu::iwdg::Iwdg::new()))?;
    let elfs = firmware_elf::with_bootloader(elf)?;
    mcu.load_elfs(&elfs.iter().map(Vec::as_slice).collect::<Vec<_>>())?;

    mcu.run_until(100_000_000, |m| m.exceptions_taken(SYSTICK) >= 10)?;
    let mcr = mcu.read_peripheral(CAN1_BASE).ok_or("no CAN1")?;
    let btr = mcu.read_peripheral(CAN1_BASE + 0x1C).ok_or("no CAN1")?;
    let clocks = mcu.clocks();
    eprintln!("at {} ns: MCR {mcr:#010x}, BTR {btr:#010x}, {clocks:?}", mcu.now());
    assert!(mcu.exceptions_taken(SYSTICK) >= 10, "SysTick runs");
    assert_eq!(mcu.scs().systick.reload(), clocks.hclk / 1000 - 1, "1 kHz at HCLK");
    assert_eq!(mcr & 1, 0, "CAN1 asked to leave initialisation mode (MCR.INRQ clear)");
    assert_ne!(btr, 0x0123_0000, "BTR set from its reset value");
    Ok(())
}
