#!/usr/bin/env python3
"""An independent OPC UA client (PyPI asyncua) against `dnet-master ui --opcua`.

Two checks, one per mode; each prints `compared: N ...` and exits 1 on the first difference:

read  (ui without --users): browses Objects/DeviceNet anonymously on the endpoint without
      security, and compares every node's identity, status, images and decoded inputs with the
      console's own JSON (`GET /api/node/MAC`), read just before and after (a value that changes in
      between is compared with either). Checks the EngineeringUnits of the currents, that the
      endpoint offers no UserName token, and that an anonymous Close is refused.
call  (ui --users FILE --opcua-pki DIR): the methods. Anonymous and viewer calls are refused
      (BadUserAccessDenied), a wrong password is refused at session activation; the operator,
      over Basic256Sha256 Sign & Encrypt, subscribes to the breaker's switch_state, calls Close
      and sees it change to `closed` as the breaker reports it, then Open and `open`; SetOutput
      of the image as it is is carried out, of 3 bytes refused by the scanner (BadInvalidState).
"""

import argparse
import asyncio
import json
import sys
import tempfile
import urllib.request
from pathlib import Path

from asyncua import Client, ua
from asyncua.crypto.cert_gen import setup_self_signed_certificate
from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256
from cryptography.x509.oid import ExtendedKeyUsageOID

NAMESPACE = "urn:dnet-master:devicenet"
AMPERE_UNIT_ID = (ord("A") << 16) | (ord("M") << 8) | ord("P")


def fail(msg):
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def console_node(console, mac):
    with urllib.request.urlopen(f"{console}api/node/{mac}", timeout=10) as r:
        return json.load(r)


def console_state(console):
    with urllib.request.urlopen(f"{console}api/state", timeout=10) as r:
        return json.load(r)


async def child(node, ns, name):
    return await node.get_child([f"{ns}:{name}"])


async def read_node(obj, ns):
    """Every variable under a node's object: {"Identity/VendorId": value, ...}."""
    out = {}
    for c in await obj.get_children():
        name = (await c.read_browse_name()).Name
        cls = await c.read_node_class()
        if cls == ua.NodeClass.Variable:
            out[name] = await c.read_value()
        elif cls == ua.NodeClass.Object:
            for v in await c.get_children():
                if await v.read_node_class() == ua.NodeClass.Variable:
                    out[f"{name}/{(await v.read_browse_name()).Name}"] = await v.read_value()
    return out


def expected_pairs(j):
    """(path, value) the console's JSON gives for one node."""
    n = j["node"]
    ident = n["identity"]
    pairs = [
        ("Identity/VendorId", ident["vendor_id"]),
        ("Identity/DeviceType", ident["device_type"]),
        ("Identity/ProductCode", ident["product_code"]),
        ("Identity/Revision", ident["revision"]),
        ("Identity/SerialNumber", ident["serial_number"]),
        ("Identity/ProductName", ident["product_name"]),
        ("Status/Status", n["status"]),
        ("Status/Code", n["code"]),
        ("Connection", n["connection"]),
        ("InputImage", bytes(n["input"])),
        ("OutputImage", bytes(n["output"])),
    ]
    for f in j.get("fields", []):
        if f["name"].startswith("param_"):
            pairs.append((f"Parameters/{f['name']}", f["values"][0]))
        elif len(f["values"]) == 1:
            pairs.append((f"Inputs/{f['name']}", float(f["values"][0])))
        else:
            for i, v in enumerate(f["values"]):
                pairs.append((f"Inputs/{f['name']}[{i}]", float(v)))
    return pairs


def same(got, want):
    if isinstance(want, bytes) and got is None:
        return want == b""
    return got == want


async def read_mode(args):
    compared = 0
    client = Client(args.url)
    await client.connect()
    try:
        endpoints = await client.get_endpoints()
        for e in endpoints:
            if e.SecurityPolicyUri.endswith("#None"):
                kinds = {p.TokenType for p in e.UserIdentityTokens}
                if kinds != {ua.UserTokenType.Anonymous}:
                    fail(f"the endpoint without security offers {kinds}: only anonymous expected")
                compared += 1
        ns = await client.get_namespace_index(NAMESPACE)
        dn = await client.nodes.objects.get_child([f"{ns}:DeviceNet"])
        macs = [n["mac"] for n in console_state(args.console)["nodes"]]
        if len(macs) < args.min_nodes:
            fail(f"the console shows {len(macs)} node(s), expected at least {args.min_nodes}")
        for mac in macs:
            before = console_node(args.console, mac)
            obj = await child(dn, ns, f"MAC{mac:02d}")
            got = await read_node(obj, ns)
            after = console_node(args.console, mac)
            wants = dict(expected_pairs(before))
            for path, want2 in expected_pairs(after):
                want1 = wants.get(path, want2)
                if path not in got:
                    fail(f"MAC {mac}: no variable {path} (have {sorted(got)})")
                if not (same(got[path], want1) or same(got[path], want2)):
                    fail(f"MAC {mac} {path}: OPC UA {got[path]!r}, console {want1!r} / {want2!r}")
                compared += 1
            if before["profile"] == "breaker":
                phase = await obj.get_child([f"{ns}:Inputs", f"{ns}:phase_a"])
                eu = await (await phase.get_child(["0:EngineeringUnits"])).read_value()
                if (eu.UnitId, eu.DisplayName.Text) != (AMPERE_UNIT_ID, "A"):
                    fail(f"MAC {mac} phase_a EngineeringUnits {eu}")
                compared += 1
                try:
                    await obj.call_method(f"{ns}:Close")
                    fail(f"MAC {mac}: an anonymous Close was accepted")
                except ua.uaerrors.BadUserAccessDenied:
                    compared += 1
    finally:
        await client.disconnect()
    print(f"compared: {compared} values and refusals over {len(macs)} node(s)")


async def secure_client(url, user, password, workdir):
    key, cert = workdir / "client-key.pem", workdir / "client-cert.der"
    await setup_self_signed_certificate(
        key, cert, "urn:dnet-tests:opcua-client", "localhost",
        [ExtendedKeyUsageOID.CLIENT_AUTH], {"commonName": "dnet tests"},
    )
    client = Client(url)
    client.application_uri = "urn:dnet-tests:opcua-client"
    await client.set_security(
        SecurityPolicyBasic256Sha256, certificate=str(cert), private_key=str(key),
        mode=ua.MessageSecurityMode.SignAndEncrypt,
    )
    if user is not None:
        client.set_user(user)
        client.set_password(password)
    return client


class Changes:
    def __init__(self):
        self.values = []
        self.event = asyncio.Event()

    def datachange_notification(self, node, val, data):
        self.values.append(val)
        self.event.set()

    async def wait_for(self, value, timeout):
        end = asyncio.get_running_loop().time() + timeout
        while value not in self.values:
            left = end - asyncio.get_running_loop().time()
            if left <= 0:
                fail(f"switch_state never became {value!r}: notifications {self.values}")
            self.event.clear()
            try:
                await asyncio.wait_for(self.event.wait(), left)
            except asyncio.TimeoutError:
                pass


async def refused_call(client, mac, method, who):
    ns = await client.get_namespace_index(NAMESPACE)
    obj = await client.nodes.objects.get_child([f"{ns}:DeviceNet", f"{ns}:MAC{mac:02d}"])
    try:
        await obj.call_method(f"{ns}:{method}")
    except ua.uaerrors.BadUserAccessDenied:
        return 1
    fail(f"{who}: {method} on MAC {mac} was accepted")


async def call_mode(args):
    with tempfile.TemporaryDirectory(prefix="opcua-client-") as work:
        await calls(args, Path(work))


async def calls(args, work):
    compared = 0
    # Anonymous, on the endpoint without security and on the encrypted one.
    c = Client(args.url)
    await c.connect()
    compared += await refused_call(c, args.mac, "Close", "anonymous")
    await c.disconnect()
    c = await secure_client(args.url, None, None, work)
    await c.connect()
    compared += await refused_call(c, args.mac, "Open", "anonymous (encrypted)")
    await c.disconnect()
    # A viewer may read, not operate.
    c = await secure_client(args.url, args.viewer, args.viewer_password, work)
    await c.connect()
    compared += await refused_call(c, args.mac, "Close", "viewer")
    await c.disconnect()
    # A wrong password: no session.
    c = await secure_client(args.url, args.user, args.password + "x", work)
    try:
        await c.connect()
        fail("a wrong password opened a session")
    except ua.uaerrors.BadIdentityTokenRejected:
        compared += 1
    except ua.UaError as e:
        fail(f"a wrong password: {e!r} (expected BadIdentityTokenRejected)")
    # The operator closes and opens the breaker; the breaker's report comes back by subscription.
    c = await secure_client(args.url, args.user, args.password, work)
    await c.connect()
    try:
        ns = await c.get_namespace_index(NAMESPACE)
        obj = await c.nodes.objects.get_child([f"{ns}:DeviceNet", f"{ns}:MAC{args.mac:02d}"])
        state = await obj.get_child([f"{ns}:Inputs", f"{ns}:switch_state"])
        changes = Changes()
        sub = await c.create_subscription(100, changes)
        await sub.subscribe_data_change(state)
        start = await state.read_value()
        first, second = ("Open", "open") if start == "closed" else ("Close", "closed")
        then, then_state = ("Close", "closed") if first == "Open" else ("Open", "open")
        await obj.call_method(f"{ns}:{first}")
        await changes.wait_for(second, args.timeout)
        compared += 1
        await obj.call_method(f"{ns}:{then}")
        await changes.wait_for(then_state, args.timeout)
        compared += 1
        print(f"switch_state notifications: {changes.values}")
        # SetOutput: the image as it is (the sequence number unchanged: nothing executes again),
        # then an image of the wrong size, which the scanner refuses.
        image = await (await obj.get_child([f"{ns}:OutputImage"])).read_value()
        await obj.call_method(f"{ns}:SetOutput", ua.Variant(image, ua.VariantType.ByteString))
        compared += 1
        try:
            await obj.call_method(f"{ns}:SetOutput", ua.Variant(b"\x01\x02\x03", ua.VariantType.ByteString))
            fail("SetOutput of 3 bytes was accepted")
        except ua.uaerrors.BadInvalidState:
            compared += 1
        await sub.delete()
    finally:
        await c.disconnect()
    print(f"compared: {compared} calls and refusals")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mode", choices=["read", "call"])
    p.add_argument("--url", required=True)
    p.add_argument("--console", help="the console's URL (read mode)")
    p.add_argument("--min-nodes", type=int, default=1)
    p.add_argument("--mac", type=int, default=5)
    p.add_argument("--user")
    p.add_argument("--password")
    p.add_argument("--viewer")
    p.add_argument("--viewer-password")
    p.add_argument("--timeout", type=float, default=20.0)
    args = p.parse_args()
    asyncio.run(read_mode(args) if args.mode == "read" else call_mode(args))


if __name__ == "__main__":
    main()
