#!/usr/bin/env python3
"""The Modbus TCP server of `dnet-master ui --modbus-tcp` checked by an independent client.

pymodbus reads the status tables and every node's block, and each value is compared with what the
console's JSON API says (`GET /api/state`, `GET /api/node/MAC`), decoded here from the register map
of the guide (docs/src/plant/modbus-tcp.md), not from the server's code. Then writes must be
refused (exception 01), other unit IDs answered with exception 0x0A, bad reads with 02 / 03, and
hostile bytes over raw TCP (not Modbus, a wrong protocol identifier, a length past the data, an
overflowing quantity, more connections than allowed) must be answered or dropped while the server
keeps answering.

Exit 0 with a `compared:` line giving how many values were compared; 1 with the first difference.
Nothing compared is a failure.
"""

import argparse
import json
import socket
import struct
import sys
import time
import urllib.request

from pymodbus.client import ModbusTcpClient

# The register map (docs/src/plant/modbus-tcp.md).
SCAN_COUNTER = 0
ACTIVE, FAULTED, IDLE, VERIFY = 2, 6, 10, 14
SCANNER_STATUS, SCANNER_MAC, NODE_COUNT, CYCLE_TIME, BUS_LOAD = 18, 19, 20, 21, 22
NODE_STATUS_TABLE = 32
NODE_BLOCK_BASE, NODE_BLOCK_LEN = 256, 256
NODE_INPUT, NODE_OUTPUT, IMAGE_REGISTERS = 8, 136, 120
MAP_END = NODE_BLOCK_BASE + 64 * NODE_BLOCK_LEN

compared = 0


def fail(message):
    print(f"FAIL: {message}", flush=True)
    sys.exit(1)


def same(what, got, want):
    global compared
    if got != want:
        fail(f"{what}: Modbus {got!r}, console {want!r}")
    compared += 1


def api(console, path):
    with urllib.request.urlopen(console.rstrip("/") + path, timeout=10) as r:
        return json.load(r)


def registers(client, address, count, device_id=1, holding=False):
    read = client.read_holding_registers if holding else client.read_input_registers
    rr = read(address, count=count, device_id=device_id)
    if rr.isError():
        fail(f"read {count} at {address} (unit {device_id}): {rr}")
    return list(rr.registers)


def bitmap(regs):
    """Four registers, MAC m at bit m % 16 of register m // 16, as a set of MACs."""
    return {16 * i + b for i, r in enumerate(regs) for b in range(16) if r >> b & 1}


def image(regs, length):
    """Registers holding two bytes each, the first byte low."""
    out = bytearray()
    for r in regs:
        out += bytes([r & 0xFF, r >> 8])
    return bytes(out[:length])


def check_status(client, console):
    """The status tables against /api/state read before and after (a stable node set)."""
    for _attempt in range(50):
        before = api(console, "/api/state")
        table = registers(client, 0, 23)
        codes = registers(client, NODE_STATUS_TABLE, 64)
        after = api(console, "/api/state")
        key = lambda s: [(n["mac"], n["status"], n["code"]) for n in s["nodes"]] + [s["status"]]
        if key(before) == key(after):
            break
        time.sleep(0.1)
    else:
        fail("the node statuses never held still for one read")
    nodes = after["nodes"]
    if not nodes:
        fail("the console shows no node: nothing to compare")
    counter = table[0] | table[1] << 16
    lo, hi = before["cycles"] % 2**32, after["cycles"] % 2**32
    if not lo <= counter <= hi:
        fail(f"scan counter {counter} not within the console's {lo}..{hi}")
    compared_counter()
    macs = lambda pred: {n["mac"] for n in nodes if pred(n)}
    same("active node table", bitmap(table[ACTIVE:ACTIVE + 4]), macs(lambda n: True))
    same("faulted node table", bitmap(table[FAULTED:FAULTED + 4]), macs(lambda n: n["status"] not in ("ok", "idle")))
    same("idle node table", bitmap(table[IDLE:IDLE + 4]), macs(lambda n: n["status"] == "idle"))
    same("verify error table", bitmap(table[VERIFY:VERIFY + 4]),
         macs(lambda n: n["status"] in ("keying_mismatch", "size_mismatch")))
    status = after["status"]
    bits = {"starting": 1 << 8, "running": 1, "bus_warning": 1 | 1 << 9, "bus_off": 2 | 1 << 5,
            "duplicate_mac": 2 | 1 << 6, "stopped": 1 << 10}[status]
    if macs(lambda n: n["status"] not in ("ok", "idle")):
        bits |= 1 << 3
    if macs(lambda n: n["status"] in ("keying_mismatch", "size_mismatch")):
        bits |= 1 << 4
    same("scanner status bits", table[SCANNER_STATUS], bits)
    same("scanner MAC", table[SCANNER_MAC], after["mac"])
    same("node count", table[NODE_COUNT], len(nodes))
    tenths = sorted(round(s["cycle_ms"] * 10) for s in (before, after))
    if not tenths[0] - 1 <= table[CYCLE_TIME] <= tenths[1] + 1:
        fail(f"cycle time {table[CYCLE_TIME]} (0.1 ms) not within the console's {tenths}")
    load = sorted(round(s["bus_load"] * 1000) for s in (before, after))
    if not load[0] - 1 <= table[BUS_LOAD] <= load[1] + 1:
        fail(f"bus load {table[BUS_LOAD]} (0.1 %) not within the console's {load}")
    by_mac = {n["mac"]: n["code"] for n in nodes}
    own = {"duplicate_mac": 70, "bus_off": 91}.get(status, 0)
    for mac in range(64):
        want = by_mac.get(mac, own if mac == after["mac"] else 0)
        same(f"node status table MAC {mac}", codes[mac], want)
    return nodes


def compared_counter():
    global compared
    compared += 1


def check_node(client, console, mac):
    """A node's block against /api/node/MAC, read when both show the same exchange count."""
    base = NODE_BLOCK_BASE + mac * NODE_BLOCK_LEN
    for _attempt in range(200):
        # One read (one cycle's values): the head and 117 registers of the input image.
        head = registers(client, base, 125)
        tail = registers(client, base + 125, NODE_INPUT + IMAGE_REGISTERS - 125)
        out = registers(client, base + NODE_OUTPUT, IMAGE_REGISTERS, holding=True)
        node = api(console, f"/api/node/{mac}")["node"]
        exchanges = head[4] | head[5] << 16
        if exchanges == node["exchanges"] % 2**32:
            break
        time.sleep(0.01)
    else:
        fail(f"MAC {mac}: the Modbus block and /api/node never showed the same exchange count")
    same(f"MAC {mac} status", head[0], node["code"])
    flags = 1 << 2 | (1 << 3 if node["status"] == "ok" else 0)
    flags |= (1 if len(node["input"]) > 240 else 0) | (2 if len(node["output"]) > 240 else 0)
    same(f"MAC {mac} flags", head[1], flags)
    same(f"MAC {mac} input size", head[2], node["input_size"] or 0)
    same(f"MAC {mac} output size", head[3], node["output_size"] or 0)
    same(f"MAC {mac} exchanges", exchanges, node["exchanges"] % 2**32)
    if len(node["input"]) > 2 * (125 - NODE_INPUT):
        fail(f"MAC {mac}: an input image of {len(node['input'])} bytes is longer than this check reads at once")
    head += tail
    want_in = bytes(node["input"][:240])
    want_out = bytes(node["output"][:240])
    same(f"MAC {mac} input image", image(head[NODE_INPUT:], len(want_in)), want_in)
    same(f"MAC {mac} output image", image(out, len(want_out)), want_out)
    # Past the image: zeros.
    used = (len(want_in) + 1) // 2
    same(f"MAC {mac} after the input image", head[NODE_INPUT + used:], [0] * (IMAGE_REGISTERS - used))
    return node


def exception_of(rr):
    return getattr(rr, "exception_code", None) if rr.isError() else None


def check_refusals(client, host, port, mac):
    base = NODE_BLOCK_BASE + mac * NODE_BLOCK_LEN
    before = registers(client, base + NODE_OUTPUT, 4)
    same("write register refused", exception_of(client.write_register(base + NODE_OUTPUT, 1)), 1)
    same("write registers refused", exception_of(client.write_registers(base + NODE_OUTPUT, [1, 2])), 1)
    same("write coil refused", exception_of(client.write_coil(0, True)), 1)
    same("read coils refused", exception_of(client.read_coils(0, count=8)), 1)
    same("output image unchanged", registers(client, base + NODE_OUTPUT, 4), before)
    # pymodbus will not send a read of 126 registers: raw bytes.
    for fc in (3, 4):
        answer = raw(host, port, mbap(1, struct.pack(">BHH", fc, 0, 126)), wait=1.0)
        same(f"FC {fc} read of 126 registers refused", answer[7:9], bytes([fc | 0x80, 3]))
    same("past the map refused", exception_of(client.read_input_registers(MAP_END - 1, count=2)), 2)
    same("unit 7 refused", exception_of(client.read_input_registers(0, count=1, device_id=7)), 0x0A)
    for unit in (0, 255):
        same(f"unit {unit} answered", registers(client, SCANNER_MAC, 1, device_id=unit),
             registers(client, SCANNER_MAC, 1))


def raw(host, port, data, wait=2.0):
    """Sends `data` on a new connection; what came back before the server closed or `wait` passed."""
    s = socket.create_connection((host, port), timeout=5)
    s.settimeout(wait)
    got = b""
    try:
        s.sendall(data)
        while True:
            chunk = s.recv(4096)
            if not chunk:
                break
            got += chunk
    except (socket.timeout, ConnectionResetError):
        pass
    finally:
        s.close()
    return got


def mbap(unit, pdu, tid=1, protocol=0, length=None):
    return struct.pack(">HHHB", tid, protocol, len(pdu) + 1 if length is None else length, unit) + pdu


def check_hostile(client, host, port, connections):
    hostile = {
        "HTTP request": b"GET / HTTP/1.1\r\nHost: x\r\n\r\n",
        "protocol id 1": mbap(1, b"\x04\x00\x00\x00\x01", protocol=1),
        "length 0": mbap(1, b"\x04\x00\x00\x00\x01", length=0),
        "length past the data": mbap(1, b"\x04\x00\x00", length=0xFFFF),
        "truncated read": mbap(1, b"\x04\x00"),
        "quantity overflow (FC 16)": mbap(1, b"\x10\x00\x00\x80\x00\x00"),
        "coil bytes past the frame": mbap(1, b"\x0f\x00\x00\x00\x08\xc8\x01"),
        "function 0x80": mbap(1, b"\x80\x00"),
        "random bytes": bytes(range(256)) * 4,
    }
    for name, data in hostile.items():
        got = raw(host, port, data, wait=1.0)
        # Answered with a well-formed MBAP frame or dropped; either way the server goes on.
        if got and (len(got) < 9 or got[2:4] != b"\0\0"):
            fail(f"{name}: malformed answer {got.hex()}")
        same(f"still answering after {name}", len(registers(client, 0, 2)), 2)
    # A valid request split byte by byte is still one request.
    s = socket.create_connection((host, port), timeout=5)
    for b in mbap(1, b"\x04\x00\x13\x00\x01", tid=77):
        s.sendall(bytes([b]))
        time.sleep(0.005)
    answer = s.recv(64)
    s.close()
    same("a request sent byte by byte", answer[:2] + answer[7:9], b"\x00\x4d\x04\x02")
    time.sleep(0.5)  # the server sees the hostile connections' ends
    # More connections than allowed: the extra ones are closed, the client keeps its own.
    extra = []
    closed = 0
    for _ in range(connections + 4):
        s = socket.create_connection((host, port), timeout=5)
        s.settimeout(2.0)
        extra.append(s)
    for s in extra:
        try:
            s.sendall(mbap(1, b"\x04\x00\x00\x00\x01"))
            if not s.recv(64):
                closed += 1
        except (socket.timeout, ConnectionResetError, BrokenPipeError):
            closed += 1
    # The pymodbus client holds one place: of the others, `connections - 1` are served.
    same("connections closed over the limit", closed, len(extra) - (connections - 1))
    for s in extra:
        s.close()
    time.sleep(0.3)
    same("still answering after the connection flood", len(registers(client, 0, 2)), 2)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--modbus", required=True, help="HOST:PORT of the Modbus TCP server")
    p.add_argument("--console", required=True, help="the console's URL")
    p.add_argument("--connections", type=int, default=8, help="--modbus-tcp-connections given")
    p.add_argument("--min-nodes", type=int, default=1)
    a = p.parse_args()
    host, port = a.modbus.rsplit(":", 1)
    port = int(port)
    client = ModbusTcpClient(host, port=port, timeout=5, retries=0)
    if not client.connect():
        fail(f"cannot connect to {a.modbus}")
    nodes = check_status(client, a.console)
    if len(nodes) < a.min_nodes:
        fail(f"{len(nodes)} node(s) in the scan list, expected at least {a.min_nodes}")
    checked = 0
    for n in nodes:
        node = check_node(client, a.console, n["mac"])
        checked += 1
        if node["status"] == "ok" and not node["input"]:
            fail(f"MAC {n['mac']}: ok with an empty input image: nothing compared")
    check_refusals(client, host, port, nodes[0]["mac"])
    check_hostile(client, host, port, a.connections)
    client.close()
    if compared == 0 or checked == 0:
        fail("nothing compared")
    print(f"compared: {compared} values, {checked} node block(s), {len(nodes)} node(s)", flush=True)
    print("ok", flush=True)


if __name__ == "__main__":
    main()
