//! Byte-at-a-time memory routines for the firmware, in place of `compiler_builtins`' word-wise
//! ones.
//!
//! The converter copies and clears little at a time (CAN frames, serial frames of at most 260
//! bytes; the 3 KiB converter once, at reset), so the builtins' aligned and misaligned word loops
//! buy no measurable time here and cost some 1.9 KiB of flash (`memcpy` alone 730 bytes). These
//! plain loops are a few dozen bytes each. Bare-metal target only: host builds keep their C
//! library's.
//!
//! The stores are volatile: LLVM would otherwise recognise each loop as the very `memcpy` or
//! `memset` idiom it implements (once inlined into the `__aeabi_*` entry points, whose names do
//! not stop it) and compile it into a call to itself.

use core::ffi::c_int;

/// `memcpy`: copies `n` bytes from `src` to `dest` (no overlap).
///
/// # Safety
/// The C contract: both ranges valid for `n` bytes, not overlapping.
#[no_mangle]
pub unsafe extern "C" fn memcpy(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller's contract.
    unsafe { copy(dest, src, n) };
    dest
}

/// `memmove`: copies `n` bytes from `src` to `dest`; the ranges may overlap.
///
/// # Safety
/// The C contract: both ranges valid for `n` bytes.
#[no_mangle]
pub unsafe extern "C" fn memmove(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller's contract.
    unsafe { copy(dest, src, n) };
    dest
}

/// `memset`: fills `n` bytes at `dest` with `c` (its low byte).
///
/// # Safety
/// The C contract: the range valid for `n` bytes.
#[no_mangle]
pub unsafe extern "C" fn memset(dest: *mut u8, c: c_int, n: usize) -> *mut u8 {
    // SAFETY: the caller's contract.
    unsafe { fill(dest, c as u8, n) };
    dest
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
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memcpy(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memcpy's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memcpy4`: both pointers word-aligned (unused here).
///
/// # Safety
/// As [`memcpy`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memcpy4(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memcpy's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memcpy8`: both pointers double-word-aligned (unused here).
///
/// # Safety
/// As [`memcpy`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memcpy8(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memcpy's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memmove`.
///
/// # Safety
/// As [`memmove`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memmove(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memmove's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memmove4`.
///
/// # Safety
/// As [`memmove`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memmove4(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memmove's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memmove8`.
///
/// # Safety
/// As [`memmove`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memmove8(dest: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is memmove's.
    unsafe { copy(dest, src, n) };
}

/// `__aeabi_memset` (note the ARM argument order: length before value).
///
/// # Safety
/// As [`memset`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memset(dest: *mut u8, n: usize, c: c_int) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, c as u8, n) };
}

/// `__aeabi_memset4`.
///
/// # Safety
/// As [`memset`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memset4(dest: *mut u8, n: usize, c: c_int) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, c as u8, n) };
}

/// `__aeabi_memset8`.
///
/// # Safety
/// As [`memset`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memset8(dest: *mut u8, n: usize, c: c_int) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, c as u8, n) };
}

/// `__aeabi_memclr`: `memset` with 0.
///
/// # Safety
/// As [`memset`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memclr(dest: *mut u8, n: usize) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, 0, n) };
}

/// `__aeabi_memclr4`.
///
/// # Safety
/// As [`memset`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memclr4(dest: *mut u8, n: usize) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, 0, n) };
}

/// `__aeabi_memclr8`.
///
/// # Safety
/// As [`memset`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memclr8(dest: *mut u8, n: usize) {
    // SAFETY: the caller's contract is memset's.
    unsafe { fill(dest, 0, n) };
}
