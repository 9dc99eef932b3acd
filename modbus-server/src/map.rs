//! The register map: what each Modbus register address holds, computed from the scanner's state
//! ([`ScannerState`]) at the moment of the request. Pure: no I/O, no clock, no lock; the server
//! ([`crate::server`]) takes the state's lock, calls [`read_registers`] and answers.
//!
//! The layout follows the status data table of Pyramid Solutions' BridgeWay DeviceNet scanner
//! (AB7603 user manual, Modbus/TCP chapter, "Status Data Table" and "Input Status Register Bit
//! Definitions", PUB-AB7603-014, 2011): a scan counter, then 64-bit node tables (faulted, auto
//! verify error, idle, active), then a status byte per MAC ID. The addresses are our own (the
//! BridgeWay's status table starts at input register 257 behind its input data); every table is
//! kept, and each node's input and output image is at a fixed address per MAC ID so that a SCADA
//! tag can name it. The guide's page `docs/src/plant/modbus-tcp.md` documents the same map.
//!
//! Addresses here are the protocol's (0-based, as in the request PDU); a SCADA that numbers input
//! registers from 1 (`30001`) adds 1.
//!
//! ## No-panic contract
//!
//! [`read_registers`] answers every `(address, quantity)` pair, with the values or a
//! [`MapError`]; it indexes nothing it has not checked.

use dnet_scanner::model::{NodeState, NodeStatus, ScannerState, ScannerStatus};
use thiserror::Error;

/// Scan counter: full scan cycles done, 32 bits, low word first (2 registers).
pub const SCAN_COUNTER: u16 = 0;
/// Active node table: a node of the scan list (64 bits, 4 registers; bit `m % 16` of register
/// `ACTIVE_TABLE + m / 16` is MAC `m`).
pub const ACTIVE_TABLE: u16 = 2;
/// Faulted node table: a node of the scan list with a non-zero status code other than idle (86).
pub const FAULTED_TABLE: u16 = 6;
/// Idle node table: a node in I/O that produces idle (zero-length) data, code 86.
pub const IDLE_TABLE: u16 = 10;
/// Auto verify error table: a node whose identity (code 73) or I/O sizes (code 77) do not match
/// the scan list.
pub const VERIFY_ERROR_TABLE: u16 = 14;
/// Scanner status bits ([`scanner_status_bits`]).
pub const SCANNER_STATUS: u16 = 18;
/// The scanner's own MAC ID.
pub const SCANNER_MAC: u16 = 19;
/// The number of nodes in the scan list.
pub const NODE_COUNT: u16 = 20;
/// Median scan cycle time, in 0.1 ms (saturates at 65535).
pub const CYCLE_TIME: u16 = 21;
/// Bus load, in 0.1 % (0-1000).
pub const BUS_LOAD: u16 = 22;
/// Node status table: one register per MAC ID (64), the node's status code (0 for a MAC not in
/// the scan list; the scanner's own status at its MAC).
pub const NODE_STATUS_TABLE: u16 = 32;
/// The first node block: MAC `m`'s block is at `NODE_BLOCK_BASE + m * NODE_BLOCK_LEN`.
pub const NODE_BLOCK_BASE: u16 = 256;
/// The registers of one node block.
pub const NODE_BLOCK_LEN: u16 = 256;
/// In a node block: the node's status code.
pub const NODE_STATUS: u16 = 0;
/// In a node block: the node's flags ([`node_flags`]).
pub const NODE_FLAGS: u16 = 1;
/// In a node block: the input size read, bytes (0: not read).
pub const NODE_INPUT_SIZE: u16 = 2;
/// In a node block: the output size read, bytes (0: not read).
pub const NODE_OUTPUT_SIZE: u16 = 3;
/// In a node block: cycles with data exchanged, 32 bits, low word first (2 registers; wraps).
pub const NODE_EXCHANGES: u16 = 4;
/// In a node block: the input image, two bytes a register ([`IMAGE_REGISTERS`] registers).
pub const NODE_INPUT: u16 = 8;
/// In a node block: the output image, two bytes a register ([`IMAGE_REGISTERS`] registers).
pub const NODE_OUTPUT: u16 = 136;
/// The registers of an image in a node block: 240 bytes; a longer image is cut there and its
/// node's flag says so.
pub const IMAGE_REGISTERS: u16 = 120;
/// The first address past the map (64 node blocks after the status tables).
pub const MAP_END: u32 = NODE_BLOCK_BASE as u32 + 64 * NODE_BLOCK_LEN as u32;
/// The most registers one read may ask for (Modbus Application Protocol v1.1b3 §6.3, §6.4:
/// quantity 1 to 125).
pub const MAX_READ: u16 = 125;

/// Scanner status bit: scanning (running, or running with bus warnings) — the BridgeWay's
/// "Run mode" bit.
pub const STATUS_RUN: u16 = 1 << 0;
/// Scanner status bit: the scanner itself is faulted (bus-off or duplicate MAC ID).
pub const STATUS_FAULTED: u16 = 1 << 1;
/// Scanner status bit: at least one node is faulted (the faulted node table is not empty).
pub const STATUS_NODE_FAULT: u16 = 1 << 3;
/// Scanner status bit: at least one node failed verification (auto verify error table).
pub const STATUS_VERIFY_FAULT: u16 = 1 << 4;
/// Scanner status bit: bus-off (code 91).
pub const STATUS_BUS_OFF: u16 = 1 << 5;
/// Scanner status bit: another node has the scanner's MAC ID (code 70).
pub const STATUS_DUPLICATE_MAC: u16 = 1 << 6;
/// Scanner status bit (ours; not in the BridgeWay's register): network access in progress.
pub const STATUS_STARTING: u16 = 1 << 8;
/// Scanner status bit (ours): the bus is in error-warning state.
pub const STATUS_BUS_WARNING: u16 = 1 << 9;
/// Scanner status bit (ours): the scanner stopped.
pub const STATUS_STOPPED: u16 = 1 << 10;

/// Node flag: the input image is longer than [`IMAGE_REGISTERS`] registers and is cut.
pub const FLAG_INPUT_CUT: u16 = 1 << 0;
/// Node flag: the output image is longer than [`IMAGE_REGISTERS`] registers and is cut.
pub const FLAG_OUTPUT_CUT: u16 = 1 << 1;
/// Node flag: the node is in the scan list (the other words of a block of a MAC that is not are 0).
pub const FLAG_IN_SCAN_LIST: u16 = 1 << 2;
/// Node flag: in I/O with data exchanged this cycle (status code 0).
pub const FLAG_OK: u16 = 1 << 3;

/// Why a read is refused; each maps to a Modbus exception code ([`MapError::exception_code`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Error)]
pub enum MapError {
    /// Quantity 0 or more than [`MAX_READ`]: exception 03 (illegal data value).
    #[error("read of {quantity} registers: 1 to {MAX_READ} may be read at once")]
    Quantity {
        /// The quantity asked for.
        quantity: u16,
    },
    /// The range runs past [`MAP_END`]: exception 02 (illegal data address).
    #[error("registers {address}..{end}: the map ends at {MAP_END}")]
    Address {
        /// The first register asked for.
        address: u16,
        /// One past the last.
        end: u32,
    },
}

impl MapError {
    /// The Modbus exception code: 03 for a quantity, 02 for an address.
    #[must_use]
    pub fn exception_code(self) -> u8 {
        match self {
            MapError::Quantity { .. } => 0x03,
            MapError::Address { .. } => 0x02,
        }
    }
}

/// `quantity` registers from `address` (FC 03 and FC 04 read the same map), or why not: the
/// quantity is checked before the address, as the Modbus specification orders the checks.
pub fn read_registers(state: &ScannerState, address: u16, quantity: u16) -> Result<Vec<u16>, MapError> {
    if quantity == 0 || quantity > MAX_READ {
        return Err(MapError::Quantity { quantity });
    }
    let end = u32::from(address) + u32::from(quantity);
    if end > MAP_END {
        return Err(MapError::Address { address, end });
    }
    let view = View::new(state);
    Ok((u32::from(address)..end).map(|a| view.register(a)).collect())
}

/// The state with its nodes indexed by MAC ID and the node tables computed once per request.
struct View<'a> {
    state: &'a ScannerState,
    nodes: [Option<&'a NodeState>; 64],
    tables: [u64; 4],
}

impl<'a> View<'a> {
    fn new(state: &'a ScannerState) -> Self {
        let mut nodes = [None; 64];
        let mut tables = [0u64; 4];
        for node in &state.nodes {
            if let Some(slot) = nodes.get_mut(usize::from(node.mac)) {
                *slot = Some(node);
                let bit = 1u64 << node.mac;
                tables[0] |= bit;
                if is_faulted(node.status) {
                    tables[1] |= bit;
                }
                if node.status == NodeStatus::Idle {
                    tables[2] |= bit;
                }
                if matches!(node.status, NodeStatus::KeyingMismatch | NodeStatus::SizeMismatch) {
                    tables[3] |= bit;
                }
            }
        }
        View { state, nodes, tables }
    }

    fn register(&self, address: u32) -> u16 {
        let base = u32::from(NODE_BLOCK_BASE);
        if address >= base {
            let mac = (address - base) / u32::from(NODE_BLOCK_LEN);
            let offset = (address - base) % u32::from(NODE_BLOCK_LEN);
            return match self.nodes.get(mac as usize) {
                Some(Some(node)) => node_register(node, offset as u16),
                _ => 0,
            };
        }
        let a = address as u16;
        let word = |table: usize, first: u16| {
            let shift = u32::from(a - first) * 16;
            (self.tables.get(table).copied().unwrap_or(0) >> shift) as u16
        };
        match a {
            SCAN_COUNTER => self.state.cycles as u16,
            1 => (self.state.cycles >> 16) as u16,
            ACTIVE_TABLE..FAULTED_TABLE => word(0, ACTIVE_TABLE),
            FAULTED_TABLE..IDLE_TABLE => word(1, FAULTED_TABLE),
            IDLE_TABLE..VERIFY_ERROR_TABLE => word(2, IDLE_TABLE),
            VERIFY_ERROR_TABLE..SCANNER_STATUS => word(3, VERIFY_ERROR_TABLE),
            SCANNER_STATUS => scanner_status_bits(self.state.status, self.tables[1], self.tables[3]),
            SCANNER_MAC => u16::from(self.state.mac),
            NODE_COUNT => self.state.nodes.len().min(usize::from(u16::MAX)) as u16,
            CYCLE_TIME => tenths(self.state.cycle_ms),
            BUS_LOAD => tenths(self.state.bus_load * 100.0).min(1000),
            _ if (NODE_STATUS_TABLE..NODE_STATUS_TABLE + 64).contains(&a) => {
                let mac = a - NODE_STATUS_TABLE;
                match self.nodes.get(usize::from(mac)) {
                    Some(Some(node)) => u16::from(node.status.code()),
                    _ if mac == u16::from(self.state.mac) => u16::from(scanner_code(self.state.status)),
                    _ => 0,
                }
            }
            _ => 0,
        }
    }
}

/// Faulted: not exchanging data for a reason other than idle data (codes 72, 73, 77, 78, 83, 84).
fn is_faulted(status: NodeStatus) -> bool {
    !matches!(status, NodeStatus::Ok | NodeStatus::Idle)
}

/// `value * 10`, rounded, in 0..=65535 (NaN: 0).
fn tenths(value: f64) -> u16 {
    let t = (value * 10.0).round();
    if t.is_nan() || t <= 0.0 {
        0
    } else if t >= f64::from(u16::MAX) {
        u16::MAX
    } else {
        t as u16
    }
}

/// The scanner status register: the BridgeWay's input status bits 0, 1, 3, 4, 5 and 6, and ours
/// 8-10 (`faulted` and `verify` are the faulted and auto verify error node tables).
#[must_use]
pub fn scanner_status_bits(status: ScannerStatus, faulted: u64, verify: u64) -> u16 {
    let mut bits = match status {
        ScannerStatus::Starting => STATUS_STARTING,
        ScannerStatus::Running => STATUS_RUN,
        ScannerStatus::BusWarning => STATUS_RUN | STATUS_BUS_WARNING,
        ScannerStatus::BusOff => STATUS_FAULTED | STATUS_BUS_OFF,
        ScannerStatus::DuplicateMac => STATUS_FAULTED | STATUS_DUPLICATE_MAC,
        ScannerStatus::Stopped => STATUS_STOPPED,
    };
    if faulted != 0 {
        bits |= STATUS_NODE_FAULT;
    }
    if verify != 0 {
        bits |= STATUS_VERIFY_FAULT;
    }
    bits
}

/// The scanner's own entry in the node status table: 70 (duplicate MAC ID) and 91 (bus-off), the
/// two states of the scanner that have a status code (`dnet_scanner::model`); 0 otherwise.
#[must_use]
pub fn scanner_code(status: ScannerStatus) -> u8 {
    match status {
        ScannerStatus::DuplicateMac => 70,
        ScannerStatus::BusOff => 91,
        _ => 0,
    }
}

/// The node's flags register.
#[must_use]
pub fn node_flags(node: &NodeState) -> u16 {
    let cut = |image: &[u8]| image.len() > 2 * usize::from(IMAGE_REGISTERS);
    let mut flags = FLAG_IN_SCAN_LIST;
    if cut(&node.input) {
        flags |= FLAG_INPUT_CUT;
    }
    if cut(&node.output) {
        flags |= FLAG_OUTPUT_CUT;
    }
    if node.status == NodeStatus::Ok {
        flags |= FLAG_OK;
    }
    flags
}

/// Register `index` of an image: bytes `2 * index` (low byte) and `2 * index + 1` (high byte), so
/// that a DeviceNet INT (little-endian on the wire) reads as its value; 0 past the image's end.
#[must_use]
pub fn image_register(image: &[u8], index: u16) -> u16 {
    let at = |i: usize| image.get(i).copied().map_or(0, u16::from);
    let first = 2 * usize::from(index);
    at(first) | at(first + 1) << 8
}

fn node_register(node: &NodeState, offset: u16) -> u16 {
    match offset {
        NODE_STATUS => u16::from(node.status.code()),
        NODE_FLAGS => node_flags(node),
        NODE_INPUT_SIZE => node.input_size.unwrap_or(0),
        NODE_OUTPUT_SIZE => node.output_size.unwrap_or(0),
        NODE_EXCHANGES => node.exchanges as u16,
        5 => (node.exchanges >> 16) as u16,
        o if (NODE_INPUT..NODE_INPUT + IMAGE_REGISTERS).contains(&o) => {
            image_register(&node.input, o - NODE_INPUT)
        }
        o if (NODE_OUTPUT..NODE_OUTPUT + IMAGE_REGISTERS).contains(&o) => {
            image_register(&node.output, o - NODE_OUTPUT)
        }
        _ => 0,
    }
}

#[cfg(test)]
mod tests;
