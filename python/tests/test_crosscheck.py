"""dnet against devicenet-py (PyPI), the independent master, on the same soft slave.

devicenet-py talks to a python-can bus; python-can's ``slcan`` interface opens the same SLCAN pty
the soft slave answers on. devicenet-py reads Connection object instance 2 (the poll connection)
only, so the check compares what both masters read there after each allocated explicit and poll
through the Group 2 Only port.

devicenet-py 0.0.1 sends its Allocate with the identifier of an explicit request on an established
connection (Group 2 message 4), which a device without that connection ignores; the Allocate of a
Group 2 only server goes through the unconnected port, Group 2 message 6 (protocol §3.4). The test
gives its master_slave_connect that identifier and leaves the rest (the request's bytes, the wait,
the response's decoding) to devicenet-py.
"""

import can
import pytest
from devicenet.cid import DeviceNetCID
from devicenet.devicenet import DeviceNet
from devicenet.enums import DeviceNetConnectionObjectAttributes as Attr
from devicenet.fields import DeviceNetAllocationChoiceByte

import dnet

COMPARED = [Attr.INSTANCE_TYPE, Attr.CP23_PRODUCED_CONNECTION_ID, Attr.CP23_CONSUMED_CONNECTION_ID,
            Attr.PRODUCED_CONNECTION_SIZE, Attr.CONSUMED_CONNECTION_SIZE]


def test_dnet_and_devicenet_py_read_the_same_poll_connection(soft_slave, monkeypatch):
    path = soft_slave.removeprefix("slcan:")
    bus = can.Bus(interface="slcan", channel=path, bitrate=250_000)
    try:
        other = DeviceNet(bus, mac_id=0, vendor_id=1, serial_number=0x01020304)
        other.connect()
        with monkeypatch.context() as patch:
            patch.setattr(
                DeviceNetCID,
                "master_explicit_request",
                classmethod(lambda cls, dest_mac: cls.group_2_unconnected_explicit_request(dest_mac=dest_mac)),
            )
            other.master_slave_connect(5, DeviceNetAllocationChoiceByte(explicit_message=True, polled=True))
        theirs = {a.name: other.get_attribute_single(5, a) for a in COMPARED}
    finally:
        bus.shutdown()
    # The soft slave's set is still allocated to MAC 0: dnet (also MAC 0) releases and
    # allocates it again, as a master restarted after a crash does.
    with dnet.Master(bus=soft_slave) as m:
        r = m.connect(5, epr=500)
        assert r["ok"], [f for f in r["frames"] if f["verdict"] == "fail"]
        # devicenet-py's AttributeEnum members are all int 0 (its __new__ calls int.__new__(cls)),
        # so they compare equal: keyed by name, the attribute ID taken from .value.
        ours = {a.name: int.from_bytes(m.get(5, 5, 2, a.value), "little") for a in COMPARED}
    assert len(theirs) == len(COMPARED)
    assert ours == theirs
    # The poll connection's identifiers (protocol §1): the response Group 1 message 15 from MAC 5,
    # the command Group 2 message 5 to MAC 5.
    assert theirs["CP23_PRODUCED_CONNECTION_ID"] == (0xF << 6) | 5 == 0x3C5
    assert theirs["CP23_CONSUMED_CONNECTION_ID"] == 0x400 | (5 << 3) | 5 == 0x42D
    assert theirs["PRODUCED_CONNECTION_SIZE"] == r["device"]["produced_size"] == 18
    assert theirs["CONSUMED_CONNECTION_SIZE"] == r["device"]["consumed_size"] == 8
