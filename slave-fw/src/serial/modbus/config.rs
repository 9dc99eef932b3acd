//! The configuration of a Modbus gateway ([`ModbusConfig`]): the line, timing, images, the scan
//! list, and their validation.

use super::entry::{ByteOrder, ScanEntry};
use super::framing::Framing;
use super::pdu;
use crate::serial::error::{as_u32, ConfigError, Conflict, Field, Problem};
use crate::serial::health::HealthConfig;
use crate::serial::line::{DataBits, SerialSettings};
use crate::serial::sequencer::{check_idle_frame, IdleAction, OutputMode};
use crate::serial::{IDLE_FRAME_CAPACITY, IMAGE_CAPACITY};
use heapless::Vec;

/// The most entries in a scan list.
pub const SCAN_LIST_CAPACITY: usize = 16;

/// Everything that describes a Modbus RTU gateway.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ModbusConfig {
    /// The serial line; RTU requires 8 data bits.
    pub serial: SerialSettings,
    /// How requests and responses are framed on the line.
    #[cfg_attr(feature = "serde", serde(default))]
    pub framing: Framing,
    /// Milliseconds to wait for a response after the request's transmission, `1..=60_000`.
    pub response_timeout_ms: u32,
    /// Repetitions of a request after a timeout or corrupted answer, `0..=10`.
    pub retries: u8,
    /// Milliseconds from the start of one read cycle to the start of the next, `0..=3_600_000`
    /// (0: back to back).
    pub poll_period_ms: u32,
    /// Length of the input image in bytes, `0..=64`.
    pub input_len: u16,
    /// Length of the output image in bytes, `0..=64`.
    pub output_len: u16,
    /// Register byte order in the images.
    pub byte_order: ByteOrder,
    /// The transactions, `1..=16`.
    pub scan: Vec<ScanEntry, SCAN_LIST_CAPACITY>,
    /// Stale timeout and policy (no valid response from any slave for that long).
    pub health: HealthConfig,
    /// Sent once on entry into idle: a Modbus ADU without CRC (unit, function, data), `2..=32`
    /// bytes; the CRC is appended.
    pub on_idle: IdleAction,
    /// Sent once on entry into fault, like `on_idle`.
    pub on_fault: IdleAction,
    /// Where the data-valid bits start in the input image, one bit per scan entry (entry `k` is
    /// bit `k % 8` of byte `offset + k / 8`); `None`: no bits. See the [`units`](super::units)
    /// module.
    #[cfg_attr(feature = "serde", serde(default, skip_serializing_if = "Option::is_none"))]
    pub valid_bits_offset: Option<u16>,
}

impl ModbusConfig {
    /// The longest response timeout accepted, one minute.
    pub const MAX_RESPONSE_TIMEOUT_MS: u32 = 60_000;
    /// The most retries accepted.
    pub const MAX_RETRIES: u8 = 10;
    /// The longest poll period accepted, one hour.
    pub const MAX_POLL_PERIOD_MS: u32 = 3_600_000;

    /// A configuration for `scan` with 19200 8E1, 1 s response timeout, 2 retries, a 100 ms poll
    /// period, images just large enough for the scan list (and its trigger bytes), little-endian
    /// registers, 3 s stale timeout holding the last value, nothing on idle or fault, no
    /// data-valid bits.
    pub fn new(scan: Vec<ScanEntry, SCAN_LIST_CAPACITY>) -> Self {
        let end = |write: bool| {
            scan.iter().filter(|e| e.function.is_write() == write).map(|e| e.range().end).max().unwrap_or(0)
        };
        let len = |write| u16::try_from(end(write)).unwrap_or(u16::MAX);
        // The output image also holds every trigger byte ([`ScanEntry::trigger_offset`]).
        let triggers = scan.iter().filter_map(|e| e.trigger_offset).map(|b| b.saturating_add(1)).max();
        ModbusConfig {
            serial: SerialSettings::new_8e1(19200),
            framing: Framing::Rtu,
            response_timeout_ms: 1000,
            retries: 2,
            poll_period_ms: 100,
            input_len: len(false),
            output_len: len(true).max(triggers.unwrap_or(0)),
            byte_order: ByteOrder::LittleEndian,
            scan,
            health: HealthConfig::default(),
            on_idle: IdleAction::Nothing,
            on_fault: IdleAction::Nothing,
            valid_bits_offset: None,
        }
    }

    /// Checks every field, every scan entry against its function and image, that read entries
    /// do not overlap in the input image, nor the data-valid bits any of them.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.serial.validate()?;
        // ASCII takes 7 data bits (§2.5.2.1) or 8, which many ASCII instruments offer too.
        if self.serial.data_bits != DataBits::Eight && self.framing != Framing::Ascii {
            return Err(ConfigError::conflict(Field::SerialDataBits, Conflict::ModbusDataBits));
        }
        ConfigError::check_range(
            Field::ResponseTimeout,
            self.response_timeout_ms,
            1,
            Self::MAX_RESPONSE_TIMEOUT_MS,
        )?;
        ConfigError::check_range(Field::Retries, u32::from(self.retries), 0, u32::from(Self::MAX_RETRIES))?;
        ConfigError::check_range(Field::PollPeriod, self.poll_period_ms, 0, Self::MAX_POLL_PERIOD_MS)?;
        ConfigError::check_range(Field::InputLen, u32::from(self.input_len), 0, as_u32(IMAGE_CAPACITY))?;
        ConfigError::check_range(Field::OutputLen, u32::from(self.output_len), 0, as_u32(IMAGE_CAPACITY))?;
        ConfigError::check_range(Field::Scan, as_u32(self.scan.len()), 1, as_u32(SCAN_LIST_CAPACITY))?;
        for (i, e) in self.scan.iter().enumerate() {
            self.validate_entry(e).map_err(|err| err.at(i))?;
            if e.function.is_write() {
                continue;
            }
            let r = e.range();
            let overlap =
                self.scan.iter().take(i).position(|o| {
                    !o.function.is_write() && o.range().start < r.end && r.start < o.range().end
                });
            if let Some(other) = overlap {
                return Err(ConfigError {
                    field: Field::ScanOffset,
                    index: None,
                    problem: Problem::Overlap { other: u16::try_from(other).unwrap_or(u16::MAX) },
                }
                .at(i));
            }
        }
        super::valid_bits::validate(self.valid_bits_offset, &self.scan, self.input_len)?;
        self.health.validate()?;
        check_idle_frame(Field::OnIdle, &self.on_idle, 2, IDLE_FRAME_CAPACITY)?;
        check_idle_frame(Field::OnFault, &self.on_fault, 2, IDLE_FRAME_CAPACITY)
    }

    /// The frame to send on entry into `mode` (without its CRC), if any.
    pub(super) fn mode_frame(&self, mode: OutputMode) -> Option<&[u8]> {
        match mode {
            OutputMode::Idle => self.on_idle.frame(),
            OutputMode::Fault => self.on_fault.frame(),
            OutputMode::Startup | OutputMode::Run => None,
        }
    }

    fn validate_entry(&self, e: &ScanEntry) -> Result<(), ConfigError> {
        ConfigError::check_range(Field::ScanUnit, u32::from(e.unit), 1, 247)?;
        let image = usize::from(if e.function.is_write() { self.output_len } else { self.input_len });
        // The most items that fit the image at offset 0, and the protocol maximum.
        let fit = if e.function.is_bits() { image.saturating_mul(8) } else { image / 2 };
        let max = u32::from(e.function.max_count()).min(as_u32(fit));
        ConfigError::check_range(Field::ScanCount, u32::from(e.count), 1, max)?;
        ConfigError::check_range(Field::ScanAddress, u32::from(e.address), 0, 0x1_0000 - u32::from(e.count))?;
        // A 32-bit word order moves bytes between the registers of a pair: register functions
        // only, an even count.
        if e.word_order.is_pairwise() {
            let registers = matches!(
                e.function,
                pdu::Function::ReadHoldingRegisters
                    | pdu::Function::ReadInputRegisters
                    | pdu::Function::WriteMultipleRegisters
            );
            if !registers || e.count % 2 != 0 {
                return Err(ConfigError::conflict(Field::ScanWordOrder, Conflict::WordOrderNeedsPairs));
            }
        }
        ConfigError::check_range(
            Field::ScanOffset,
            u32::from(e.offset),
            0,
            as_u32(image.saturating_sub(e.image_len())),
        )?;
        super::schedule::check(e, &self.scan, self.output_len)
    }
}
