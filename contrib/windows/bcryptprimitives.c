/*
 * A stand-in bcryptprimitives.dll for running the Windows build of dnet-master under Debian's
 * wine 8 in CI (scripts/windows-wine). Test equipment only: never shipped, never installed on a
 * Windows machine, which has the real DLL since Windows 10.
 *
 * Rust's standard library (1.78 and later) gets its random bytes (the seeds of HashMap's hasher)
 * from ProcessPrng in bcryptprimitives.dll. Wine 8 has no such DLL, so a Rust program fails to
 * start there. This one exports ProcessPrng and fills the buffer from RtlGenRandom
 * (SystemFunction036 in advapi32.dll), which wine implements with the host's random source.
 *
 * Build: x86_64-w64-mingw32-gcc -shared -O2 -o bcryptprimitives.dll bcryptprimitives.c -ladvapi32
 */
#include <windows.h>

/* RtlGenRandom: declared by hand, as Microsoft documents it (ntsecapi.h needs more of the SDK). */
BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

/* ProcessPrng: fills `data` with `length` random bytes; TRUE on success (as Windows' own always
 * returns). RtlGenRandom takes a 32-bit length, so a larger request is filled in pieces. */
__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length)
{
    while (length > 0) {
        ULONG piece = length > 0x40000000 ? 0x40000000 : (ULONG)length;
        if (!SystemFunction036(data, piece)) {
            return FALSE;
        }
        data += piece;
        length -= piece;
    }
    return TRUE;
}
