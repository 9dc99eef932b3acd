#!/usr/bin/env python3
"""Writes the binary trace fixtures of can-io/tests/trace_binary.rs with tools independent of
can-io's readers: python-can's BLFWriter, Wireshark's editcap, and pcap/pcapng records packed
here with the struct module (the layouts follow the pcap and pcapng drafts and tcpdump.org's
LINKTYPE_CAN_SOCKETCAN page, not can-io's code).

Regenerate (Debian packages: python3, tshark for editcap; python-can 4.6 in a venv):

    cd can-io/tests/data
    # the log and the pcap of one simulated run (dnet-master writes both)
    (cd ../../.. && cargo run -q -p master-harness -- --bus sim \
        --log can-io/tests/data/bring-up.log \
        --pcap can-io/tests/data/binary/bring-up.pcap connect --mac 5)
    /work/main/.venv/bin/python make-binary-fixtures.py   # any python with python-can 4.6

Inputs: bring-up.log (candump -L, read with python-can's CanutilsLogReader) and
binary/bring-up.pcap (dnet-master --pcap: classic pcap, microseconds, little-endian, link type 227).

Outputs in binary/:
  bring-up.blf       BLFWriter, zlib, containers of 256 bytes so objects span containers
  foreign.blf        BLFWriter, uncompressed: bring-up's first 4 frames, then an error frame,
                     an extended, a remote and an FD frame, a global marker (not a frame), and
                     a DeviceNet frame marked transmitted (is_rx=False)
  bring-up.pcapng    editcap -F pcapng bring-up.pcap
  bring-up-ns.pcap   editcap -F nsecpcap bring-up.pcap (nanosecond magic A1B23C4D)
  bring-up-be.pcap   bring-up.pcap rewritten big-endian (magic A1B2C3D4 read as D4C3B2A1 is not
                     it: header and record headers in big-endian order; no common tool writes one)
  foreign.pcap       struct: 2 DeviceNet frames around an error, an extended, a remote, a 72-byte
                     CAN FD, a DLC 9 and a truncated record, and a half-written last record
  foreign.pcapng     struct: interface 0 "can0" (link type 227, if_tsresol 9 = ns), interface 1
                     (link type 1, no name); EPBs inbound, outbound, without flags, on the
                     Ethernet interface, and a CAN FD frame with CANFD_FDF
"""

import os
import struct
import subprocess
import sys

import can

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "binary")
LOG = os.path.join(HERE, "bring-up.log")
PCAP = os.path.join(OUT, "bring-up.pcap")


def messages():
    return list(can.CanutilsLogReader(LOG))


def write_blf():
    msgs = messages()
    # The first frame comes 436 µs into the run, so python-can's measurement start (the first
    # timestamp truncated to ms) is 0 and the objects' times are the log's times.
    with can.BLFWriter(os.path.join(OUT, "bring-up.blf"), max_container_size=256) as w:
        for m in msgs:
            w.on_message_received(m)

    with can.BLFWriter(os.path.join(OUT, "foreign.blf"), compression_level=0) as w:
        for m in msgs[:4]:
            w.on_message_received(m)
        t = msgs[3].timestamp
        w.on_message_received(can.Message(timestamp=t + 0.001, is_error_frame=True, arbitration_id=0x4, dlc=8, data=bytes(8)))
        w.on_message_received(can.Message(timestamp=t + 0.002, is_extended_id=True, arbitration_id=0x42B, data=b"\x01"))
        w.on_message_received(can.Message(timestamp=t + 0.003, is_extended_id=False, is_remote_frame=True, arbitration_id=0x42B, dlc=0))
        w.on_message_received(can.Message(timestamp=t + 0.004, is_extended_id=False, is_fd=True, arbitration_id=0x42B, data=bytes(range(12))))
        w.log_event("bench note", timestamp=t + 0.005)
        w.on_message_received(can.Message(timestamp=t + 0.006, is_extended_id=False, is_rx=False, arbitration_id=0x42C, data=b"\x00\x4b\x03\x01\x02\x00"))


def editcap(*args):
    subprocess.run(["editcap", *args], check=True)


def socketcan(id_flags, data, length=None, fd_flags=0, size=16):
    length = len(data) if length is None else length
    body = struct.pack(">IBBBB", id_flags, length, fd_flags, 0, 0) + data
    return body.ljust(size, b"\0")


def pcap_record(us, packet, caplen=None, order="<"):
    caplen = len(packet) if caplen is None else caplen
    return struct.pack(order + "IIII", us // 1_000_000, us % 1_000_000, caplen, len(packet)) + packet[:caplen]


def write_pcaps():
    editcap("-F", "pcapng", PCAP, os.path.join(OUT, "bring-up.pcapng"))
    editcap("-F", "nsecpcap", PCAP, os.path.join(OUT, "bring-up-ns.pcap"))

    # Big-endian: the same records with every header field swapped (the packet bytes are kept).
    data = open(PCAP, "rb").read()
    magic, vmaj, vmin, zone, sigfigs, snaplen, link = struct.unpack_from("<IHHiIII", data, 0)
    out = [struct.pack(">IHHiIII", magic, vmaj, vmin, zone, sigfigs, snaplen, link)]
    pos = 24
    while pos < len(data):
        sec, usec, incl, orig = struct.unpack_from("<IIII", data, pos)
        out.append(struct.pack(">IIII", sec, usec, incl, orig) + data[pos + 16 : pos + 16 + incl])
        pos += 16 + incl
    open(os.path.join(OUT, "bring-up-be.pcap"), "wb").write(b"".join(out))

    # Foreign records (the numbers are the records' 1-based positions).
    header = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 262144, 227)
    records = [
        pcap_record(1_000_000, socketcan(0x407, bytes([0, 1, 0, 4, 3, 2, 1]))),  # 1 DeviceNet
        pcap_record(1_000_100, socketcan(0x2000_0004, bytes(8))),  # 2 error frame
        pcap_record(1_000_200, socketcan(0x8000_042B, b"\x01")),  # 3 extended
        pcap_record(1_000_300, socketcan(0x4000_042B, b"", length=0)),  # 4 remote
        pcap_record(1_000_400, socketcan(0x42B, bytes(range(12)), fd_flags=0x04, size=72)),  # 5 CAN FD
        pcap_record(1_000_500, socketcan(0x42B, bytes(8), length=9)),  # 6 DLC 9
        pcap_record(1_000_600, socketcan(0x42B, b"\x00\xcb\x00"), caplen=6),  # 7 truncated
        pcap_record(2_500_000, socketcan(0x7FF, b"")),  # 8 DeviceNet
        pcap_record(2_600_000, socketcan(0x42B, b"\x00\xcc"))[:20],  # 9 half-written
    ]
    open(os.path.join(OUT, "foreign.pcap"), "wb").write(header + b"".join(records))


def option(code, value):
    pad = (4 - len(value) % 4) % 4
    return struct.pack("<HH", code, len(value)) + value + b"\0" * pad


def block(kind, body):
    length = 12 + len(body)
    return struct.pack("<II", kind, length) + body + struct.pack("<I", length)


def epb(interface, ts, packet, flags=None):
    pad = (4 - len(packet) % 4) % 4
    body = struct.pack("<IIIII", interface, ts >> 32, ts & 0xFFFFFFFF, len(packet), len(packet)) + packet + b"\0" * pad
    if flags is not None:
        body += option(2, struct.pack("<I", flags)) + option(0, b"")
    return block(6, body)


def write_pcapng():
    shb = block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))
    idb0 = block(1, struct.pack("<HHI", 227, 0, 0) + option(2, b"can0") + option(9, b"\x09") + option(0, b""))
    idb1 = block(1, struct.pack("<HHI", 1, 0, 0))
    ns = 1_000_000_000
    blocks = [
        shb,
        idb0,
        idb1,
        epb(0, 5 * ns + 1_500, socketcan(0x407, bytes([0, 1, 0, 4, 3, 2, 1])), flags=0b01),  # 1 Rx, 5.000002 s
        epb(0, 5 * ns + 2_400, socketcan(0x42B, b"\x00\xcb\x00"), flags=0b10),  # 2 Tx, 5.000002 s
        epb(1, 5 * ns + 3_000, bytes(60)),  # 3 Ethernet interface
        epb(0, 5 * ns + 4_000, socketcan(0x42B, bytes(range(16)), fd_flags=0x04, size=72)),  # 4 CAN FD
        epb(0, 6 * ns, socketcan(0x3C5, b"\x82\x00")),  # 5 no flags
    ]
    open(os.path.join(OUT, "foreign.pcapng"), "wb").write(b"".join(blocks))


def main():
    if not os.path.exists(PCAP):
        sys.exit(f"{PCAP} is missing: write it with dnet-master --pcap (see this script's docstring)")
    write_blf()
    write_pcaps()
    write_pcapng()


if __name__ == "__main__":
    main()
