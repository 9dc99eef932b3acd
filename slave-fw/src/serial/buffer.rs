//! Receive buffer helpers shared by the framed parser and the Modbus master.

/// Removes the first `n` bytes of `buf` (all of them when `n` is larger), keeping the rest in
/// order.
///
/// A forward byte copy: `heapless::Vec::drain` (and `copy_within`) call `memmove`, which is 1.5 KiB
/// of flash on the firmware for these two buffers of a few hundred bytes
/// (`slave-fw/firmware/size-budget.toml`).
pub(crate) fn drop_front<const N: usize>(buf: &mut heapless::Vec<u8, N>, n: usize) {
    let len = buf.len();
    let n = n.min(len);
    let mut to = 0;
    while let Some(&b) = buf.get(to + n) {
        if let Some(slot) = buf.get_mut(to) {
            *slot = b;
        }
        to += 1;
    }
    buf.truncate(len - n);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::none(0, &[1, 2, 3, 4])]
    #[case::one(1, &[2, 3, 4])]
    #[case::most(3, &[4])]
    #[case::all(4, &[])]
    #[case::more_than_all(9, &[])]
    fn drop_front_keeps_the_rest(#[case] n: usize, #[case] rest: &[u8]) {
        let mut buf = heapless::Vec::<u8, 8>::from_slice(&[1, 2, 3, 4]).unwrap();
        drop_front(&mut buf, n);
        assert_eq!(buf, rest);
    }
}
