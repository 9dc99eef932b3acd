//! The machine's exception model on hand-assembled Thumb code (no thumb build needed):
//! SysTick entry and return with the FP frame, BASEPRI masking as RTIC's locks use it,
//! preemption by priority and tail chaining, system reset through AIRCR, WFI, bus faults.

use rstest::rstest;
use stm32_emu::cpu::core::CoreFault;
use stm32_emu::machine::{Chip, Fault, Stm32};
use unicorn_engine::RegisterARM;

mod thumb;

use thumb::*;

/// Main: SysTick every 1000 cycles, S0 = 0x1234, then a loop counting in R4 and copying S0
/// to R5. The handler counts at COUNTER and clobbers R0, R1 and S0.
fn systick_program() -> Vec<(u32, Asm)> {
    let mut main = Asm::new(RESET);
    enable_fpu(&mut main);
    main.ldr_const(0, 0xE000_E010).ldr_const(1, 999).str(1, 0, 1).movs(1, 7).str(1, 0, 0);
    main.ldr_const(2, 0x1234).vmov_s0_from(2);
    let top = main.here();
    main.adds(4, 1).vmov_from_s0(5).b(top);
    let mut handler = Asm::new(FLASH + 0x400);
    handler.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).vmov_s0_from(1).bx_lr();
    vec![(RESET, main), (FLASH + 0x400, handler)]
}

#[test]
fn systick_is_taken_and_returns_with_the_context_restored() {
    let mut mcu = machine(&mut systick_program(), &[(SYSTICK, FLASH + 0x400)]);
    // 16 MHz HSI: 1000 cycles is 62.5 µs; 1 ms is 16 periods.
    mcu.run_for(1_000_000).expect("runs");
    let count = word(&mcu, COUNTER);
    assert!((15..=16).contains(&count), "{count} SysTick interrupts in 1 ms");
    assert_eq!(mcu.exceptions_taken(SYSTICK), u64::from(count));
    assert_eq!(mcu.scs().current(), 0, "back in thread mode");
    assert_eq!(mcu.register(RegisterARM::SP), STACK_TOP, "frame popped");
    assert_eq!(mcu.register(RegisterARM::R0), 0xE000_E010, "R0 restored");
    assert_eq!(mcu.register(RegisterARM::R1), 7, "R1 restored");
    assert_eq!(mcu.register(RegisterARM::R5), 0x1234, "S0 restored from the FP frame");
    // Three instructions a loop, 16,000 cycles, less the handlers'.
    assert!(mcu.register(RegisterARM::R4) > 4_000);
}

#[test]
fn instructions_are_counted_and_the_handlers_apart() {
    let mut mcu = machine(&mut systick_program(), &[(SYSTICK, FLASH + 0x400)]);
    mcu.run_for(1_000_000).expect("runs");
    let count = u64::from(word(&mcu, COUNTER));
    // The handler is six instructions: LDR (literal), LDR, ADDS, STR, VMOV, BX LR.
    assert_eq!(mcu.handler_instructions(), 6 * count);
    // At 16 MHz, one instruction a cycle: 1 ms is 16,000 instructions, handlers included.
    assert!((15_990..=16_010).contains(&mcu.instructions()), "{}", mcu.instructions());
}

#[test]
fn exception_entry_stacks_the_frame_and_sets_exc_return() {
    let mut mcu = machine(&mut systick_program(), &[(SYSTICK, FLASH + 0x400)]);
    let handler = FLASH + 0x400;
    let entered = mcu.run_until(1_000_000, |m| m.pc() == handler).expect("runs");
    assert!(entered);
    assert_eq!(mcu.scs().current(), SYSTICK);
    assert_eq!(mcu.scs().icsr() & 0x1FF, u32::from(SYSTICK), "ICSR.VECTACTIVE");
    // The thread used the FPU: the 26-word frame, EXC_RETURN "thread, MSP, FP frame".
    assert_eq!(mcu.register(RegisterARM::LR), 0xFFFF_FFE9);
    let sp = mcu.register(RegisterARM::SP);
    assert_eq!(sp, STACK_TOP - 26 * 4);
    assert_eq!(word(&mcu, sp), 0xE000_E010, "stacked R0");
    assert_eq!(word(&mcu, sp + 28) & (1 << 24), 1 << 24, "stacked xPSR has T");
    assert_eq!(word(&mcu, sp + 32), 0x1234, "stacked S0");
}

/// Main: EXTI2 at priority 0xE0 enabled, BASEPRI = `basepri`, EXTI2 pended, then R4 counts
/// to 100, BASEPRI = 0 and R5 counts forever. The handler stores R4 at COUNTER + 4 and
/// counts at COUNTER.
fn basepri_program(basepri: u16) -> Vec<(u32, Asm)> {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, 0xE000_E100).movs(1, 1).lsls(1, 1, 8).str(1, 0, 0);
    main.ldr_const(2, 0xE000_E408).movs(3, 0xE0).strb(3, 2, 0);
    main.movs(3, basepri).msr_basepri(3);
    main.ldr_const(2, 0xE000_E200).str(1, 2, 0);
    let count = main.here();
    main.adds(4, 1).cmp(4, 100).bne(count);
    main.movs(3, 0).msr_basepri(3);
    let idle = main.here();
    main.adds(5, 1).b(idle);
    let mut handler = Asm::new(FLASH + 0x400);
    handler.ldr_const(0, COUNTER).str(4, 0, 1).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).bx_lr();
    vec![(RESET, main), (FLASH + 0x400, handler)]
}

#[rstest]
#[case::basepri_of_equal_priority_masks_until_lowered(0xE0, 100)]
#[case::basepri_of_lower_priority_lets_it_in_at_once(0xF0, 0)]
#[case::no_basepri(0, 0)]
fn basepri_masking(#[case] basepri: u16, #[case] r4_in_handler: u32) {
    let mut mcu = machine(&mut basepri_program(basepri), &[(EXTI2, FLASH + 0x400)]);
    mcu.run_for(200_000).expect("runs");
    assert_eq!(word(&mcu, COUNTER), 1, "one EXTI2 interrupt");
    assert_eq!(word(&mcu, COUNTER + 4), r4_in_handler);
    assert_eq!(mcu.register(RegisterARM::R4), 100);
}

/// EXTI2 (0xE0) pends CAN1_RX0 (0xD0: preempts at once) and EXTI3 (0xE0: waits, then is
/// tail-chained). Each handler appends its IRQ number to a log at COUNTER.
#[test]
fn preemption_by_priority_and_tail_chaining() {
    let mut main = Asm::new(RESET);
    // IPR: EXTI2, EXTI3 at 0xE0, CAN1_RX0 at 0xD0; enable all three; pend EXTI2.
    main.ldr_const(2, 0xE000_E408).movs(3, 0xE0).strb(3, 2, 0).strb(3, 2, 1);
    main.ldr_const(2, 0xE000_E414).movs(3, 0xD0).strb(3, 2, 0);
    main.ldr_const(0, 0xE000_E100).ldr_const(1, (1 << 8) | (1 << 9) | (1 << 20)).str(1, 0, 0);
    main.ldr_const(2, 0xE000_E200).movs(1, 1).lsls(1, 1, 8).str(1, 2, 0);
    let idle = main.here();
    main.wfi().b(idle);
    // Log: R0 = COUNTER, R1 = its count, the entry at COUNTER + 4 + 4 * count.
    let log = |asm: &mut Asm, irq: u16| {
        asm.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).lsls(1, 1, 2).op(0x1809); // adds r1, r1, r0
        asm.movs(2, irq).str(2, 1, 0);
    };
    let mut exti2 = Asm::new(FLASH + 0x400);
    log(&mut exti2, 8);
    // Pend EXTI3 then CAN1_RX0 (ISPR0), then log again.
    exti2.ldr_const(2, 0xE000_E200).ldr_const(3, (1 << 9) | (1 << 20)).str(3, 2, 0);
    log(&mut exti2, 108);
    exti2.bx_lr();
    let mut exti3 = Asm::new(FLASH + 0x500);
    log(&mut exti3, 9);
    exti3.bx_lr();
    let mut can = Asm::new(FLASH + 0x600);
    log(&mut can, 20);
    can.bx_lr();
    let handlers = [(EXTI2, FLASH + 0x400), (EXTI3, FLASH + 0x500), (CAN1_RX0, FLASH + 0x600)];
    let mut programs = [(RESET, main), (FLASH + 0x400, exti2), (FLASH + 0x500, exti3), (FLASH + 0x600, can)];
    let mut mcu = machine(&mut programs, &handlers);
    mcu.run_for(100_000).expect("runs");
    let entries: Vec<u32> = (0..word(&mcu, COUNTER)).map(|i| word(&mcu, COUNTER + 4 + 4 * i)).collect();
    assert_eq!(entries, [8, 20, 108, 9], "EXTI2, CAN1_RX0 preempting, EXTI2 again, EXTI3 chained");
    assert_eq!(mcu.exceptions_taken(EXTI3), 1);
    assert!(mcu.sleeping(), "WFI in thread mode");
    assert_eq!(mcu.register(RegisterARM::SP), STACK_TOP);
}

/// A thread on PSP (CONTROL.SPSEL): the frame goes on PSP, the handler runs on MSP with
/// EXC_RETURN 0xFFFF_FFFD, and the return switches back (PM0214 §2.3.7, table 17).
#[test]
fn a_thread_on_psp_is_stacked_on_psp_and_handled_on_msp() {
    const PSP_TOP: u32 = 0x2000_0800;
    let mut main = Asm::new(RESET);
    main.ldr_const(0, PSP_TOP).op(0xF380).op(0x8809); // MSR PSP, R0
    main.movs(0, 2).op(0xF380).op(0x8814).op(0xF3BF).op(0x8F6F); // MSR CONTROL, R0; ISB
    main.ldr_const(0, 0xE000_E010).ldr_const(1, 999).str(1, 0, 1).movs(1, 7).str(1, 0, 0);
    let top = main.here();
    main.adds(4, 1).b(top);
    let mut handler = Asm::new(FLASH + 0x400);
    // COUNTER + 4: the handler's SP; COUNTER + 8: its LR.
    handler.ldr_const(0, COUNTER).op(0x4669).str(1, 0, 1).op(0x4672).str(2, 0, 2);
    handler.ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).bx_lr();
    let mut mcu = machine(&mut [(RESET, main), (FLASH + 0x400, handler)], &[(SYSTICK, FLASH + 0x400)]);
    mcu.run_for(200_000).expect("runs");
    assert!(word(&mcu, COUNTER) >= 2);
    assert_eq!(word(&mcu, COUNTER + 4), STACK_TOP, "the handler on MSP, nothing stacked there");
    assert_eq!(word(&mcu, COUNTER + 8), 0xFFFF_FFFD, "EXC_RETURN: thread, PSP, no FP frame");
    assert_eq!(mcu.register(RegisterARM::CONTROL) & 2, 2, "back on PSP");
    assert_eq!(mcu.register(RegisterARM::PSP), PSP_TOP, "PSP frame popped");
    assert_eq!(mcu.register(RegisterARM::MSP), STACK_TOP);
}

/// CCR.STKALIGN (set at reset): a frame pushed from an SP that is 4 mod 8 is aligned down and
/// xPSR bit 9 says so; the return restores the SP (PM0214 §2.3.7, §4.4.7).
#[test]
fn the_frame_is_8_byte_aligned_and_the_padding_undone() {
    let mut main = Asm::new(RESET);
    main.op(0xB081); // SUB SP, #4
    main.ldr_const(0, 0xE000_E010).ldr_const(1, 999).str(1, 0, 1).movs(1, 7).str(1, 0, 0);
    let top = main.here();
    main.adds(4, 1).b(top);
    let mut handler = Asm::new(FLASH + 0x400);
    handler.ldr_const(0, COUNTER).op(0x4669).str(1, 0, 1).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).bx_lr();
    let mut mcu = machine(&mut [(RESET, main), (FLASH + 0x400, handler)], &[(SYSTICK, FLASH + 0x400)]);
    mcu.run_for(100_000).expect("runs");
    let frame = word(&mcu, COUNTER + 4);
    assert_eq!(frame, STACK_TOP - 4 - 32 - 4, "aligned down to 8");
    assert_ne!(word(&mcu, frame + 28) & (1 << 9), 0, "stacked xPSR bit 9");
    assert_eq!(mcu.register(RegisterARM::SP), STACK_TOP - 4, "padding undone on return");
}

#[rstest]
#[case::reserved_value(0xFFFF_FFF5)]
#[case::handler_mode_on_psp(0xFFFF_FFF3)]
fn an_invalid_exc_return_stops_the_machine(#[case] exc_return: u32) {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, 0xE000_ED04).ldr_const(1, 1 << 26).str(1, 0, 0); // ICSR.PENDSTSET
    let here = main.here();
    main.b(here);
    let mut handler = Asm::new(FLASH + 0x400);
    handler.ldr_const(0, exc_return).op(0x4700); // BX R0
    let mut mcu = machine(&mut [(RESET, main), (FLASH + 0x400, handler)], &[(SYSTICK, FLASH + 0x400)]);
    let fault = mcu.run_for(10_000).expect_err("faults");
    assert_eq!(fault, Fault::Core(CoreFault::InvalidExceptionReturn { exc_return }));
}

/// As cortex-m-rt's reset handler does for thumbv7em-none-eabihf: CPACR CP10, CP11 full
/// access.
fn enable_fpu(asm: &mut Asm) {
    asm.ldr_const(0, 0xE000_ED88).ldr_const(1, 0xF << 20).str(1, 0, 0);
}

#[rstest]
#[case::fpu_enabled(true)]
#[case::fpu_off_is_a_nocp_fault(false)]
fn an_fp_instruction_needs_cpacr(#[case] enabled: bool) {
    let mut main = Asm::new(RESET);
    if enabled {
        enable_fpu(&mut main);
    }
    main.movs(2, 1).vmov_s0_from(2);
    let here = main.here();
    main.b(here);
    let mut mcu = machine(&mut [(RESET, main)], &[]);
    let result = mcu.run_for(10_000);
    assert_eq!(result.is_ok(), enabled, "{result:?}");
    if let Err(fault) = result {
        assert!(matches!(fault, Fault::Core(CoreFault::NoCoprocessor { .. })));
    }
}

#[test]
fn sysresetreq_resets_the_machine() {
    let mut main = Asm::new(RESET);
    // Count resets in SRAM (kept by a system reset), then request one while below 3.
    main.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).cmp(1, 3);
    let stay = main.here() + 2 + 2 * 3;
    main.op(0xD000 | ((stay as i32 - (main.here() as i32 + 4)) / 2) as u16 & 0xFF); // beq stay
    main.ldr_const(2, 0xE000_ED0C).ldr_const(3, 0x05FA_0004).str(3, 2, 0);
    let here = main.here();
    main.b(here);
    let mut mcu = machine(&mut [(RESET, main)], &[]);
    mcu.run_for(100_000).expect("runs");
    assert_eq!(word(&mcu, COUNTER), 3);
    assert_eq!(mcu.resets(), 3, "power-on reset and two system resets");
}

#[rstest]
#[case::unmapped_peripheral(0x4000_6400)]
#[case::unmapped_memory(0x6000_0000)]
fn a_load_where_nothing_answers_is_a_bus_fault(#[case] address: u32) {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, address).ldr(1, 0, 0);
    let here = main.here();
    main.b(here);
    let mut mcu = machine(&mut [(RESET, main)], &[]);
    let fault = mcu.run_for(10_000).expect_err("faults");
    assert_eq!(fault, Fault::Core(CoreFault::Bus { address, pc: RESET + 2, write: false }));
    assert!(fault.to_string().contains(&format!("{address:#010x}")));
}

#[test]
fn the_unique_id_reads_from_system_memory() {
    let mut mcu = Stm32::new(Chip::Stm32F405, *b"0123456789ab").expect("machine");
    let mut id = [0; 12];
    assert!(mcu.read_memory(0x1FFF_7A10, &mut id));
    assert_eq!(&id, b"0123456789ab");
    assert!(!mcu.write_memory(0x1000_0000 + 64 * 1024, &[0]), "CCM is 64 KiB");
    assert!(mcu.write_memory(0x1000_0000, &[0]));
}

#[test]
fn an_undefined_instruction_stops_the_machine() {
    let mut main = Asm::new(RESET);
    main.movs(0, 1).op(0xDE00); // UDF #0
    let mut mcu = machine(&mut [(RESET, main)], &[]);
    let fault = mcu.run_for(10_000).expect_err("faults");
    assert_eq!(fault, Fault::Core(CoreFault::Undefined { pc: RESET + 2 }));
}
