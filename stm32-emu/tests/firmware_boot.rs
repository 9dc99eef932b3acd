//! The exact board firmware ELF boots on the machine with stand-in peripheral models: it
//! sets up the clocks, SysTick and bxCAN, leaves CAN initialisation mode, and takes (and
//! returns from) SysTick interrupts.
//!
//! Ignored by default: it needs the thumb build. Run it with
//!
//! ```text
//! cargo build -p slave-fw-firmware --profile firmware --target thumbv7em-none-eabihf
//! cargo test -p stm32-emu --test firmware_boot -- --ignored
//! ```
//!
//! It runs the newest reference-board build found (`slave-fw-firmware` or scripts/firmware-size's
//! `slave-fw-firmware-reference`, never the emulated QEMU build), or `STM32_EMU_FIRMWARE=path`.
//! A firmware linked past 0x0800_0000 (at ACTIVE, issue 31) is loaded after the reference
//! board's bootloader (`scripts/build-bootloader --test-key reference`, or
//! `STM32_EMU_BOOTLOADER=path`), which starts it.

mod firmware_elf;
mod stand_ins;

use stand_ins::{Bxcan, Flash, Gpio, Rcc, Record, Shared, Usart};
use std::cell::RefCell;
use std::rc::Rc;
use stm32_emu::machine::{Chip, Stm32};

const SYSTICK: u16 = 15;
/// The reference board's HSE (board/src/boards/reference.rs).
const HSE_HZ: u32 = 8_000_000;

/// The board's peripherals as stand-ins, at their RM0090 §2.3 table 1 addresses.
fn board(record: &Shared) -> Result<Stm32, Box<dyn std::error::Error>> {
    let mut mcu = Stm32::new(Chip::Stm32F405, *b"stm32-emu-id")?;
    mcu.add_peripheral(0x4002_3800, 0x400, Box::new(Rcc::new(HSE_HZ, record)))?;
    mcu.add_peripheral(0x4002_3C00, 0x400, Box::new(Flash::new(record)))?;
    let ports = [
        ("GPIOA", 0x4002_0000, [0xA800_0000, 0x0C00_0000, 0x6400_0000]),
        ("GPIOB", 0x4002_0400, [0x0000_0280, 0x0000_00C0, 0x0000_0100]),
        ("GPIOC", 0x4002_0800, [0, 0, 0]),
    ];
    for (name, base, reset) in ports {
        // Every input high: the DIP switches (PB0–PB7, pull-ups) all open.
        mcu.add_peripheral(base, 0x400, Box::new(Gpio::new(name, reset, 0xFFFF, record)))?;
    }
    mcu.add_peripheral(0x4000_4400, 0x400, Box::new(Usart::new("USART2", record)))?;
    mcu.add_peripheral(0x4001_1000, 0x400, Box::new(Usart::new("USART1", record)))?;
    mcu.add_peripheral(0x4000_6400, 0x400, Box::new(Bxcan::new(record)))?;
    // The crate's own IWDG model (issue 31: the firmware feeds the watchdog the bootloader starts).
    mcu.add_peripheral(stm32_emu::iwdg::BASE, 0x400, Box::new(stm32_emu::iwdg::Iwdg::new()))?;
    Ok(mcu)
}

/// Whether the firmware wrote BTR in initialisation mode and then cleared MCR.INRQ (bxcan's
/// `enable_non_blocking`, RM0090 §32.4.1).
fn can_enabled(record: &Record) -> bool {
    let can: Vec<(u32, u32)> =
        record.stores.iter().filter(|(name, _, _)| *name == "bxCAN1").map(|&(_, o, v)| (o, v)).collect();
    let Some(btr) = can.iter().position(|&(offset, _)| offset == 0x1C) else {
        return false;
    };
    let init_before = can[..btr].iter().any(|&(offset, value)| offset == 0 && value & 1 != 0);
    let left_init = can[btr..].iter().any(|&(offset, value)| offset == 0 && value & 1 == 0);
    init_before && left_init
}

#[test]
#[ignore = "needs the thumb build of slave-fw-firmware (see the file's docs)"]
fn the_board_firmware_enables_can_and_takes_systick_interrupts() -> Result<(), Box<dyn std::error::Error>> {
    let (_, elf) = firmware_elf::board_elf()?;
    let record = Rc::new(RefCell::new(Record::default()));
    let mut mcu = board(&record)?;
    let elfs = firmware_elf::with_bootloader(elf)?;
    mcu.load_elfs(&elfs.iter().map(Vec::as_slice).collect::<Vec<_>>())?;

    // 50 ms of emulated time at most: init runs in well under that.
    let booted = mcu.run_until(50_000_000, |m| {
        can_enabled(&record.borrow()) && m.scs().systick.enabled() && m.exceptions_taken(SYSTICK) >= 10
    });
    let stores = record.borrow().stores.len();
    let booted = booted.map_err(|fault| format!("{fault} (after {stores} peripheral stores)"))?;
    assert!(
        booted,
        "at {} ns, pc {:#010x}: CAN enabled {}, SysTick taken {} times",
        mcu.now(),
        mcu.pc(),
        can_enabled(&record.borrow()),
        mcu.exceptions_taken(SYSTICK)
    );

    let clocks = mcu.clocks();
    let systick = &mcu.scs().systick;
    assert!(systick.interrupt_enabled() && systick.on_processor_clock());
    assert_eq!(systick.reload(), clocks.hclk / 1000 - 1, "a 1 kHz tick at HCLK");
    assert!(clocks.hclk > 16_000_000, "the PLL is running: {clocks:?}");
    // Every SysTick handler but the one just entered returned.
    let taken = mcu.exceptions_taken(SYSTICK);
    assert!(mcu.exceptions_returned(SYSTICK) + 1 >= taken);
    // 10 ms more: ten more ticks, every one returned.
    mcu.run_for(10_000_000)?;
    let ticks = mcu.exceptions_taken(SYSTICK) - taken;
    assert!((9..=11).contains(&ticks), "{ticks} SysTick interrupts in 10 ms");
    assert!(mcu.exceptions_returned(SYSTICK) + 1 >= mcu.exceptions_taken(SYSTICK));
    assert!(mcu.exceptions_taken(16 + 8) >= 1, "the converter task (EXTI2) ran");
    Ok(())
}
