#!/usr/bin/env python3
"""A load figure for `dnet-master ui --opcua` (not a test: it prints figures, it asserts nothing
but that it saw the nodes asked for).

Browses every variable under Objects/DeviceNet anonymously, subscribes to all of them (publishing
interval 100 ms), counts the data-change notifications for --seconds, and prints: the nodes and
variables, the browse time, notifications per second in all and per node, and the server's
resident memory when --pid is given (VmRSS of /proc/PID/status, at the start and at the end).

    dnet-master --bus sim --slave-mac 1,2,...,63 ui --no-history --opcua 127.0.0.1:4840 &
    .venv/bin/python tests/python/opcua_load.py --url opc.tcp://127.0.0.1:4840/ --nodes 63 --pid $!
"""

import argparse
import asyncio
import sys
import time

from asyncua import Client, ua

NAMESPACE = "urn:dnet-master:devicenet"


def rss_kib(pid):
    if pid is None:
        return None
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return None


class Counter:
    def __init__(self):
        self.count = 0

    def datachange_notification(self, node, val, data):
        self.count += 1


async def variables(node):
    out = []
    for c in await node.get_children():
        cls = await c.read_node_class()
        if cls == ua.NodeClass.Variable:
            out.append(c)
        elif cls == ua.NodeClass.Object:
            out.extend(await variables(c))
    return out


async def main(args):
    rss_start = rss_kib(args.pid)
    async with Client(args.url, timeout=30) as c:
        ns = await c.get_namespace_index(NAMESPACE)
        dn = await c.nodes.objects.get_child([f"{ns}:DeviceNet"])
        t0 = time.monotonic()
        objects = [o for o in await dn.get_children() if (await o.read_browse_name()).Name.startswith("MAC")]
        if len(objects) < args.nodes:
            print(f"FAIL: {len(objects)} node objects, expected {args.nodes}", file=sys.stderr)
            sys.exit(1)
        vars_ = []
        for o in objects:
            vars_.extend(await variables(o))
        browse_s = time.monotonic() - t0
        counter = Counter()
        sub = await c.create_subscription(100, counter)
        for i in range(0, len(vars_), 500):
            await sub.subscribe_data_change(vars_[i:i + 500], queuesize=1)
        await asyncio.sleep(2)  # the initial values
        counter.count = 0
        await asyncio.sleep(args.seconds)
        per_s = counter.count / args.seconds
        await sub.delete()
    rss_end = rss_kib(args.pid)
    print(f"nodes: {len(objects)}, variables: {len(vars_)}, browse: {browse_s:.2f} s")
    print(f"notifications: {per_s:.0f}/s in all, {per_s / len(objects):.1f}/s per node")
    if rss_start is not None:
        print(f"server VmRSS: {rss_start} KiB at the start, {rss_end} KiB at the end")


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--url", required=True)
    p.add_argument("--nodes", type=int, default=1)
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--pid", type=int)
    asyncio.run(main(p.parse_args()))
