"""A parameter sweep: set the breaker's parameter 0 to each value in turn through the poll
output, poll until the device's input image shows it, check it, and write one CSV row a value.

    python parameter_sweep.py                      # the simulated bus, sweep.csv
    python parameter_sweep.py --bus slcan:/dev/ttyACM0 --out bench.csv

Exit status 0 when every value was confirmed, 1 otherwise.
"""

import argparse
import csv
import sys

import dnet

# The breaker's poll output (guide: I/O data, "Commands through the poll output").
SET_PARAMETER = 3


def sweep(master: dnet.Master, mac: int, parameter: int, values, max_polls: int):
    """One row a value: the polls it took, the value read back, whether it matched."""
    report = master.connect(mac, epr=100)
    if not report["ok"]:
        raise SystemExit(f"bring-up of MAC {mac}: {report['failures']} frame check(s) failed")
    offset = 10 + 2 * parameter  # the parameters follow the 10 status bytes, 2 bytes each
    rows = []
    for sequence, value in enumerate(values, start=1):
        # A new sequence number makes the device execute the command once.
        output = bytes([SET_PARAMETER, sequence & 0xFF, parameter]) + value.to_bytes(2, "little") + bytes(3)
        for polls in range(1, max_polls + 1):
            image = master.poll(mac, output)
            read_back = int.from_bytes(image[offset : offset + 2], "little")
            if read_back == value:
                break
        rows.append({"value": value, "sequence": sequence, "polls": polls, "read_back": read_back,
                     "ok": read_back == value})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bus", default="sim", help="sim, socketcan:IFACE or slcan:PATH (default: sim)")
    ap.add_argument("--mac", type=int, default=5, help="the device's MAC ID (default: 5)")
    ap.add_argument("--parameter", type=int, default=0, choices=range(4), help="breaker parameter 0-3")
    ap.add_argument("--values", default="100,250,1000,4000,65535", help="comma-separated values")
    ap.add_argument("--max-polls", type=int, default=20, help="polls to wait for each value")
    ap.add_argument("--out", default="sweep.csv", help="the CSV file (default: sweep.csv)")
    args = ap.parse_args(argv)
    values = [int(v, 0) for v in args.values.split(",")]

    with dnet.Master(bus=args.bus) as master:
        rows = sweep(master, args.mac, args.parameter, values, args.max_polls)

    with open(args.out, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["value", "sequence", "polls", "read_back", "ok"])
        writer.writeheader()
        writer.writerows(rows)
    failed = [r["value"] for r in rows if not r["ok"]]
    print(f"{len(rows)} value(s) swept, {len(failed)} not confirmed{': ' + str(failed) if failed else ''}; "
          f"{args.out} written")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
