//! A peripheral whose RCC clock enable bit is clear (stm32_emu::periph's module docs): every
//! model with an enable bit reads 0 and loses writes, and the machine stops on the first such
//! access with a fault naming the peripheral, the register and the bit; with the bit set, the
//! same load reads the register's reset value (RM0090 §7.3.10, §7.3.13, §7.3.14 for the bits,
//! each model's section for the reset value).

mod thumb;

use rstest::rstest;
use stm32_emu::bxcan::Bxcan;
use stm32_emu::cpu::bus::UnclockedAccess;
use stm32_emu::gpio::{Gpio, Port};
use stm32_emu::machine::{Chip, Fault, Stm32};
use stm32_emu::periph::{ClockGate, Peripheral};
use stm32_emu::pwr::Pwr;
use stm32_emu::rcc::{Hse, Rcc, BASE as RCC_BASE};
use stm32_emu::usart::{Usart, UsartId};
use thumb::*;
use unicorn_engine::RegisterARM;

/// One model with an enable bit: how to build it, its block, a register with a non-zero reset
/// value, that value, and its gate.
struct Case {
    model: fn() -> Box<dyn Peripheral>,
    base: u32,
    offset: u32,
    reset_value: u32,
    gate: ClockGate,
}

fn bxcan1() -> Case {
    // CAN_MSR resets to 0x0000_0C02: SLAK, and RX/SAMP recessive (RM0090 §32.9.2).
    Case {
        model: || Box::new(Bxcan::new()),
        base: 0x4000_6400,
        offset: 4,
        reset_value: 0x0C02,
        gate: ClockGate::Apb1(25),
    }
}

fn gpioa() -> Case {
    // GPIOA_MODER resets to 0xA800_0000: PA13–PA15 in the debug port's alternate function
    // (RM0090 §8.4.1).
    Case {
        model: || Box::new(Gpio::new(Port::A)),
        base: 0x4002_0000,
        offset: 0,
        reset_value: 0xA800_0000,
        gate: ClockGate::Ahb1(0),
    }
}

fn gpiob() -> Case {
    // GPIOB_MODER resets to 0x0000_0280: PB3, PB4 for the debug port (RM0090 §8.4.1).
    Case {
        model: || Box::new(Gpio::new(Port::B)),
        base: 0x4002_0400,
        offset: 0,
        reset_value: 0x0280,
        gate: ClockGate::Ahb1(1),
    }
}

fn usart(id: UsartId, gate: ClockGate) -> Case {
    let model: fn() -> Box<dyn Peripheral> = match id {
        UsartId::Usart1 => || Box::new(Usart::new(UsartId::Usart1)),
        UsartId::Usart2 => || Box::new(Usart::new(UsartId::Usart2)),
        UsartId::Usart6 => || Box::new(Usart::new(UsartId::Usart6)),
    };
    // USART_SR resets to 0x00C0 (TXE, TC; RM0090 §30.6.1).
    Case { model, base: id.base(), offset: 0, reset_value: 0x00C0, gate }
}

fn pwr() -> Case {
    // PWR_CSR: VOSRDY (bit 14) is set, the regulator being ready (RM0090 §5.4.2).
    Case {
        model: || Box::new(Pwr::new(Chip::Stm32F405)),
        base: 0x4000_7000,
        offset: 4,
        reset_value: 1 << 14,
        gate: ClockGate::Apb1(28),
    }
}

/// The RCC enable register of `gate`: RCC_AHB1ENR at offset 0x30, RCC_APB1ENR 0x40,
/// RCC_APB2ENR 0x44 (RM0090 §7.3.10, §7.3.13, §7.3.14).
fn enable_register(gate: ClockGate) -> u32 {
    RCC_BASE
        + match gate {
            ClockGate::Ahb1(_) => 0x30,
            ClockGate::Apb1(_) => 0x40,
            ClockGate::Apb2(_) => 0x44,
        }
}

/// A machine with RCC and `case`'s model running `main`.
fn machine_with(case: &Case, main: Asm) -> Stm32 {
    let mut mcu = Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine");
    mcu.add_peripheral(RCC_BASE, 0x400, Box::new(Rcc::new(Hse::None))).expect("RCC");
    mcu.add_peripheral(case.base, 0x400, (case.model)()).expect("model");
    flash(&mut mcu, &image(&mut [(RESET, main)], &[]));
    mcu
}

#[rstest]
#[case::bxcan1(bxcan1(), "bxCAN1", "RCC_APB1ENR.CAN1EN (bit 25)")]
#[case::gpioa(gpioa(), "GPIOA", "RCC_AHB1ENR.GPIOAEN (bit 0)")]
#[case::gpiob(gpiob(), "GPIOB", "RCC_AHB1ENR.GPIOBEN (bit 1)")]
#[case::usart1(usart(UsartId::Usart1, ClockGate::Apb2(4)), "USART1", "RCC_APB2ENR.USART1EN (bit 4)")]
#[case::usart2(usart(UsartId::Usart2, ClockGate::Apb1(17)), "USART2", "RCC_APB1ENR.USART2EN (bit 17)")]
#[case::usart6(usart(UsartId::Usart6, ClockGate::Apb2(5)), "USART6", "RCC_APB2ENR.USART6EN (bit 5)")]
#[case::pwr(pwr(), "PWR", "RCC_APB1ENR.PWREN (bit 28)")]
fn a_load_from_an_unclocked_peripheral_reads_0_and_stops_the_machine(
    #[case] case: Case,
    #[case] peripheral: &str,
    #[case] bit: &str,
) {
    let address = case.base + case.offset;
    let mut main = Asm::new(RESET);
    main.movs(1, 0x55).ldr_const(0, address).ldr(1, 0, 0).movs(2, 1);
    let here = main.here();
    main.b(here);
    let mut mcu = machine_with(&case, main);
    let fault = mcu.run_for(10_000).expect_err("an unclocked access stops the machine");
    let access = UnclockedAccess {
        peripheral: mcu_name(peripheral),
        address,
        gate: case.gate,
        pc: RESET + 4,
        write: false,
    };
    assert_eq!(fault, Fault::Unclocked(access));
    let message = fault.to_string();
    for part in [peripheral, bit, &format!("{address:#010x}"), "read 0"] {
        assert!(message.contains(part), "{message:?} names {part:?}");
    }
    assert_eq!(mcu.register(RegisterARM::R1), 0, "the load read 0");
    assert_eq!(mcu.register(RegisterARM::R2), 0, "the machine stopped after the load");
    assert_eq!(mcu.run_for(10_000), Err(fault), "and stays stopped");
}

/// The names as the models give them (`&'static str`).
fn mcu_name(name: &str) -> &'static str {
    ["bxCAN1", "GPIOA", "GPIOB", "USART1", "USART2", "USART6", "PWR"]
        .into_iter()
        .find(|n| *n == name)
        .expect("a model's name")
}

#[rstest]
#[case::bxcan1(bxcan1())]
#[case::gpioa(gpioa())]
#[case::gpiob(gpiob())]
#[case::usart1(usart(UsartId::Usart1, ClockGate::Apb2(4)))]
#[case::usart2(usart(UsartId::Usart2, ClockGate::Apb1(17)))]
#[case::usart6(usart(UsartId::Usart6, ClockGate::Apb2(5)))]
#[case::pwr(pwr())]
fn with_its_enable_bit_set_the_same_load_reads_the_reset_value(#[case] case: Case) {
    let mut main = Asm::new(RESET);
    main.ldr_const(2, enable_register(case.gate)).ldr_const(3, 1 << case.gate.bit()).str(3, 2, 0);
    main.ldr_const(0, case.base + case.offset).ldr(1, 0, 0);
    let here = main.here();
    main.b(here);
    let mut mcu = machine_with(&case, main);
    mcu.run_for(10_000).expect("a clocked access runs on");
    assert_eq!(mcu.register(RegisterARM::R1), case.reset_value);
}

/// bxCAN's MCR.INRQ written with CAN1EN clear (what the firmware of the `fault-can-clock`
/// self-test does first) is lost, and the store is reported as such.
#[test]
fn a_store_to_an_unclocked_bxcan_is_lost_and_stops_the_machine() {
    let case = bxcan1();
    let mut main = Asm::new(RESET);
    main.ldr_const(0, case.base).movs(1, 1).str(1, 0, 0);
    let here = main.here();
    main.b(here);
    let mut mcu = machine_with(&case, main);
    let fault = mcu.run_for(10_000).expect_err("stops");
    let access = UnclockedAccess {
        peripheral: "bxCAN1",
        address: case.base,
        gate: case.gate,
        pc: RESET + 4,
        write: true,
    };
    assert_eq!(fault, Fault::Unclocked(access));
    assert!(fault.to_string().contains("lost"), "{fault}");
    let apb1enr = enable_register(case.gate);
    assert_eq!(mcu.read_peripheral(apb1enr), Some(0), "CAN1EN is clear at reset");
    assert_eq!(
        mcu.read_peripheral(case.base),
        Some(0),
        "a debugger's read of the unclocked block reads 0 too"
    );
    assert_eq!(mcu.run_for(10_000), Err(fault), "and is not the firmware's access");
}

#[rstest]
#[case::can1(ClockGate::Apb1(25), "RCC_APB1ENR.CAN1EN (bit 25)")]
#[case::can2(ClockGate::Apb1(26), "RCC_APB1ENR.CAN2EN (bit 26)")]
#[case::gpioh(ClockGate::Ahb1(7), "RCC_AHB1ENR.GPIOHEN (bit 7)")]
#[case::usart6(ClockGate::Apb2(5), "RCC_APB2ENR.USART6EN (bit 5)")]
#[case::unnamed(ClockGate::Apb1(27), "RCC_APB1ENR bit 27")]
fn a_gate_is_named_by_its_register_and_bit(#[case] gate: ClockGate, #[case] text: &str) {
    assert_eq!(gate.to_string(), text);
}
