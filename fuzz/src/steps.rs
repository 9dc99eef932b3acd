//! The byte format of the frame-sequence fuzz inputs, shared with the seed generator.
//!
//! An input is a list of records: `[dt, kind|len, id_hi, id_lo, data…]`:
//!
//! | byte | meaning |
//! |---|---|
//! | `dt` | time since the previous record, in 10 ms units (0–2.55 s) |
//! | `kind\|len` | bits 7–6: 0 or 1 a CAN frame, 2 serial bytes from the instrument (a time step only for the bare node), 3 bus-off; bits 5–0: the data length (a CAN frame takes at most 8) |
//! | `id_hi`, `id_lo` | the 11-bit identifier (`id_hi & 7`); ignored but present for the other kinds |
//! | `data` | `len` bytes (fewer if the input ends) |

/// Milliseconds per unit of `dt`.
pub const DT_UNIT_MS: u64 = 10;

/// One decoded record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step<'a> {
    /// A CAN frame `(id, data)` arrives.
    Frame(u16, &'a [u8]),
    /// Bytes from the instrument arrive (a plain time step for the bare node).
    Serial(&'a [u8]),
    /// The CAN controller goes bus-off.
    BusOff,
}

/// Decodes `input` into `(milliseconds since the previous record, step)` pairs.
pub fn steps(mut input: &[u8]) -> impl Iterator<Item = (u64, Step<'_>)> {
    core::iter::from_fn(move || {
        let (head, rest) = input.split_at_checked(4)?;
        let dt = u64::from(head[0]) * DT_UNIT_MS;
        let kind = head[1] >> 6;
        let len = usize::from(head[1] & 0x3F);
        let id = u16::from(head[2] & 7) << 8 | u16::from(head[3]);
        let take = match kind {
            0 | 1 => len.min(8),
            2 => len,
            _ => 0,
        }
        .min(rest.len());
        let (data, rest) = rest.split_at(take);
        input = rest;
        let step = match kind {
            0 | 1 => Step::Frame(id, data),
            2 => Step::Serial(data),
            _ => Step::BusOff,
        };
        Some((dt, step))
    })
}

/// Encodes one record (for seeds).
pub fn encode(out: &mut Vec<u8>, dt_ms: u64, step: Step<'_>) {
    let dt = (dt_ms / DT_UNIT_MS).min(255) as u8;
    let (kind, id, data): (u8, u16, &[u8]) = match step {
        Step::Frame(id, data) => (0, id, &data[..data.len().min(8)]),
        Step::Serial(data) => (2, 0, &data[..data.len().min(63)]),
        Step::BusOff => (3, 0, &[]),
    };
    out.extend_from_slice(&[dt, kind << 6 | data.len() as u8, (id >> 8) as u8 & 7, id as u8]);
    out.extend_from_slice(data);
}

/// Splits `input` into length-prefixed chunks of at most `max` bytes: `[len, bytes…]`.
pub fn chunks(mut input: &[u8], max: usize) -> impl Iterator<Item = &[u8]> {
    core::iter::from_fn(move || {
        let (&len, rest) = input.split_first()?;
        let n = (usize::from(len) % (max + 1)).min(rest.len());
        let (chunk, rest) = rest.split_at(n);
        input = rest;
        Some(chunk)
    })
}

/// Encodes length-prefixed chunks (for seeds).
pub fn encode_chunk(out: &mut Vec<u8>, chunk: &[u8]) {
    out.push(chunk.len() as u8);
    out.extend_from_slice(chunk);
}
