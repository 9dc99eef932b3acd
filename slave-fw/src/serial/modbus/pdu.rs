//! The Modbus RTU ADU codec: unit address, PDU, CRC-16 (Modbus Application Protocol V1.1b3 §6,
//! Modbus over Serial Line V1.02 §2.5.1).
//!
//! [`Request`] and [`Response`] are validated representations in the smoltcp style: `parse` takes
//! one complete ADU (address through CRC) and either returns the value or a [`CodecError`];
//! `emit` writes the ADU, CRC included, and `buffer_len` says how long it is. Both directions exist
//! for both, so the same code serves the master here and a simulated slave in tests.
//!
//! RTU has no length field: [`response_len`] and [`request_len`] tell from the first bytes of a
//! frame how long it will be, which is how the master delimits responses.
//!
//! Register values are carried as their big-endian wire bytes (`&[u8]`), so views borrow from the
//! ADU and nothing is copied; bit values are packed LSB first, eight per byte, as on the wire.

use crate::serial::checksum::crc16_modbus;
use core::fmt;

/// The longest RTU ADU: address, 253-byte PDU, CRC.
pub const ADU_CAPACITY: usize = 256;
/// The most data bytes a read response carries (125 registers, 2000 bits).
pub const MAX_READ_BYTES: usize = 250;
/// The most coils or discrete inputs one read may ask for (§6.1, §6.2).
pub const MAX_READ_BITS: u16 = 2000;
/// The most registers one read may ask for (§6.3, §6.4).
pub const MAX_READ_REGISTERS: u16 = 125;
/// The most coils one write may set (§6.11).
pub const MAX_WRITE_BITS: u16 = 1968;
/// The most registers one write may set (§6.12).
pub const MAX_WRITE_REGISTERS: u16 = 123;

/// The public function codes this codec speaks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(try_from = "u8", into = "u8"))]
pub enum Function {
    /// 0x01 Read Coils.
    ReadCoils,
    /// 0x02 Read Discrete Inputs.
    ReadDiscreteInputs,
    /// 0x03 Read Holding Registers.
    ReadHoldingRegisters,
    /// 0x04 Read Input Registers.
    ReadInputRegisters,
    /// 0x05 Write Single Coil.
    WriteSingleCoil,
    /// 0x06 Write Single Register.
    WriteSingleRegister,
    /// 0x0F Write Multiple Coils.
    WriteMultipleCoils,
    /// 0x10 Write Multiple Registers.
    WriteMultipleRegisters,
}

impl Function {
    /// The function code.
    pub const fn code(self) -> u8 {
        match self {
            Function::ReadCoils => 0x01,
            Function::ReadDiscreteInputs => 0x02,
            Function::ReadHoldingRegisters => 0x03,
            Function::ReadInputRegisters => 0x04,
            Function::WriteSingleCoil => 0x05,
            Function::WriteSingleRegister => 0x06,
            Function::WriteMultipleCoils => 0x0F,
            Function::WriteMultipleRegisters => 0x10,
        }
    }

    /// The function for `code`, if this codec speaks it.
    pub const fn from_code(code: u8) -> Option<Function> {
        match code {
            0x01 => Some(Function::ReadCoils),
            0x02 => Some(Function::ReadDiscreteInputs),
            0x03 => Some(Function::ReadHoldingRegisters),
            0x04 => Some(Function::ReadInputRegisters),
            0x05 => Some(Function::WriteSingleCoil),
            0x06 => Some(Function::WriteSingleRegister),
            0x0F => Some(Function::WriteMultipleCoils),
            0x10 => Some(Function::WriteMultipleRegisters),
            _ => None,
        }
    }

    /// Whether the function writes (5, 6, 15, 16).
    pub const fn is_write(self) -> bool {
        matches!(
            self,
            Function::WriteSingleCoil
                | Function::WriteSingleRegister
                | Function::WriteMultipleCoils
                | Function::WriteMultipleRegisters
        )
    }

    /// Whether the function moves bits (coils, discrete inputs) rather than registers.
    pub const fn is_bits(self) -> bool {
        matches!(
            self,
            Function::ReadCoils
                | Function::ReadDiscreteInputs
                | Function::WriteSingleCoil
                | Function::WriteMultipleCoils
        )
    }

    /// The largest quantity one request may carry (1 for the single writes).
    pub const fn max_count(self) -> u16 {
        match self {
            Function::ReadCoils | Function::ReadDiscreteInputs => MAX_READ_BITS,
            Function::ReadHoldingRegisters | Function::ReadInputRegisters => MAX_READ_REGISTERS,
            Function::WriteSingleCoil | Function::WriteSingleRegister => 1,
            Function::WriteMultipleCoils => MAX_WRITE_BITS,
            Function::WriteMultipleRegisters => MAX_WRITE_REGISTERS,
        }
    }

    /// Bytes that `count` bits or registers occupy: `ceil(count / 8)` or `2 × count`.
    pub const fn data_len(self, count: u16) -> usize {
        if self.is_bits() {
            (count as usize).div_ceil(8)
        } else {
            count as usize * 2
        }
    }
}

impl TryFrom<u8> for Function {
    type Error = CodecError;
    fn try_from(code: u8) -> Result<Self, CodecError> {
        Function::from_code(code).ok_or(CodecError::UnknownFunction(code))
    }
}

impl From<Function> for u8 {
    fn from(f: Function) -> u8 {
        f.code()
    }
}

/// An exception code (§7). Unknown codes are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ExceptionCode {
    /// 0x01: the function is not supported.
    IllegalFunction,
    /// 0x02: the address range is not valid.
    IllegalDataAddress,
    /// 0x03: a value in the request is not valid.
    IllegalDataValue,
    /// 0x04: the server failed while performing the action.
    ServerDeviceFailure,
    /// 0x05: accepted, processing will take long.
    Acknowledge,
    /// 0x06: the server is busy.
    ServerDeviceBusy,
    /// 0x08: parity error in extended memory.
    MemoryParityError,
    /// 0x0A: gateway path unavailable.
    GatewayPathUnavailable,
    /// 0x0B: gateway target device failed to respond.
    GatewayTargetFailedToRespond,
    /// Any other code.
    Unknown(u8),
}

impl ExceptionCode {
    /// The code as sent.
    pub const fn as_raw(self) -> u8 {
        match self {
            ExceptionCode::IllegalFunction => 0x01,
            ExceptionCode::IllegalDataAddress => 0x02,
            ExceptionCode::IllegalDataValue => 0x03,
            ExceptionCode::ServerDeviceFailure => 0x04,
            ExceptionCode::Acknowledge => 0x05,
            ExceptionCode::ServerDeviceBusy => 0x06,
            ExceptionCode::MemoryParityError => 0x08,
            ExceptionCode::GatewayPathUnavailable => 0x0A,
            ExceptionCode::GatewayTargetFailedToRespond => 0x0B,
            ExceptionCode::Unknown(c) => c,
        }
    }
}

impl From<u8> for ExceptionCode {
    fn from(raw: u8) -> Self {
        match raw {
            0x01 => ExceptionCode::IllegalFunction,
            0x02 => ExceptionCode::IllegalDataAddress,
            0x03 => ExceptionCode::IllegalDataValue,
            0x04 => ExceptionCode::ServerDeviceFailure,
            0x05 => ExceptionCode::Acknowledge,
            0x06 => ExceptionCode::ServerDeviceBusy,
            0x08 => ExceptionCode::MemoryParityError,
            0x0A => ExceptionCode::GatewayPathUnavailable,
            0x0B => ExceptionCode::GatewayTargetFailedToRespond,
            c => ExceptionCode::Unknown(c),
        }
    }
}

impl fmt::Display for ExceptionCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExceptionCode::IllegalFunction => f.write_str("illegal function"),
            ExceptionCode::IllegalDataAddress => f.write_str("illegal data address"),
            ExceptionCode::IllegalDataValue => f.write_str("illegal data value"),
            ExceptionCode::ServerDeviceFailure => f.write_str("server device failure"),
            ExceptionCode::Acknowledge => f.write_str("acknowledge"),
            ExceptionCode::ServerDeviceBusy => f.write_str("server device busy"),
            ExceptionCode::MemoryParityError => f.write_str("memory parity error"),
            ExceptionCode::GatewayPathUnavailable => f.write_str("gateway path unavailable"),
            ExceptionCode::GatewayTargetFailedToRespond => {
                f.write_str("gateway target device failed to respond")
            }
            ExceptionCode::Unknown(c) => write!(f, "exception 0x{c:02X}"),
        }
    }
}

/// Why an ADU could not be parsed or emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CodecError {
    /// Fewer bytes than the smallest ADU of its kind.
    TooShort,
    /// The ADU's length does not match its function and byte count.
    Length {
        /// The length the contents call for.
        expected: usize,
        /// The length given.
        found: usize,
    },
    /// The CRC does not match.
    Crc,
    /// A function code this codec does not speak.
    UnknownFunction(u8),
    /// A byte count that does not match the quantity, or is odd for registers.
    ByteCount,
    /// A quantity of zero or above the function's maximum.
    Count(u16),
    /// A Write Single Coil value other than 0xFF00 or 0x0000.
    CoilValue(u16),
    /// The output buffer is shorter than the ADU.
    BufferTooSmall {
        /// The ADU's length.
        needed: usize,
    },
}

impl fmt::Display for CodecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CodecError::TooShort => f.write_str("frame too short"),
            CodecError::Length { expected, found } => {
                write!(f, "frame of {found} bytes, expected {expected}")
            }
            CodecError::Crc => f.write_str("CRC mismatch"),
            CodecError::UnknownFunction(c) => write!(f, "unknown function 0x{c:02X}"),
            CodecError::ByteCount => f.write_str("byte count does not match the quantity"),
            CodecError::Count(n) => write!(f, "quantity {n} out of range"),
            CodecError::CoilValue(v) => write!(f, "coil value 0x{v:04X} is neither 0xFF00 nor 0x0000"),
            CodecError::BufferTooSmall { needed } => write!(f, "the frame needs {needed} bytes"),
        }
    }
}

impl core::error::Error for CodecError {}

/// A request from master to slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Request<'a> {
    /// 0x01: `count` coils from `address`.
    ReadCoils {
        /// First coil.
        address: u16,
        /// Quantity, `1..=2000`.
        count: u16,
    },
    /// 0x02: `count` discrete inputs from `address`.
    ReadDiscreteInputs {
        /// First input.
        address: u16,
        /// Quantity, `1..=2000`.
        count: u16,
    },
    /// 0x03: `count` holding registers from `address`.
    ReadHoldingRegisters {
        /// First register.
        address: u16,
        /// Quantity, `1..=125`.
        count: u16,
    },
    /// 0x04: `count` input registers from `address`.
    ReadInputRegisters {
        /// First register.
        address: u16,
        /// Quantity, `1..=125`.
        count: u16,
    },
    /// 0x05: set one coil.
    WriteSingleCoil {
        /// The coil.
        address: u16,
        /// On (0xFF00) or off (0x0000).
        value: bool,
    },
    /// 0x06: set one holding register.
    WriteSingleRegister {
        /// The register.
        address: u16,
        /// The value.
        value: u16,
    },
    /// 0x0F: set `count` coils from `address`.
    WriteMultipleCoils {
        /// First coil.
        address: u16,
        /// Quantity, `1..=1968`.
        count: u16,
        /// `ceil(count / 8)` bytes, LSB first.
        bits: &'a [u8],
    },
    /// 0x10: set holding registers from `address`.
    WriteMultipleRegisters {
        /// First register.
        address: u16,
        /// Big-endian register values, 2 bytes each, `1..=123` registers.
        values: &'a [u8],
    },
}

/// A response from slave to master.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Response<'a> {
    /// 0x01: coil states, LSB first.
    ReadCoils(&'a [u8]),
    /// 0x02: input states, LSB first.
    ReadDiscreteInputs(&'a [u8]),
    /// 0x03: big-endian register values.
    ReadHoldingRegisters(&'a [u8]),
    /// 0x04: big-endian register values.
    ReadInputRegisters(&'a [u8]),
    /// 0x05: echo of the request.
    WriteSingleCoil {
        /// The coil.
        address: u16,
        /// Its new state.
        value: bool,
    },
    /// 0x06: echo of the request.
    WriteSingleRegister {
        /// The register.
        address: u16,
        /// Its new value.
        value: u16,
    },
    /// 0x0F: address and quantity written.
    WriteMultipleCoils {
        /// First coil.
        address: u16,
        /// Quantity.
        count: u16,
    },
    /// 0x10: address and quantity written.
    WriteMultipleRegisters {
        /// First register.
        address: u16,
        /// Quantity.
        count: u16,
    },
    /// `function | 0x80, code`.
    Exception {
        /// The function code of the refused request (without the 0x80 bit).
        function: u8,
        /// Why.
        code: ExceptionCode,
    },
}

/// Checks the trailing CRC of a whole ADU and returns the bytes before it.
fn strip_crc(adu: &[u8], min_len: usize) -> Result<&[u8], CodecError> {
    if adu.len() < min_len {
        return Err(CodecError::TooShort);
    }
    let split = adu.len() - 2;
    let body = adu.get(..split).ok_or(CodecError::TooShort)?;
    let crc = adu.get(split..).ok_or(CodecError::TooShort)?;
    if crc16_modbus(body).to_le_bytes().as_slice() != crc {
        return Err(CodecError::Crc);
    }
    Ok(body)
}

/// The big-endian u16 at `i`, or 0 past the end (callers check lengths first).
fn be16(b: &[u8], i: usize) -> u16 {
    match (b.get(i), b.get(i + 1)) {
        (Some(&hi), Some(&lo)) => u16::from_be_bytes([hi, lo]),
        _ => 0,
    }
}

fn check_len(body: &[u8], expected_adu: usize) -> Result<(), CodecError> {
    let found = body.len() + 2;
    if found == expected_adu {
        Ok(())
    } else {
        Err(CodecError::Length { expected: expected_adu, found })
    }
}

fn check_count(function: Function, count: u16) -> Result<(), CodecError> {
    if (1..=function.max_count()).contains(&count) {
        Ok(())
    } else {
        Err(CodecError::Count(count))
    }
}

fn coil_value(raw: u16) -> Result<bool, CodecError> {
    match raw {
        0xFF00 => Ok(true),
        0x0000 => Ok(false),
        v => Err(CodecError::CoilValue(v)),
    }
}

fn coil_raw(value: bool) -> u16 {
    if value {
        0xFF00
    } else {
        0x0000
    }
}

/// A bounds-checked ADU writer; `finish` appends the CRC.
struct AduWriter<'a> {
    out: &'a mut [u8],
    pos: usize,
}

impl<'a> AduWriter<'a> {
    fn new(out: &'a mut [u8], len: usize) -> Result<Self, CodecError> {
        match out.get_mut(..len) {
            Some(out) => Ok(AduWriter { out, pos: 0 }),
            None => Err(CodecError::BufferTooSmall { needed: len }),
        }
    }

    fn u8(&mut self, b: u8) {
        if let Some(slot) = self.out.get_mut(self.pos) {
            *slot = b;
        }
        self.pos += 1;
    }

    fn u16(&mut self, v: u16) {
        for b in v.to_be_bytes() {
            self.u8(b);
        }
    }

    fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.u8(b);
        }
    }

    fn finish(mut self) -> usize {
        let crc = crc16_modbus(self.out.get(..self.pos).unwrap_or(&[]));
        self.bytes(&crc.to_le_bytes());
        self.pos
    }
}

impl<'a> Request<'a> {
    /// The function.
    pub const fn function(&self) -> Function {
        match self {
            Request::ReadCoils { .. } => Function::ReadCoils,
            Request::ReadDiscreteInputs { .. } => Function::ReadDiscreteInputs,
            Request::ReadHoldingRegisters { .. } => Function::ReadHoldingRegisters,
            Request::ReadInputRegisters { .. } => Function::ReadInputRegisters,
            Request::WriteSingleCoil { .. } => Function::WriteSingleCoil,
            Request::WriteSingleRegister { .. } => Function::WriteSingleRegister,
            Request::WriteMultipleCoils { .. } => Function::WriteMultipleCoils,
            Request::WriteMultipleRegisters { .. } => Function::WriteMultipleRegisters,
        }
    }

    /// The read request of `function` (1–4) for `count` items from `address`; `None` for writes.
    pub const fn read(function: Function, address: u16, count: u16) -> Option<Request<'static>> {
        match function {
            Function::ReadCoils => Some(Request::ReadCoils { address, count }),
            Function::ReadDiscreteInputs => Some(Request::ReadDiscreteInputs { address, count }),
            Function::ReadHoldingRegisters => Some(Request::ReadHoldingRegisters { address, count }),
            Function::ReadInputRegisters => Some(Request::ReadInputRegisters { address, count }),
            _ => None,
        }
    }

    /// The ADU length, address and CRC included.
    pub fn buffer_len(&self) -> usize {
        match self {
            Request::WriteMultipleCoils { bits: data, .. }
            | Request::WriteMultipleRegisters { values: data, .. } => 9 + data.len(),
            _ => 8,
        }
    }

    /// The length of the normal (non-exception) response ADU.
    pub fn response_len(&self) -> usize {
        match *self {
            Request::ReadCoils { count, .. }
            | Request::ReadDiscreteInputs { count, .. }
            | Request::ReadHoldingRegisters { count, .. }
            | Request::ReadInputRegisters { count, .. } => 5 + self.function().data_len(count),
            _ => 8,
        }
    }

    /// Writes the ADU for `unit` into `out`, CRC included; returns its length.
    pub fn emit(&self, unit: u8, out: &mut [u8]) -> Result<usize, CodecError> {
        let function = self.function();
        match *self {
            Request::ReadCoils { count, .. }
            | Request::ReadDiscreteInputs { count, .. }
            | Request::ReadHoldingRegisters { count, .. }
            | Request::ReadInputRegisters { count, .. } => check_count(function, count)?,
            Request::WriteMultipleCoils { count, bits, .. } => {
                check_count(function, count)?;
                if bits.len() != function.data_len(count) {
                    return Err(CodecError::ByteCount);
                }
            }
            Request::WriteMultipleRegisters { values, .. } => {
                if values.len() % 2 != 0 {
                    return Err(CodecError::ByteCount);
                }
                check_count(function, u16::try_from(values.len() / 2).unwrap_or(u16::MAX))?;
            }
            Request::WriteSingleCoil { .. } | Request::WriteSingleRegister { .. } => {}
        }
        let mut w = AduWriter::new(out, self.buffer_len())?;
        w.u8(unit);
        w.u8(function.code());
        match *self {
            Request::ReadCoils { address, count }
            | Request::ReadDiscreteInputs { address, count }
            | Request::ReadHoldingRegisters { address, count }
            | Request::ReadInputRegisters { address, count } => {
                w.u16(address);
                w.u16(count);
            }
            Request::WriteSingleCoil { address, value } => {
                w.u16(address);
                w.u16(coil_raw(value));
            }
            Request::WriteSingleRegister { address, value } => {
                w.u16(address);
                w.u16(value);
            }
            Request::WriteMultipleCoils { address, count, bits } => {
                w.u16(address);
                w.u16(count);
                w.u8(bits.len() as u8);
                w.bytes(bits);
            }
            Request::WriteMultipleRegisters { address, values } => {
                w.u16(address);
                w.u16((values.len() / 2) as u16);
                w.u8(values.len() as u8);
                w.bytes(values);
            }
        }
        Ok(w.finish())
    }

    /// Parses one complete request ADU; returns the unit address and the request.
    pub fn parse(adu: &'a [u8]) -> Result<(u8, Request<'a>), CodecError> {
        let body = strip_crc(adu, 8)?;
        let (&unit, pdu) = body.split_first().ok_or(CodecError::TooShort)?;
        let (&code, data) = pdu.split_first().ok_or(CodecError::TooShort)?;
        let function = Function::try_from(code)?;
        let address = be16(data, 0);
        let word = be16(data, 2);
        let request = match function {
            Function::ReadCoils
            | Function::ReadDiscreteInputs
            | Function::ReadHoldingRegisters
            | Function::ReadInputRegisters => {
                check_len(body, 8)?;
                check_count(function, word)?;
                Request::read(function, address, word).ok_or(CodecError::UnknownFunction(code))?
            }
            Function::WriteSingleCoil => {
                check_len(body, 8)?;
                Request::WriteSingleCoil { address, value: coil_value(word)? }
            }
            Function::WriteSingleRegister => {
                check_len(body, 8)?;
                Request::WriteSingleRegister { address, value: word }
            }
            Function::WriteMultipleCoils | Function::WriteMultipleRegisters => {
                let byte_count = usize::from(*data.get(4).ok_or(CodecError::TooShort)?);
                check_len(body, 9 + byte_count)?;
                check_count(function, word)?;
                if byte_count != function.data_len(word) {
                    return Err(CodecError::ByteCount);
                }
                let payload = data.get(5..5 + byte_count).ok_or(CodecError::TooShort)?;
                if function == Function::WriteMultipleCoils {
                    Request::WriteMultipleCoils { address, count: word, bits: payload }
                } else {
                    Request::WriteMultipleRegisters { address, values: payload }
                }
            }
        };
        Ok((unit, request))
    }
}

impl<'a> Response<'a> {
    /// The function code as sent (with 0x80 for exceptions).
    pub const fn function_code(&self) -> u8 {
        match self {
            Response::ReadCoils(_) => 0x01,
            Response::ReadDiscreteInputs(_) => 0x02,
            Response::ReadHoldingRegisters(_) => 0x03,
            Response::ReadInputRegisters(_) => 0x04,
            Response::WriteSingleCoil { .. } => 0x05,
            Response::WriteSingleRegister { .. } => 0x06,
            Response::WriteMultipleCoils { .. } => 0x0F,
            Response::WriteMultipleRegisters { .. } => 0x10,
            Response::Exception { function, .. } => *function | 0x80,
        }
    }

    /// The ADU length, address and CRC included.
    pub fn buffer_len(&self) -> usize {
        match self {
            Response::ReadCoils(d)
            | Response::ReadDiscreteInputs(d)
            | Response::ReadHoldingRegisters(d)
            | Response::ReadInputRegisters(d) => 5 + d.len(),
            Response::Exception { .. } => 5,
            _ => 8,
        }
    }

    /// Writes the ADU for `unit` into `out`, CRC included; returns its length.
    pub fn emit(&self, unit: u8, out: &mut [u8]) -> Result<usize, CodecError> {
        if let Response::ReadCoils(d)
        | Response::ReadDiscreteInputs(d)
        | Response::ReadHoldingRegisters(d)
        | Response::ReadInputRegisters(d) = self
        {
            if d.len() > MAX_READ_BYTES {
                return Err(CodecError::ByteCount);
            }
        }
        let mut w = AduWriter::new(out, self.buffer_len())?;
        w.u8(unit);
        w.u8(self.function_code());
        match *self {
            Response::ReadCoils(d)
            | Response::ReadDiscreteInputs(d)
            | Response::ReadHoldingRegisters(d)
            | Response::ReadInputRegisters(d) => {
                w.u8(d.len() as u8);
                w.bytes(d);
            }
            Response::WriteSingleCoil { address, value } => {
                w.u16(address);
                w.u16(coil_raw(value));
            }
            Response::WriteSingleRegister { address, value: count }
            | Response::WriteMultipleCoils { address, count }
            | Response::WriteMultipleRegisters { address, count } => {
                w.u16(address);
                w.u16(count);
            }
            Response::Exception { code, .. } => w.u8(code.as_raw()),
        }
        Ok(w.finish())
    }

    /// Parses one complete response ADU; returns the unit address and the response.
    pub fn parse(adu: &'a [u8]) -> Result<(u8, Response<'a>), CodecError> {
        let body = strip_crc(adu, 5)?;
        let (&unit, pdu) = body.split_first().ok_or(CodecError::TooShort)?;
        let (&code, data) = pdu.split_first().ok_or(CodecError::TooShort)?;
        if code & 0x80 != 0 {
            check_len(body, 5)?;
            let exception = *data.first().ok_or(CodecError::TooShort)?;
            return Ok((
                unit,
                Response::Exception { function: code & 0x7F, code: ExceptionCode::from(exception) },
            ));
        }
        let function = Function::try_from(code)?;
        let response = match function {
            Function::ReadCoils
            | Function::ReadDiscreteInputs
            | Function::ReadHoldingRegisters
            | Function::ReadInputRegisters => {
                let byte_count = usize::from(*data.first().ok_or(CodecError::TooShort)?);
                check_len(body, 5 + byte_count)?;
                if byte_count > MAX_READ_BYTES || (!function.is_bits() && byte_count % 2 != 0) {
                    return Err(CodecError::ByteCount);
                }
                let d = data.get(1..1 + byte_count).ok_or(CodecError::TooShort)?;
                match function {
                    Function::ReadCoils => Response::ReadCoils(d),
                    Function::ReadDiscreteInputs => Response::ReadDiscreteInputs(d),
                    Function::ReadHoldingRegisters => Response::ReadHoldingRegisters(d),
                    _ => Response::ReadInputRegisters(d),
                }
            }
            Function::WriteSingleCoil => {
                check_len(body, 8)?;
                Response::WriteSingleCoil { address: be16(data, 0), value: coil_value(be16(data, 2))? }
            }
            Function::WriteSingleRegister => {
                check_len(body, 8)?;
                Response::WriteSingleRegister { address: be16(data, 0), value: be16(data, 2) }
            }
            Function::WriteMultipleCoils => {
                check_len(body, 8)?;
                Response::WriteMultipleCoils { address: be16(data, 0), count: be16(data, 2) }
            }
            Function::WriteMultipleRegisters => {
                check_len(body, 8)?;
                Response::WriteMultipleRegisters { address: be16(data, 0), count: be16(data, 2) }
            }
        };
        Ok((unit, response))
    }

    /// Whether this is the normal response to `request`: same function, the byte count its
    /// quantity calls for, or the echo of what was written. Exceptions are not answers here.
    pub fn answers(&self, request: &Request<'_>) -> bool {
        match (*self, *request) {
            (Response::ReadCoils(d), Request::ReadCoils { count, .. })
            | (Response::ReadDiscreteInputs(d), Request::ReadDiscreteInputs { count, .. })
            | (Response::ReadHoldingRegisters(d), Request::ReadHoldingRegisters { count, .. })
            | (Response::ReadInputRegisters(d), Request::ReadInputRegisters { count, .. }) => {
                d.len() == request.function().data_len(count)
            }
            (
                Response::WriteSingleCoil { address: a, value: v },
                Request::WriteSingleCoil { address, value },
            ) => a == address && v == value,
            (
                Response::WriteSingleRegister { address: a, value: v },
                Request::WriteSingleRegister { address, value },
            ) => a == address && v == value,
            (
                Response::WriteMultipleCoils { address: a, count: c },
                Request::WriteMultipleCoils { address, count, .. },
            ) => a == address && c == count,
            (
                Response::WriteMultipleRegisters { address: a, count: c },
                Request::WriteMultipleRegisters { address, values },
            ) => a == address && usize::from(c) * 2 == values.len(),
            _ => false,
        }
    }
}

/// The length of the response ADU that starts with `prefix`: `Ok(None)` until enough bytes are
/// known (2, or 3 for reads), an error for an unknown function or an impossible byte count.
pub fn response_len(prefix: &[u8]) -> Result<Option<usize>, CodecError> {
    let Some(&code) = prefix.get(1) else {
        return Ok(None);
    };
    if code & 0x80 != 0 {
        return Ok(Some(5));
    }
    match Function::try_from(code)? {
        Function::ReadCoils
        | Function::ReadDiscreteInputs
        | Function::ReadHoldingRegisters
        | Function::ReadInputRegisters => match prefix.get(2) {
            None => Ok(None),
            Some(&n) if usize::from(n) > MAX_READ_BYTES => Err(CodecError::ByteCount),
            Some(&n) => Ok(Some(5 + usize::from(n))),
        },
        _ => Ok(Some(8)),
    }
}

/// Checks a response ADU that [`response_len`] has delimited, so that its length already agrees
/// with its function and byte count: `Ok` exactly when [`Response::parse`] accepts it, the same
/// errors otherwise. What `parse` checks beyond `response_len` (the CRC, an even byte count for
/// registers, a coil value of 0xFF00 or 0x0000), without building the [`Response`]: a master that
/// knows its request reads the few values it needs from the bytes (firmware flash).
pub fn check_delimited_response(adu: &[u8]) -> Result<(), CodecError> {
    let body = strip_crc(adu, 5)?;
    let (Some(&code), Some(&byte_count)) = (body.get(1), body.get(2)) else {
        return Err(CodecError::TooShort);
    };
    match Function::from_code(code) {
        Some(Function::ReadHoldingRegisters | Function::ReadInputRegisters) if byte_count % 2 != 0 => {
            Err(CodecError::ByteCount)
        }
        Some(Function::WriteSingleCoil) => coil_value(be16(body, 4)).map(|_| ()),
        _ => Ok(()),
    }
}

/// The length of the request ADU that starts with `prefix`: `Ok(None)` until enough bytes are
/// known (2, or 7 for the multiple writes), an error for an unknown function.
pub fn request_len(prefix: &[u8]) -> Result<Option<usize>, CodecError> {
    let Some(&code) = prefix.get(1) else {
        return Ok(None);
    };
    match Function::try_from(code)? {
        Function::WriteMultipleCoils | Function::WriteMultipleRegisters => match prefix.get(6) {
            None => Ok(None),
            Some(&n) if 9 + usize::from(n) > ADU_CAPACITY => Err(CodecError::ByteCount),
            Some(&n) => Ok(Some(9 + usize::from(n))),
        },
        _ => Ok(Some(8)),
    }
}

#[cfg(test)]
mod tests;
