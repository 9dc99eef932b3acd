#!/usr/bin/env python3
"""A standard SLCAN client against the emulated firmware: python-can's `slcan` interface.

Proves the firmware's SLCAN side is the Lawicel protocol python-can speaks, not only something our
own harness tolerates. Over the adapter it does what a minimal DeviceNet master does with a
group-2-only device (protocol §2 of the guide): waits for the device's duplicate MAC ID checks,
allocates the explicit connection of the Predefined Master/Slave Connection Set through the Group 2
Only Unconnected Explicit Request port, and reads the Identity vendor ID.

    slcan_identity.py /dev/pts/N [--mac 5] [--vendor 0x1234]

Exit status 0 when the device answered as expected, 1 otherwise (the frames seen are printed).
"""

import argparse
import sys
import time

import can
import serial

MASTER_MAC = 0


def group2(mac: int, message: int) -> int:
    """Group 2 identifier (notes section 1.1): 0x400 | mac << 3 | message."""
    return 0x400 | (mac << 3) | message


def wake(path: str, timeout: float) -> serial.Serial:
    """QEMU notices a new client on its pty with some delay: repeat 'close channel' until the
    adapter answers. The handle stays open (without reading) so QEMU keeps the client."""
    holder = serial.Serial(path, 115200, timeout=0.3)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        holder.write(b"C\r")
        if holder.read(1) in (b"\r", b"\x07"):
            holder.reset_input_buffer()
            return holder
    sys.exit(f"no answer from the SLCAN adapter on {path} within {timeout} s")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pty")
    parser.add_argument("--mac", type=int, default=5)
    parser.add_argument("--vendor", type=lambda s: int(s, 0), default=0x1234)
    args = parser.parse_args()

    holder = wake(args.pty, 30.0)
    time.sleep(0.5)  # answers to repeated commands still on their way are dropped by python-can
    seen = []

    # The standard client: python-can sets the bit rate (S5 = 250 kbit/s) and opens the channel.
    with can.Bus(interface="slcan", channel=args.pty, bitrate=250000, sleep_after_open=0) as bus:

        def receive(want_id: int, timeout: float):
            end = time.monotonic() + timeout
            while time.monotonic() < end:
                msg = bus.recv(timeout=max(0.0, end - time.monotonic()))
                if msg is None:
                    break
                seen.append(f"{msg.arbitration_id:03X}#{msg.data.hex().upper()}")
                if msg.arbitration_id == want_id:
                    return bytes(msg.data)
            return None

        def send(can_id: int, data: bytes):
            bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
            seen.append(f"{can_id:03X}#{data.hex().upper()} (sent)")

        def fail(what: str) -> int:
            print(f"FAIL: {what}\nframes:\n  " + "\n  ".join(seen))
            return 1

        # The device's duplicate MAC ID checks (held by the closed adapter until it opened).
        dup = group2(args.mac, 7)
        checks = [receive(dup, 5.0), receive(dup, 5.0)]
        if None in checks:
            return fail("the device's two duplicate MAC ID checks did not come")
        vendor_in_check = int.from_bytes(checks[0][1:3], "little")

        # Allocate explicit (choice 0x01) through the Group 2 Only port; the device answers once
        # on-line, 1 s after its second check.
        response = group2(args.mac, 3)
        answer = None
        for _ in range(20):
            send(group2(args.mac, 6), bytes([MASTER_MAC, 0x4B, 0x03, 0x01, 0x01, MASTER_MAC]))
            answer = receive(response, 0.3)
            if answer is not None:
                break
        if answer != bytes([MASTER_MAC, 0xCB, 0x00]):
            return fail(f"allocate answered {answer!r}, expected 00 CB 00")

        # Get_Attribute_Single Identity (class 1) instance 1 attribute 1 over the explicit connection.
        send(group2(args.mac, 4), bytes([MASTER_MAC, 0x0E, 0x01, 0x01, 0x01]))
        answer = receive(response, 2.0)
        if answer is None or len(answer) != 4 or answer[:2] != bytes([MASTER_MAC, 0x8E]):
            return fail(f"Get vendor ID answered {answer!r}")
        vendor = int.from_bytes(answer[2:4], "little")
        if vendor != args.vendor or vendor != vendor_in_check:
            return fail(f"vendor ID 0x{vendor:04X}; expected 0x{args.vendor:04X} (dup MAC check: 0x{vendor_in_check:04X})")
        print(f"python-can {can.__version__} slcan: MAC {args.mac} allocated, Identity vendor ID 0x{vendor:04X}")
        print("frames:\n  " + "\n  ".join(seen))
    holder.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
