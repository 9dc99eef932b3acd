//! The breaker's commands through its poll output (guide: reference/io-data.md, "Commands
//! through the poll output"): byte 0 the command code, byte 1 a sequence number, bytes 2–7 the
//! arguments. The converter executes a command once, on a change of code or sequence number
//! (`slave_fw::serial::sequencer`), so every command here carries the node's last sequence number
//! plus one. One builder for the console's breaker buttons, the OPC UA `Open`/`Close` methods and
//! Sparkplug's `Breaker/Open`/`Breaker/Close` DCMD metrics.

pub use slave_fw::serial::breaker::BreakerCommand;
use slave_fw::serial::sequencer::Command;

/// The output image that has the breaker execute `command`: `output_size` bytes (the node's
/// consumed size; `None`: 8), at least the 5 that hold code, sequence number and the longest
/// arguments (set parameter: id, value low, value high); byte 1, the sequence number, is that of
/// `current` (the node's output image now; nothing: 0) plus one, wrapping.
#[must_use]
pub fn breaker_output(command: BreakerCommand, current: &[u8], output_size: Option<u16>) -> Vec<u8> {
    let sequence = current.get(1).copied().unwrap_or(0).wrapping_add(1);
    let data = command.to_data();
    let mut args = [0u8; 6];
    for (slot, &b) in args.iter_mut().zip(data.iter().skip(1)) {
        *slot = b;
    }
    let bytes = Command { code: command.code(), sequence, args }.to_bytes();
    let mut out = bytes.to_vec();
    out.resize(output_size.map_or(bytes.len(), usize::from).max(5), 0);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::open(BreakerCommand::Open, &[1, 8, 0, 0, 0, 0, 0, 0])]
    #[case::close(BreakerCommand::Close, &[2, 8, 0, 0, 0, 0, 0, 0])]
    #[case::set_parameter(BreakerCommand::SetParameter { id: 3, value: 0x1234 }, &[3, 8, 3, 0x34, 0x12, 0, 0, 0])]
    #[case::refresh(BreakerCommand::Refresh, &[4, 8, 0, 0, 0, 0, 0, 0])]
    fn every_command(#[case] command: BreakerCommand, #[case] bytes: &[u8]) {
        let out = breaker_output(command, &[2, 7, 0, 0, 0, 0, 0, 0], Some(8));
        assert_eq!(out, bytes);
        // What the converter reads back from those bytes is the command.
        let read = Command::from_outputs(&out).and_then(|c| BreakerCommand::from_command(&c));
        assert_eq!(read, Some(command));
    }

    #[rstest]
    #[case::first(&[], 1)]
    #[case::next(&[1, 41, 0, 0, 0], 42)]
    #[case::wraps(&[2, 255, 0, 0, 0], 0)]
    #[case::short_image(&[1], 1)]
    fn the_sequence_number_is_the_last_plus_one(#[case] current: &[u8], #[case] sequence: u8) {
        assert_eq!(breaker_output(BreakerCommand::Open, current, Some(8))[1], sequence);
    }

    #[rstest]
    #[case::unknown_is_8(None, 8)]
    #[case::longer_is_padded(Some(12), 12)]
    #[case::shorter_keeps_the_arguments(Some(2), 5)]
    fn the_size_is_the_nodes(#[case] size: Option<u16>, #[case] len: usize) {
        let out = breaker_output(BreakerCommand::SetParameter { id: 1, value: 0xBEEF }, &[], size);
        assert_eq!(out.len(), len);
        assert_eq!(out[..5], [3, 1, 1, 0xEF, 0xBE]);
        assert!(out[5..].iter().all(|&b| b == 0));
    }
}
