//! Byte-at-a-time memory routines for the firmware (`memcpy`, `memmove`, `memset`, `memcmp` and
//! their `__aeabi_*` entries), in place of `compiler_builtins`' word-wise ones.
//!
//! The converter copies and clears little at a time (CAN frames, serial frames of at most 260
//! bytes; the converter once, at reset), so the builtins' aligned and misaligned word loops buy no
//! measurable time here and cost some 1.9 KiB of flash (`memcpy` alone 730 bytes): the difference
//! between fitting the 32 KiB flash goal and not. These plain loops are a few dozen bytes each.
//!
//! The C symbols are exported on the bare-metal target only (host builds keep their C library's);
//! on the host the same functions are ordinary Rust functions, and the tests below check them
//! against slice copies for every offset and length of a small buffer, overlapping moves in both
//! directions included. The QEMU firmware tests run them as the firmware does.
//!
//! The stores are volatile: LLVM would otherwise recognise each loop as the very `memcpy` or
//! `memset` idiom it implements (once inlined into the `__aeabi_*` entry points, whose names do
//! not stop it) and compile it into a call to itself.

use core::ffi::c_int;

/// `memcpy`: copies `n` bytes from `src` to `dest` (no overlap).
///
/// # Safety
/// The C contract: both ranges valid for `n` bytes, not overlapping.
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn memcpy(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller's contract.
    unsafe { copy(dest, src, n) };
    dest
}

/// `memmove`: copies `n` bytes from `src` to `dest`; the ranges may overlap.
///
/// # Safety
/// The C contract: both ranges valid for `n` bytes.
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn memmove(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller's contract.
    unsafe { copy(dest, src, n) };
    dest
}

/// `memset`: fills `n` bytes at `dest` with `c` (its low byte).
///
/// # Safety
/// The C contract: the range valid for `n` bytes.
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn memset(dest: *mut u8, c: c_int, n: usize) -> *mut u8 {
    // SAFETY: the caller's contract.
    unsafe { fill(dest, c as u8, n) };
    dest
}

/// `memcmp`: compares `n` bytes; negative, zero or positive as the first differing byte of `a`
/// is below, equal to or above that of `b`.
///
/// # Safety
/// The C contract: both ranges valid for `n` bytes.
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn memcmp(a: *const u8, b: *const u8, n: usize) -> c_int {
    // SAFETY: the caller's contract.
    unsafe { compare(a, b, n) }
}

/// The first difference of two `n`-byte ranges, as `memcmp` reports it.
///
/// # Safety
/// Both ranges valid for `n` bytes.
// As `copy`: not inlined into a function LLVM takes for the builtin; the reads are volatile so
// the loop is not taken for a `memcmp`/`bcmp` idiom.
#[inline(never)]
unsafe fn compare(a: *const u8, b: *const u8, n: usize) -> c_int {
    let mut i = 0;
    while i < n {
        // SAFETY: i < n, both ranges valid for n bytes.
        let (x, y) = unsafe { (a.add(i).read_volatile(), b.add(i).read_volatile()) };
        if x != y {
            return c_int::from(x) - c_int::from(y);
        }
        i += 1;
    }
    0
}

/// Copies `n` bytes from `src` to `dest`, forward when `dest` is below `src` and backward
/// otherwise, so overlapping ranges are copied as `memmove` requires (and `memcpy` allows).
///
/// # Safety
/// Both ranges valid for `n` bytes.
// Not named like a C routine, and not inlined into one: LLVM takes a call to a function named
// `memcpy` for the builtin, and would lower it to `__aeabi_memcpy`, i.e. to itself.
#[inline(never)]
unsafe fn copy(dest: *mut u8, src: *const u8, n: usize) {
    if (dest as usize) <= (src as usize) {
        let mut i = 0;
        while i < n {
            // SAFETY: i < n; forward is safe when dest is below src.
            unsafe { dest.add(i).write_volatile(src.add(i).read()) };
            i += 1;
        }
    } else {
        let mut i = n;
        while i > 0 {
            i -= 1;
            // SAFETY: i < n; backward is safe when dest is above src.
            unsafe { dest.add(i).write_volatile(src.add(i).read()) };
        }
    }
}

/// Fills `n` bytes at `dest` with `byte`.
///
/// # Safety
/// The range valid for `n` bytes.
// As `copy`: not inlined into a function LLVM takes for the builtin.
#[inline(never)]
unsafe fn fill(dest: *mut u8, byte: u8, n: usize) {
    let mut i = 0;
    while i < n {
        // SAFETY: i < n, the range valid for n bytes.
        unsafe { dest.add(i).write_volatile(byte) };
        i += 1;
    }
}

/// `__aeabi_memcpy` (ARM run-time ABI): `memcpy` without the result.
///
/// # Safety
/// As [`memcpy`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memcpy(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memcpy's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memcpy4`: both pointers word-aligned (unused here).
///
/// # Safety
/// As [`memcpy`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memcpy4(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memcpy's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memcpy8`: both pointers double-word-aligned (unused here).
///
/// # Safety
/// As [`memcpy`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memcpy8(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memcpy's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memmove`.
///
/// # Safety
/// As [`memmove`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memmove(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memmove's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memmove4`.
///
/// # Safety
/// As [`memmove`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memmove4(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memmove's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memmove8`.
///
/// # Safety
/// As [`memmove`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memmove8(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memmove's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memset` (note the ARM argument order: length before value).
///
/// # Safety
/// As [`memset`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memset(dest: *mut u8, n: usize, c: c_int) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, c as u8, n) };
}

/// `__aeabi_memset4`.
///
/// # Safety
/// As [`memset`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memset4(dest: *mut u8, n: usize, c: c_int) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, c as u8, n) };
}

/// `__aeabi_memset8`.
///
/// # Safety
/// As [`memset`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memset8(dest: *mut u8, n: usize, c: c_int) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, c as u8, n) };
}

/// `__aeabi_memclr`: `memset` with 0.
///
/// # Safety
/// As [`memset`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memclr(dest: *mut u8, n: usize) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, 0, n) };
}

/// `__aeabi_memclr4`.
///
/// # Safety
/// As [`memset`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memclr4(dest: *mut u8, n: usize) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, 0, n) };
}

/// `__aeabi_memclr8`.
///
/// # Safety
/// As [`memset`].
#[cfg_attr(target_os = "none", no_mangle)]
pub unsafe extern "C" fn __aeabi_memclr8(dest: *mut u8, n: usize) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, 0, n) };
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: usize = 16;

    fn pattern() -> [u8; N] {
        core::array::from_fn(|i| (i as u8).wrapping_mul(37).wrapping_add(1))
    }

    #[test]
    fn copies_move_and_fills_agree_with_slices_at_every_offset_and_length() {
        for from in 0..N {
            for to in 0..N {
                for len in 0..=N - from.max(to) {
                    let mut expected = pattern();
                    expected.copy_within(from..from + len, to);
                    let entries: [unsafe extern "C" fn(*mut u8, *const u8, usize); 4] =
                        [__aeabi_memcpy, __aeabi_memmove, __aeabi_memmove4, __aeabi_memmove8];
                    for entry in entries {
                        let mut buf = pattern();
                        let p = buf.as_mut_ptr();
                        // SAFETY: both ranges lie within `buf`.
                        unsafe { entry(p.add(to), p.add(from), len) };
                        assert_eq!(buf, expected, "{from} -> {to}, {len} bytes");
                    }
                    let mut buf = pattern();
                    let p = buf.as_mut_ptr();
                    // SAFETY: both ranges lie within `buf`.
                    let r = unsafe { memmove(p.add(to), p.add(from), len) };
                    assert_eq!((buf, r), (expected, p.wrapping_add(to)), "memmove {from} -> {to}, {len}");
                }
            }
        }
        for at in 0..N {
            for len in 0..=N - at {
                let mut expected = pattern();
                expected[at..at + len].fill(0xA5);
                let mut buf = pattern();
                // SAFETY: the range lies within `buf`.
                unsafe { memset(buf.as_mut_ptr().add(at), 0x1A5, len) };
                assert_eq!(buf, expected, "memset at {at}, {len} bytes (the value's low byte)");
                let mut buf = pattern();
                // SAFETY: the range lies within `buf`.
                unsafe { __aeabi_memset(buf.as_mut_ptr().add(at), len, 0xA5) };
                assert_eq!(buf, expected, "__aeabi_memset at {at}, {len} bytes");
                expected[at..at + len].fill(0);
                let mut buf = pattern();
                // SAFETY: the range lies within `buf`.
                unsafe { __aeabi_memclr4(buf.as_mut_ptr().add(at), len) };
                assert_eq!(buf, expected, "__aeabi_memclr4 at {at}, {len} bytes");
            }
        }
    }

    #[test]
    fn memcmp_orders_by_the_first_difference() {
        let a = *b"abcdef";
        for (b, n, sign) in [(*b"abcdef", 6, 0), (*b"abcdeg", 6, -1), (*b"abcdeg", 5, 0), (*b"abXdef", 6, 1)]
        {
            // SAFETY: both ranges are 6 bytes long and n <= 6.
            let r = unsafe { memcmp(a.as_ptr(), b.as_ptr(), n) };
            assert_eq!(r.signum(), sign, "{b:?}, {n} bytes");
        }
        // SAFETY: zero bytes are read.
        assert_eq!(unsafe { memcmp(a.as_ptr(), [0u8; 0].as_ptr(), 0) }, 0);
    }
}
