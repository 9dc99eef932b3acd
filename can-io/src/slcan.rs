//! SLCAN (Lawicel CAN232/CANUSB ASCII protocol), the one line codec of the project (`no_std`, no
//! allocation). Both ends use it: the **emulated** board plays a serial CAN adapter on USART1 (QEMU
//! has no bxCAN; the host — `dnet-master --bus slcan:PTY`, `slcand`, python-can — opens it like a
//! USB-CAN dongle), and the host side ([`crate::bus::slcan`], feature `std`) talks to real
//! adapters and to that firmware.
//!
//! The parts: a line assembler ([`LineBuffer`]), the line codec ([`parse`], [`parse_received`],
//! [`frame_line`] or [`write_frame_line`], [`bitrate_code`]) and the adapter's state machine
//! ([`Adapter`]).
//!
//! ## Supported lines (each ends with `\r`; a stray `\n` is ignored)
//!
//! | host sends | meaning | answer |
//! |---|---|---|
//! | `O` / `L` | open the channel (normal / listen-only) | `\r` (also when already open) |
//! | `C` | close the channel | `\r` (also when already closed) |
//! | `Sn` | bit rate, `n` = 0–8 (10k … 1M), only while closed | `\r`, or BEL while open |
//! | `tIIILDD…` | standard data frame: 3 hex ID digits, DLC, data | `z\r`, or BEL while closed |
//! | `TIIIIIIIILDD…`, `r…`, `R…` | extended or remote frame: not DeviceNet, dropped | `Z\r`/`z\r` |
//! | `V`, `N`, `F` | version, serial number, status flags | `V1013\r`, `NDNET\r`, `F00\r` |
//! | `Z0`, `M…`, `m…` | timestamps off, acceptance code/mask (ignored) | `\r` |
//! | anything else, too long, bad hex | error | BEL (`\x07`) |
//!
//! Frames from the node go to the host as `tIIILDD…\r` (upper-case hex, no timestamp). While the
//! channel is closed the adapter is off the bus: the node's frames stay pending, exactly as an
//! unacknowledged frame stays in a bxCAN mailbox on a bus with no other node (protocol §7.1.4),
//! and go out once the host opens the channel. The bit rate is recorded but not enforced.
//!
//! ## No-panic contract
//!
//! Every function accepts any bytes; bad input gives an error value and a BEL answer, never a
//! panic, and nothing allocates.

use core::fmt;
use devicenet::CanFrame;

/// Longest line accepted, without its `\r` (`T` + 8 + 1 + 16 digits + a 4-digit timestamp).
pub const MAX_LINE: usize = 30;
/// Longest frame line sent: `t` + 3 + 1 + 16 digits + `\r`.
pub const MAX_FRAME_LINE: usize = 22;

/// The BEL byte an adapter answers a refused command with.
pub const BEL: u8 = 0x07;
/// Answer to an accepted command.
pub const OK: &[u8] = b"\r";
/// Answer to a bad or refused command.
pub const ERROR: &[u8] = b"\x07";
/// Answer to an accepted standard frame (`t`, `r`).
pub const TRANSMITTED: &[u8] = b"z\r";
/// Answer to an accepted extended frame (`T`, `R`).
pub const TRANSMITTED_EXTENDED: &[u8] = b"Z\r";

/// Why a line was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlcanError {
    /// An empty line.
    Empty,
    /// The line exceeded [`MAX_LINE`] bytes.
    TooLong,
    /// An unknown command letter.
    UnknownCommand(u8),
    /// A character that should be a hex digit is not.
    NotHex,
    /// The line is shorter or longer than its command needs.
    Length,
    /// Identifier out of range (standard above 0x7FF, extended above 0x1FFF_FFFF).
    Identifier,
    /// DLC above 8.
    Dlc,
    /// `Sn` with `n` outside 0–8.
    Bitrate,
    /// An option this adapter does not offer (timestamps, `s` BTR values).
    Unsupported,
}

impl fmt::Display for SlcanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SlcanError::Empty => f.write_str("empty line"),
            SlcanError::TooLong => write!(f, "line longer than {MAX_LINE} bytes"),
            SlcanError::UnknownCommand(c) => write!(f, "unknown command 0x{c:02X}"),
            SlcanError::NotHex => f.write_str("not a hex digit"),
            SlcanError::Length => f.write_str("wrong line length for the command"),
            SlcanError::Identifier => f.write_str("identifier out of range"),
            SlcanError::Dlc => f.write_str("DLC above 8"),
            SlcanError::Bitrate => f.write_str("bit rate code outside 0-8"),
            SlcanError::Unsupported => f.write_str("option not supported"),
        }
    }
}

impl core::error::Error for SlcanError {}

/// One parsed host line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// `O`: open the channel.
    Open,
    /// `L`: open listen-only.
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `Sn`: bit rate code 0–8 (10, 20, 50, 100, 125, 250, 500, 800, 1000 kbit/s).
    Bitrate(u8),
    /// `t`: a standard data frame to put on the bus.
    Frame(CanFrame),
    /// `T`: an extended data frame (not DeviceNet traffic).
    ExtendedFrame,
    /// `r`: a standard remote frame (not DeviceNet traffic).
    RemoteFrame,
    /// `R`: an extended remote frame (not DeviceNet traffic).
    ExtendedRemoteFrame,
    /// `V`: hardware/software version.
    Version,
    /// `N`: serial number.
    SerialNumber,
    /// `F`: status flags.
    StatusFlags,
    /// `Z0`: timestamps off.
    TimestampsOff,
    /// `Mxxxxxxxx` / `mxxxxxxxx`: acceptance code or mask (accepted, ignored).
    Acceptance,
}

/// The number `digits` spell in hex (either case), or [`SlcanError::NotHex`].
fn hex_value(digits: &[u8]) -> Result<u32, SlcanError> {
    hex_number(digits).ok_or(SlcanError::NotHex)
}

// One out-of-line copy for identifier, DLC, data and acceptance digits, giving `None` rather than
// an error so that no caller copies an error value: 112 bytes less.
#[inline(never)]
fn hex_number(digits: &[u8]) -> Option<u32> {
    // `to_digit` folds the letter case into one range check: 52 bytes less than three ranges.
    digits.iter().try_fold(0u32, |acc, &d| Some(acc << 4 | char::from(d).to_digit(16)?))
}

/// Checks a frame line after its letter: `id_digits` of identifier, a DLC, and (for data frames)
/// the data. Returns the identifier, DLC and data bytes.
fn frame_fields(rest: &[u8], id_digits: usize, remote: bool) -> Result<(u32, [u8; 8], usize), SlcanError> {
    if rest.len() < id_digits + 1 {
        return Err(SlcanError::Length);
    }
    let id = hex_value(&rest[..id_digits])?;
    let dlc = hex_value(&rest[id_digits..=id_digits])? as usize;
    if dlc > 8 {
        return Err(SlcanError::Dlc);
    }
    let data_digits = &rest[id_digits + 1..];
    let mut data = [0u8; 8];
    if remote {
        if !data_digits.is_empty() {
            return Err(SlcanError::Length);
        }
    } else {
        if data_digits.len() != 2 * dlc {
            return Err(SlcanError::Length);
        }
        for (byte, pair) in data.iter_mut().zip(data_digits.chunks_exact(2)) {
            *byte = hex_value(pair)? as u8;
        }
    }
    Ok((id, data, dlc))
}

/// Parses one line, without its `\r`.
// Inlined into `Adapter::handle_line`, its one caller in the firmware, which answers every error
// with one BEL: the error values are never built (132 bytes less than out of line, 24 less than
// left to the inliner).
#[inline(always)]
pub fn parse(line: &[u8]) -> Result<Command, SlcanError> {
    let (&letter, rest) = line.split_first().ok_or(SlcanError::Empty)?;
    match letter {
        // Nothing may follow these letters: one check for the six, 20 bytes less than one each.
        b'O' | b'L' | b'C' | b'V' | b'N' | b'F' => {
            if !rest.is_empty() {
                return Err(SlcanError::Length);
            }
            Ok(match letter {
                b'O' => Command::Open,
                b'L' => Command::ListenOnly,
                b'C' => Command::Close,
                b'V' => Command::Version,
                b'N' => Command::SerialNumber,
                _ => Command::StatusFlags,
            })
        }
        b'S' => match rest {
            [d @ b'0'..=b'8'] => Ok(Command::Bitrate(d - b'0')),
            [_] => Err(SlcanError::Bitrate),
            _ => Err(SlcanError::Length),
        },
        b's' => Err(SlcanError::Unsupported),
        b'Z' => match rest {
            [b'0'] => Ok(Command::TimestampsOff),
            [b'1'] => Err(SlcanError::Unsupported),
            _ => Err(SlcanError::Length),
        },
        b'M' | b'm' => {
            if rest.len() != 8 {
                return Err(SlcanError::Length);
            }
            hex_value(rest)?;
            Ok(Command::Acceptance)
        }
        // One arm for the four frame letters (frame_fields inlined once): 32 bytes less than four.
        b't' | b'r' | b'T' | b'R' => {
            let extended = letter.is_ascii_uppercase();
            let (id_digits, max_id) = if extended { (8, 0x1FFF_FFFF) } else { (3, 0x7FF) };
            let (id, data, dlc) = frame_fields(rest, id_digits, letter == b'r' || letter == b'R')?;
            if id > max_id {
                return Err(SlcanError::Identifier);
            }
            match letter {
                // Cannot fail (identifier and DLC checked above); `from_raw`, not `CanId::new` and
                // `new`: 16 bytes less.
                b't' => CanFrame::from_raw(id as u16, &data[..dlc])
                    .map(Command::Frame)
                    .map_err(|_| SlcanError::Dlc),
                b'r' => Ok(Command::RemoteFrame),
                b'T' => Ok(Command::ExtendedFrame),
                _ => Ok(Command::ExtendedRemoteFrame),
            }
        }
        other => Err(SlcanError::UnknownCommand(other)),
    }
}

/// Parses a line an adapter sent to the host (without its `\r`): as [`parse`], and a data frame may
/// carry a 4-digit timestamp after its data (adapters with timestamps on, `Z1`).
pub fn parse_received(line: &[u8]) -> Result<Command, SlcanError> {
    match parse(line) {
        Err(SlcanError::Length) if matches!(line.first(), Some(b't' | b'T')) && line.len() > 4 => {
            let (frame, stamp) = line.split_at(line.len() - 4);
            if stamp.iter().all(u8::is_ascii_hexdigit) {
                parse(frame)
            } else {
                Err(SlcanError::Length)
            }
        }
        other => other,
    }
}

/// The `Sn` code of a bit rate in bit/s (`S4` 125k, `S5` 250k, `S6` 500k ...), or `None` for a rate
/// SLCAN has no code for.
pub const fn bitrate_code(bits_per_second: u32) -> Option<u8> {
    match bits_per_second {
        10_000 => Some(0),
        20_000 => Some(1),
        50_000 => Some(2),
        100_000 => Some(3),
        125_000 => Some(4),
        250_000 => Some(5),
        500_000 => Some(6),
        800_000 => Some(7),
        1_000_000 => Some(8),
        _ => None,
    }
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// The line that carries `frame` to the host: `tIIILDD…\r`.
pub fn frame_line(frame: &CanFrame) -> heapless::Vec<u8, MAX_FRAME_LINE> {
    let mut line = heapless::Vec::new();
    // At most 1 + 3 + 1 + 16 + 1 = 22 bytes: always fits.
    write_frame_line(frame, |b| {
        let _ = line.push(b);
    });
    line
}

/// [`frame_line`] byte by byte to `write`, for a sender with no buffer (the emulated board's
/// USART: 92 bytes less than building the line first).
pub fn write_frame_line(frame: &CanFrame, mut write: impl FnMut(u8)) {
    let hex = |nibble: u32| HEX[(nibble & 0xF) as usize];
    // The identifier's 3 digits and the DLC's 1, as one 4-digit number.
    let head = u32::from(frame.id().as_raw()) << 4 | frame.dlc() as u32;
    write(b't');
    for shift in (0..4).rev() {
        write(hex(head >> (4 * shift)));
    }
    for &b in frame.data() {
        write(hex(u32::from(b) >> 4));
        write(hex(u32::from(b)));
    }
    write(b'\r');
}

/// Assembles host bytes into lines.
#[derive(Clone, Debug, Default)]
pub struct LineBuffer {
    buf: [u8; MAX_LINE],
    len: usize,
    overflowed: bool,
}

impl LineBuffer {
    /// An empty buffer.
    pub const fn new() -> Self {
        LineBuffer { buf: [0; MAX_LINE], len: 0, overflowed: false }
    }

    /// Adds one byte; at `\r` returns the finished line (without the `\r`), or
    /// [`SlcanError::TooLong`] when it did not fit.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], SlcanError>> {
        match byte {
            b'\r' => {
                let len = core::mem::take(&mut self.len);
                if core::mem::take(&mut self.overflowed) {
                    Some(Err(SlcanError::TooLong))
                } else {
                    // `len` never exceeds MAX_LINE: `get` leaves out a panic path (12 bytes).
                    Some(Ok(self.buf.get(..len).unwrap_or_default()))
                }
            }
            b'\n' => None,
            _ => {
                if self.len < MAX_LINE {
                    self.buf[self.len] = byte;
                    self.len += 1;
                } else {
                    self.overflowed = true;
                }
                None
            }
        }
    }
}

/// What the adapter does with one host line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Response {
    /// Bytes to send back to the host.
    pub reply: &'static [u8],
    /// A frame the host put on the bus, for the node.
    pub frame: Option<CanFrame>,
}

/// The adapter's channel state (closed after reset).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Adapter {
    open: bool,
    listen_only: bool,
    bitrate: Option<u8>,
}

impl Adapter {
    /// A closed adapter.
    pub const fn new() -> Self {
        Adapter { open: false, listen_only: false, bitrate: None }
    }

    /// Whether the host opened the channel: only then do the node's frames go to the host.
    pub const fn is_open(&self) -> bool {
        self.open
    }

    /// The last `Sn` code the host set.
    pub const fn bitrate(&self) -> Option<u8> {
        self.bitrate
    }

    /// The channel state as one number, for a board that keeps it across its own reset (the
    /// emulated firmware plays both the adapter and the node, and a real adapter is not reset with
    /// the node): bit 0 open, bit 1 listen-only, bit 2 a bit rate set, bits 8–15 its `Sn` code.
    pub const fn to_bits(&self) -> u32 {
        let (set, code) = match self.bitrate {
            Some(code) => (1 << 2, code as u32),
            None => (0, 0),
        };
        self.open as u32 | (self.listen_only as u32) << 1 | set | code << 8
    }

    /// The adapter [`Adapter::to_bits`] described.
    pub const fn from_bits(bits: u32) -> Self {
        Adapter {
            open: bits & 1 != 0,
            listen_only: bits & 2 != 0,
            bitrate: if bits & 4 != 0 { Some((bits >> 8) as u8) } else { None },
        }
    }

    /// Handles one line from [`LineBuffer::push`].
    // Out of line: inlined into the firmware's USART1 interrupt it costs 36 bytes.
    #[inline(never)]
    pub fn handle_line(&mut self, line: Result<&[u8], SlcanError>) -> Response {
        let Ok(command) = line.and_then(parse) else {
            return Response { reply: ERROR, frame: None };
        };
        // The answer is built in place, the frame not copied through a local: 16 bytes less.
        let mut response = Response { reply: OK, frame: None };
        response.reply = match command {
            Command::Open | Command::ListenOnly => {
                self.open = true;
                self.listen_only = command == Command::ListenOnly;
                OK
            }
            Command::Close => {
                self.open = false;
                OK
            }
            Command::Bitrate(_) if self.open => ERROR,
            Command::Bitrate(code) => {
                self.bitrate = Some(code);
                OK
            }
            Command::Frame(_)
            | Command::RemoteFrame
            | Command::ExtendedFrame
            | Command::ExtendedRemoteFrame => {
                // One check of the channel for the four frame commands, not a guard on each arm:
                // 84 bytes less.
                if !self.open || self.listen_only {
                    return Response { reply: ERROR, frame: None };
                }
                match command {
                    Command::Frame(f) => {
                        response.frame = Some(f);
                        TRANSMITTED
                    }
                    Command::RemoteFrame => TRANSMITTED,
                    _ => TRANSMITTED_EXTENDED,
                }
            }
            Command::Version => b"V1013\r",
            Command::SerialNumber => b"NDNET\r",
            Command::StatusFlags => b"F00\r",
            Command::TimestampsOff | Command::Acceptance => OK,
        };
        response
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::from_raw(id, data).unwrap()
    }

    #[rstest]
    #[case::closed(&[])]
    #[case::open_at_250k(&[&b"S5"[..], b"O"])]
    #[case::listen_only(&[&b"S8"[..], b"L"])]
    #[case::closed_again(&[&b"S0"[..], b"O", b"C"])]
    fn adapter_state_round_trips_through_bits(#[case] lines: &[&[u8]]) {
        let mut adapter = Adapter::new();
        for line in lines {
            adapter.handle_line(Ok(line));
        }
        assert_eq!(Adapter::from_bits(adapter.to_bits()), adapter);
    }

    #[rstest]
    #[case::open(b"O", Command::Open)]
    #[case::listen(b"L", Command::ListenOnly)]
    #[case::close(b"C", Command::Close)]
    #[case::bitrate_250k(b"S5", Command::Bitrate(5))]
    #[case::allocate_explicit(b"t42E6004B03010100", Command::Frame(frame(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00])))]
    #[case::lower_case_hex(b"t42c5000e010101", Command::Frame(frame(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01])))]
    #[case::empty_poll(b"t42D0", Command::Frame(frame(0x42D, &[])))]
    #[case::highest_id(b"t7FF0", Command::Frame(frame(0x7FF, &[])))]
    #[case::extended(b"T1234567820102", Command::ExtendedFrame)]
    #[case::remote(b"r42D0", Command::RemoteFrame)]
    #[case::extended_remote(b"R123456780", Command::ExtendedRemoteFrame)]
    #[case::version(b"V", Command::Version)]
    #[case::timestamps_off(b"Z0", Command::TimestampsOff)]
    #[case::acceptance_mask(b"mFFFFFFFF", Command::Acceptance)]
    fn parse_good(#[case] line: &[u8], #[case] command: Command) {
        assert_eq!(parse(line), Ok(command));
    }

    #[rstest]
    #[case::empty(b"", SlcanError::Empty)]
    #[case::unknown(b"X", SlcanError::UnknownCommand(b'X'))]
    #[case::open_with_junk(b"O1", SlcanError::Length)]
    #[case::bitrate_9(b"S9", SlcanError::Bitrate)]
    #[case::bitrate_missing(b"S", SlcanError::Length)]
    #[case::id_too_big(b"t8000", SlcanError::Identifier)]
    #[case::dlc_9(b"t4259", SlcanError::Dlc)]
    #[case::data_short(b"t42530000", SlcanError::Length)]
    #[case::data_long(b"t42510000", SlcanError::Length)]
    #[case::not_hex(b"t42G0", SlcanError::NotHex)]
    #[case::not_hex_data(b"t4251ZZ", SlcanError::NotHex)]
    #[case::truncated(b"t42", SlcanError::Length)]
    #[case::extended_id_too_big(b"T200000000", SlcanError::Identifier)]
    #[case::timestamps_on(b"Z1", SlcanError::Unsupported)]
    #[case::btr(b"s031C", SlcanError::Unsupported)]
    fn parse_bad(#[case] line: &[u8], #[case] err: SlcanError) {
        assert_eq!(parse(line), Err(err));
    }

    #[rstest]
    #[case::allocate_response(frame(0x42B, &[0x00, 0xCB, 0x00]), b"t42B300CB00\r")]
    #[case::dup_mac(frame(0x42F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]), b"t42F7003412785634 12\r")]
    #[case::empty(frame(0x005, &[]), b"t0050\r")]
    #[case::eight_bytes(frame(0x3C5, &[0x41, 0, 0, 0x0F, 0, 0, 0, 0xFF]), b"t3C584100000F000000FF\r")]
    fn format(#[case] f: CanFrame, #[case] line: &[u8]) {
        let expected: std::vec::Vec<u8> = line.iter().copied().filter(|&b| b != b' ').collect();
        assert_eq!(frame_line(&f).as_slice(), expected.as_slice());
        // And back.
        assert_eq!(parse(&expected[..expected.len() - 1]), Ok(Command::Frame(f)));
    }

    fn feed(lines: &mut LineBuffer, adapter: &mut Adapter, bytes: &[u8]) -> std::vec::Vec<Response> {
        let mut out = std::vec::Vec::new();
        for &b in bytes {
            if let Some(line) = lines.push(b) {
                out.push(adapter.handle_line(line));
            }
        }
        out
    }

    #[test]
    fn session() {
        let mut lines = LineBuffer::new();
        let mut adapter = Adapter::new();
        let r = feed(&mut lines, &mut adapter, b"t42E6004B03010100\rS5\rO\r\nS4\rt42E6004B03010100\rC\r");
        let replies: std::vec::Vec<&[u8]> = r.iter().map(|r| r.reply).collect();
        assert_eq!(replies, [ERROR, OK, OK, ERROR, TRANSMITTED, OK]);
        assert_eq!(r[4].frame, Some(frame(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00])));
        assert!(r.iter().enumerate().all(|(i, r)| (i == 4) == r.frame.is_some()));
        assert_eq!(adapter.bitrate(), Some(5));
        assert!(!adapter.is_open());
    }

    #[test]
    fn listen_only_refuses_frames() {
        let mut lines = LineBuffer::new();
        let mut adapter = Adapter::new();
        let r = feed(&mut lines, &mut adapter, b"L\rt42D0\r");
        assert_eq!(r[1].reply, ERROR);
        assert!(adapter.is_open());
    }

    #[test]
    fn overlong_line_is_an_error_and_the_next_line_works() {
        let mut lines = LineBuffer::new();
        let mut adapter = Adapter::new();
        let mut input = std::vec![b'O'; 100];
        input.extend_from_slice(b"\rO\r");
        let r = feed(&mut lines, &mut adapter, &input);
        assert_eq!(r.len(), 2);
        assert_eq!((r[0].reply, r[1].reply), (ERROR, OK));
    }

    #[test]
    fn no_panic_on_any_short_line() {
        // Every line of up to two bytes over a small alphabet, and some random long ones.
        let alphabet = b"OLCStTrRVNFZMm0189AFafGz\x00\xFF";
        let mut adapter = Adapter::new();
        for &a in alphabet {
            for &b in alphabet {
                let _ = adapter.handle_line(Ok(&[a]));
                let _ = adapter.handle_line(Ok(&[a, b]));
            }
        }
        let mut seed = 0x1234_5678u32;
        for _ in 0..10_000 {
            let mut line = [0u8; MAX_LINE];
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            let len = (seed % MAX_LINE as u32) as usize;
            for (i, b) in line.iter_mut().enumerate() {
                *b = alphabet[(seed.rotate_left(i as u32) as usize) % alphabet.len()];
            }
            let _ = adapter.handle_line(Ok(&line[..len]));
        }
    }
}
