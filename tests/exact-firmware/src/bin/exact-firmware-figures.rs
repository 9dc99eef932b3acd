//! `exact-firmware-figures`: the firmware figures of issue 26 item 6, measured on the exact ELF of
//! every board build running on the stm32-emu models. A benchmark: it prints figures and fails
//! only when it could not measure them, never on their values.
//!
//! ```text
//! exact-firmware-figures --dir target/thumbv7em-none-eabihf/firmware [--only BOARD]... [--sizes FILE]
//! ```
//!
//! `--dir` holds the ELFs as scripts/firmware-size names them (`slave-fw-firmware-<board>`);
//! `--sizes` is the record firmware-size leaves (`target/firmware-size.txt`), whose flash and
//! static RAM columns are joined to the table. scripts/firmware-figures runs both.
//!
//! ## What is measured, and how it is counted
//!
//! Each board is brought up by the bench master's library on the simulated bus at 500 kbit/s
//! (MAC 5, the reference device: a poll command of 8 bytes, an 18-byte response in three
//! fragments, EPR 100 ms). Then the bench delivers frames to the bxCAN model itself:
//!
//! - **poll → TXRQ**: from the instant a poll command is stored in the receive FIFO to the
//!   instruction that sets TXRQ in a transmit mailbox for the first response fragment; the
//!   machine runs one instruction at a time and `CAN_TSR`'s TME bits are read after each.
//! - **poll → idle**, the cost of a received frame: the instructions the firmware executes in
//!   handler mode (with RTIC every task runs there; thread mode is the idle loop) from that same
//!   instant until the core is back in thread mode with no exception pending: the work of one
//!   received poll command, the building and queueing of its response included, the
//!   transmit-complete interrupts of the fragments not (they come when the bus has taken each
//!   fragment); "exc" counts the exception entries meanwhile.
//! - **expl**: the same two figures for an explicit request over the explicit connection the
//!   bring-up allocated (Get_Attribute_Single of the Identity's vendor ID, the protocol §2's frame
//!   11), answered by one frame.
//! - **cycle**: the handler-mode instructions of a whole poll cycle, the three fragments sent and
//!   acknowledged included, less those of an equally long window without a poll (SysTick and
//!   the firmware's timers), 10 ms each.
//! - **max load** ("all answ", "no FOVR", "answered"): poll commands delivered back to back at rising rates, each rate for
//!   [`SWEEP_FRAMES`] frames, expressed as the share of a 500 kbit/s bus that those frames'
//!   wire time would take (what the board sends is taken every 10 µs between deliveries and
//!   acknowledged at once, taking no wire time, so above 100 % the figure is processing
//!   headroom, not a bus that exists); "no FOVR" is the highest rate after which neither receive
//!   FIFO showed an overrun (FOVR), from [`SWEEP`], `>=` when no rate swept overran.
//!   "answered" is how many of that rate's polls got the first fragment of a response, and
//!   "all answ" the highest rate at which every poll got one: a poll left unanswered is no
//!   overrun, and the columns show it rather than hide it.
//!
//! Counting: the machine counts the instructions the CPU emulator (unicorn) executes
//! (`Stm32::instructions`, `Stm32::handler_instructions`) and its time advances one HCLK cycle
//! per instruction. The figures are instructions, given as cycles under that assumption and in
//! microseconds at the board's HCLK. A Cortex-M4 retires most instructions in one cycle but
//! loads, stores, taken branches and divisions in 2 to 12 (ARM DDI 0439 §3.3.1), so real cycles
//! are higher; not included either: exception entry and return (12 cycles or more each, counted
//! apart as "exc"), flash wait states (5 at 168 MHz, 5 at 180 MHz, partly hidden by the ART
//! accelerator) and bus contention. The figures compare builds and catch regressions; a cycle
//! count on silicon needs the DWT cycle counter on a real board.

use can_io::bus::Bitrate;
use can_io::sim::{frame_duration, PowerOn, SimBus, SimDevice};
use devicenet::reference::POLL_COMMAND;
use devicenet::slave::BaudRate;
use devicenet::{CanFrame, Group2Message, Identifier, Instant, MacId};
use exact_firmware::board::{BoardKind, NodeSetting};
use exact_firmware::device::{EmulatedBoard, Firmware, OnBus};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::fmt;
use std::path::PathBuf;
use std::process::ExitCode;
use std::rc::Rc;
use stm32_emu::bxcan::{offset, rfr, CAN1_BASE};

/// The device's MAC ID (the reference transcript's).
const MAC: MacId = MacId::from_low_bits(5);
/// `CAN_TSR` TME0..TME2 (bits 26 to 28, RM0090 §32.9.3): the three mailboxes empty.
const TSR_TME: u32 = 0b111 << 26;
/// Poll commands measured one by one per board.
const POLLS: usize = 20;
/// Between two measured polls (the EPR is 100 ms).
const POLL_GAP_US: u64 = 10_000;
/// The longest the bench waits for the firmware to answer or settle, in instructions.
const SETTLE_LIMIT: u64 = 2_000_000;
/// Frames delivered at each rate of the sweep.
const SWEEP_FRAMES: usize = 300;
/// The rates of the sweep, as a share of a 500 kbit/s bus in percent.
const SWEEP: [u64; 16] =
    [25, 50, 75, 100, 150, 200, 300, 400, 600, 800, 1000, 1500, 2000, 3000, 5000, 10_000];
/// How often the sweep takes what the board sends between two deliveries, in µs.
const SERVICE_US: u64 = 10;
/// Between two rates of the sweep (the FIFOs drain).
const SWEEP_PAUSE_US: u64 = 20_000;

/// Why a board's figures could not be measured.
#[derive(Debug)]
enum FigureError {
    /// The firmware or its bootloader ELF could not be read (the message names the file).
    Elf(String),
    /// The sizes file could not be read.
    Sizes { path: PathBuf, error: std::io::Error },
    /// The machine could not be built or stopped with a fault.
    Machine(String),
    /// The master's bring-up failed.
    Connect(String),
    /// The firmware did not do what is measured within [`SETTLE_LIMIT`] instructions.
    NoAnswer(&'static str),
    /// No board of that name.
    UnknownBoard(String),
}

impl fmt::Display for FigureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FigureError::Elf(why) => f.write_str(why),
            FigureError::Sizes { path, error } => write!(f, "{}: {error}", path.display()),
            FigureError::Machine(why) => write!(f, "the machine: {why}"),
            FigureError::Connect(why) => write!(f, "bring-up: {why}"),
            FigureError::NoAnswer(what) => write!(f, "no {what} within {SETTLE_LIMIT} instructions"),
            FigureError::UnknownBoard(name) => write!(f, "no board called {name}"),
        }
    }
}

type Board = Rc<RefCell<EmulatedBoard>>;

/// One board's figures.
struct Figures {
    hclk: u32,
    /// The reference poll command.
    poll: Request,
    /// An explicit request, Get_Attribute_Single of the Identity's vendor ID.
    explicit: Request,
    /// Handler instructions of a whole poll cycle less an idle window's.
    cycle: i64,
    /// The sweep.
    max_load: Sweep,
}

/// The figures of one kind of request, over [`POLLS`] of them: medians (the maxima are
/// printed only where they differ).
struct Request {
    /// Instructions from the request in the FIFO to the TXRQ of its (first) response frame.
    to_txrq: u64,
    /// The largest of those.
    to_txrq_max: u64,
    /// Handler-mode instructions from the request in the FIFO until idle.
    handled: u64,
    /// The largest of those.
    handled_max: u64,
    /// Exception entries meanwhile.
    entries: u64,
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let (mut dir, mut sizes, mut only) = (None, None, Vec::new());
    while let Some(arg) = args.next() {
        let Some(value) = args.next() else { return usage() };
        match arg.as_str() {
            "--dir" => dir = Some(PathBuf::from(value)),
            "--sizes" => sizes = Some(PathBuf::from(value)),
            "--only" => only.push(value),
            _ => return usage(),
        }
    }
    let Some(dir) = dir else { return usage() };
    let sizes = match sizes.map(|path| read_sizes(&path)).transpose() {
        Ok(sizes) => sizes.unwrap_or_default(),
        Err(e) => {
            eprintln!("exact-firmware-figures: {e}");
            return ExitCode::FAILURE;
        }
    };
    for name in &only {
        if BoardKind::by_name(name).is_none() {
            eprintln!("exact-firmware-figures: {}", FigureError::UnknownBoard(name.clone()));
            return ExitCode::from(2);
        }
    }
    println!(
        "{:<18} {:>4} {:>15} {:>19} {:>15} {:>19} {:>6} {:>9} {:>9} {:>9} {:>6} {:>5}",
        "board",
        "MHz",
        "poll->TXRQ",
        "poll->idle (exc)",
        "expl->TXRQ",
        "expl->idle (exc)",
        "cycle",
        "all answ",
        "no FOVR",
        "answered",
        "flash",
        "ram"
    );
    let mut failed = false;
    for kind in BoardKind::all().into_iter().filter(|k| only.is_empty() || only.iter().any(|n| n == k.name)) {
        let path = dir.join(format!("slave-fw-firmware-{}", kind.name));
        match measure(kind, &path) {
            Ok(f) => println!("{}", row(kind.name, &f, sizes.iter().find(|s| s.0 == kind.name))),
            Err(e) => {
                failed = true;
                println!("{:<18} FAILED: {e}", kind.name);
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

fn usage() -> ExitCode {
    eprintln!("usage: exact-firmware-figures --dir DIR [--only BOARD]... [--sizes FILE]");
    ExitCode::from(2)
}

/// The table row of one board: instructions, then µs at HCLK in brackets; a maximum after a
/// slash where it differs from the median.
fn row(name: &str, f: &Figures, size: Option<&(String, u64, u64)>) -> String {
    let cell = |median: u64, max: u64| {
        let us = median as f64 * 1e6 / f64::from(f.hclk);
        match max > median {
            true => format!("{median}/{max} ({us:.1})"),
            false => format!("{median} ({us:.1})"),
        }
    };
    let load = format!("{}{} %", if f.max_load.overran_above { "" } else { ">=" }, f.max_load.load);
    let (flash, ram) = size.map_or(("-".into(), "-".into()), |s| (s.1.to_string(), s.2.to_string()));
    format!(
        "{:<18} {:>4} {:>15} {:>19} {:>15} {:>19} {:>6} {:>9} {:>9} {:>9} {:>6} {:>5}",
        name,
        f.hclk / 1_000_000,
        cell(f.poll.to_txrq, f.poll.to_txrq_max),
        format!("{} {}", cell(f.poll.handled, f.poll.handled_max), f.poll.entries),
        cell(f.explicit.to_txrq, f.explicit.to_txrq_max),
        format!("{} {}", cell(f.explicit.handled, f.explicit.handled_max), f.explicit.entries),
        f.cycle,
        format!("{} %", f.max_load.all_answered),
        load,
        format!("{}/{SWEEP_FRAMES}", f.max_load.first_fragments),
        flash,
        ram
    )
}

/// The rows of firmware-size's record: build, flash, static RAM.
fn read_sizes(path: &PathBuf) -> Result<Vec<(String, u64, u64)>, FigureError> {
    let text =
        std::fs::read_to_string(path).map_err(|error| FigureError::Sizes { path: path.clone(), error })?;
    Ok(text
        .lines()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            let name = words.next()?;
            let flash = words.next()?.parse().ok()?;
            let ram = words.next()?.parse().ok()?;
            Some((name.to_string(), flash, ram))
        })
        .collect())
}

/// Every figure of one board.
fn measure(kind: BoardKind, path: &std::path::Path) -> Result<Figures, FigureError> {
    let elf = Firmware::from_files(kind.name, path, None).map_err(FigureError::Elf)?;
    let (board, mut now) = connected(kind, &elf)?;
    let hclk = board.borrow_mut().mcu().clocks().hclk;
    let poll = requests(&board, &mut now, &poll_command()?)?;
    let explicit = requests(&board, &mut now, &explicit_request()?)?;
    let cycle = poll_cycle(&board, &mut now)?;
    let max_load = sweep(&board, &mut now)?;
    Ok(Figures { hclk, poll, explicit, cycle, max_load })
}

/// [`POLLS`] of `frame`, [`POLL_GAP_US`] apart, each measured by [`one_request`].
fn requests(board: &Board, now: &mut u64, frame: &CanFrame) -> Result<Request, FigureError> {
    let (mut to_txrq, mut handled, mut entries) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..POLLS {
        *now = settle(board, *now + POLL_GAP_US)?;
        let (txrq, instructions, taken) = one_request(board, *now, frame)?;
        to_txrq.push(txrq);
        handled.push(instructions);
        entries.push(taken);
        *now = finish_transmissions(board, *now)?;
    }
    Ok(Request {
        to_txrq: median(&mut to_txrq),
        to_txrq_max: to_txrq.iter().copied().max().unwrap_or(0),
        handled: median(&mut handled),
        handled_max: handled.iter().copied().max().unwrap_or(0),
        entries: median(&mut entries),
    })
}

fn median(values: &mut [u64]) -> u64 {
    values.sort_unstable();
    values.get(values.len() / 2).copied().unwrap_or(0)
}

/// The board brought up by the master at 500 kbit/s, and the bus's time then (µs).
fn connected(kind: BoardKind, elf: &Firmware) -> Result<(Board, u64), FigureError> {
    let setting = NodeSetting { mac: MAC, rate: BaudRate::Kbps500, bus_off_interrupt: false };
    let device = EmulatedBoard::new(kind, elf, setting, Bitrate::K500)
        .map_err(|e| FigureError::Machine(e.to_string()))?;
    let board = Rc::new(RefCell::new(device));
    let mut bus = SimBus::new(Bitrate::K500);
    bus.attach(Box::new(OnBus(Rc::clone(&board))), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let now = {
        let mut master = Master::new(&mut session, MasterConfig::default());
        let connected = master.connect(&ConnectOptions::default());
        fault(&board)?;
        connected.map_err(|e| FigureError::Connect(e.to_string()))?;
        master.session.now().total_micros()
    };
    Ok((board, now))
}

/// The machine's fault, if it stopped.
fn fault(board: &Board) -> Result<(), FigureError> {
    match board.borrow().fault() {
        Some(why) => Err(FigureError::Machine(why.to_string())),
        None => Ok(()),
    }
}

/// Runs the board to `at` (µs on the bus's clock), taking what it sends; returns `at`.
fn settle(board: &Board, at: u64) -> Result<u64, FigureError> {
    let mut b = board.borrow_mut();
    b.handle_timeout(Instant::from_micros(at));
    while b.poll_transmit().is_some() {}
    drop(b);
    fault(board)?;
    Ok(at)
}

/// The reference poll command to MAC 5.
fn poll_command() -> Result<CanFrame, FigureError> {
    let id = Identifier::group2(MAC, Group2Message::PollCommand);
    CanFrame::new(id, &POLL_COMMAND).map_err(|e| FigureError::Machine(format!("poll command: {e:?}")))
}

/// Get_Attribute_Single of the Identity's vendor ID over the explicit connection the bring-up
/// allocated (the protocol §2's frame 11).
fn explicit_request() -> Result<CanFrame, FigureError> {
    let id = Identifier::group2(MAC, Group2Message::ExplicitRequest);
    CanFrame::new(id, &[0x00, 0x0E, 0x01, 0x01, 0x01])
        .map_err(|e| FigureError::Machine(format!("explicit request: {e:?}")))
}

/// `frame` delivered at `now`: instructions to the first TXRQ, handler instructions until idle,
/// exception entries meanwhile.
fn one_request(board: &Board, now: u64, frame: &CanFrame) -> Result<(u64, u64, u64), FigureError> {
    let mut b = board.borrow_mut();
    let tsr = b.mcu().read_peripheral(CAN1_BASE + offset::TSR).unwrap_or(0);
    if tsr & TSR_TME != TSR_TME {
        return Err(FigureError::NoAnswer("empty transmit mailboxes before the poll"));
    }
    b.handle_frame(frame, Instant::from_micros(now));
    let mcu = b.mcu();
    let (start, handler_start, entries_start) =
        (mcu.instructions(), mcu.handler_instructions(), entries(mcu));
    let mut to_txrq = None;
    loop {
        let tsr = mcu.read_peripheral(CAN1_BASE + offset::TSR).unwrap_or(TSR_TME);
        if to_txrq.is_none() && tsr & TSR_TME != TSR_TME {
            to_txrq = Some(mcu.instructions() - start);
        }
        let scs = mcu.scs();
        if to_txrq.is_some() && scs.current() == 0 && scs.highest_pending().is_none() {
            break;
        }
        if mcu.instructions() - start > SETTLE_LIMIT {
            return Err(FigureError::NoAnswer(if to_txrq.is_some() { "return to idle" } else { "response" }));
        }
        mcu.run_for(1).map_err(|e| FigureError::Machine(e.to_string()))?;
    }
    let handled = mcu.handler_instructions() - handler_start;
    let taken = entries(mcu) - entries_start;
    Ok((to_txrq.unwrap_or(0), handled, taken))
}

/// Every exception entry so far.
fn entries(mcu: &stm32_emu::machine::Stm32) -> u64 {
    (1..16 + 97).map(|n| mcu.exceptions_taken(n)).sum()
}

/// Lets the board send its queued fragments (each acknowledged at once), 1 ms.
fn finish_transmissions(board: &Board, now: u64) -> Result<u64, FigureError> {
    let mut at = now;
    for _ in 0..10 {
        at = settle(board, at + 100)?;
    }
    Ok(at)
}

/// Handler instructions of a poll cycle (10 ms from the poll, its fragments sent) less those of
/// 10 ms without one.
fn poll_cycle(board: &Board, now: &mut u64) -> Result<i64, FigureError> {
    *now = settle(board, *now + POLL_GAP_US)?;
    let idle_start = board.borrow_mut().mcu().handler_instructions();
    *now = window(board, *now, POLL_GAP_US)?;
    let idle = board.borrow_mut().mcu().handler_instructions() - idle_start;
    let busy_start = board.borrow_mut().mcu().handler_instructions();
    board.borrow_mut().handle_frame(&poll_command()?, Instant::from_micros(*now));
    *now = window(board, *now, POLL_GAP_US)?;
    let busy = board.borrow_mut().mcu().handler_instructions() - busy_start;
    Ok(busy as i64 - idle as i64)
}

/// Runs `length` µs from `now` in 100 µs steps, taking what the board sends.
fn window(board: &Board, now: u64, length: u64) -> Result<u64, FigureError> {
    let mut at = now;
    while at < now + length {
        at = settle(board, at + 100)?;
    }
    Ok(at)
}

/// The highest rate of [`SWEEP`] after which no delivery left a FIFO overrun, and whether a
/// higher one did.
fn sweep(board: &Board, now: &mut u64) -> Result<Sweep, FigureError> {
    let frame = poll_command()?;
    let wire = frame_duration(&frame, Bitrate::K500).total_micros();
    let mut highest = Sweep { load: 0, overran_above: false, first_fragments: 0, all_answered: 0 };
    for percent in SWEEP {
        *now = window(board, *now, SWEEP_PAUSE_US)?;
        let before = board.borrow().counts().overruns;
        // One frame's wire time at `percent` of the bus: the spacing between deliveries.
        let spacing = (wire * 100).div_ceil(percent).max(1);
        let mut first_fragments = 0;
        for _ in 0..SWEEP_FRAMES {
            let mut b = board.borrow_mut();
            // What the board offers between two deliveries leaves (acknowledged at once) every
            // SERVICE_US, so that the next fragment of a response can follow.
            let next = *now + spacing;
            let mut at = *now + SERVICE_US;
            while at < next {
                b.handle_timeout(Instant::from_micros(at));
                first_fragments += count_first_fragments(&mut b);
                at += SERVICE_US;
            }
            *now = next;
            b.handle_frame(&frame, Instant::from_micros(*now));
            first_fragments += count_first_fragments(&mut b);
        }
        // The last poll's response.
        for _ in 0..100 {
            *now += SERVICE_US;
            let mut b = board.borrow_mut();
            b.handle_timeout(Instant::from_micros(*now));
            first_fragments += count_first_fragments(&mut b);
        }
        fault(board)?;
        if board.borrow().counts().overruns > before || fifo_overrun(board) {
            highest.overran_above = true;
            return Ok(highest);
        }
        let answered_all = first_fragments == SWEEP_FRAMES as u64 && highest.all_answered == highest.load;
        let all_answered = if answered_all { percent } else { highest.all_answered };
        highest = Sweep { load: percent, overran_above: false, first_fragments, all_answered };
    }
    Ok(highest)
}

/// Takes what the board sent; returns how many were the first fragment of a response
/// (fragment type 0 in the fragmentation byte's bits 7–6, the protocol §2's 0x3C5 frames).
fn count_first_fragments(board: &mut EmulatedBoard) -> u64 {
    let mut first = 0;
    while let Some(sent) = board.poll_transmit() {
        if sent.data().first().is_some_and(|b| b & 0xC0 == 0) {
            first += 1;
        }
    }
    first
}

/// The sweep's result.
struct Sweep {
    /// The highest rate without an overrun, in percent of a 500 kbit/s bus.
    load: u64,
    /// A higher rate of [`SWEEP`] overran.
    overran_above: bool,
    /// First response fragments the board sent at that rate, of [`SWEEP_FRAMES`] polls.
    first_fragments: u64,
    /// The highest rate up to which every poll of every rate got a response.
    all_answered: u64,
}

/// Whether FOVR is set in either receive FIFO now.
fn fifo_overrun(board: &Board) -> bool {
    let mut b = board.borrow_mut();
    [offset::RF0R, offset::RF1R]
        .iter()
        .any(|o| b.mcu().read_peripheral(CAN1_BASE + o).unwrap_or(0) & rfr::FOVR != 0)
}
