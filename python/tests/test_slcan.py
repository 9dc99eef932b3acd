"""dnet on the real SLCAN path: the soft slave (the reference converter, MAC 5, with the simulated
breaker on its serial line) at the far end of a socat pty pair, in real time."""

import threading
import time

import pytest

import dnet


def test_connect_get_poll_on_the_soft_slave(soft_slave):
    with dnet.Master(bus=soft_slave) as m:
        r = m.connect(5, epr=500)
        assert r["ok"], [f for f in r["frames"] if f["verdict"] == "fail"]
        dev = r["device"]
        assert int.from_bytes(m.get(5, 1, 1, 1), "little") == dev["vendor_id"] == 0x1234
        assert dev["produced_size"] == len(dev["last_input"]) == 18
        # Command 3 (set parameter 1 to 0x0BB8, sequence 1) goes to the breaker over the serial
        # line; its image shows it (bytes 12-13) once the breaker answered.
        image = b""
        for _ in range(30):
            image = m.poll(5, bytes([3, 1, 1, 0xB8, 0x0B, 0, 0, 0]))
            if image[12:14] == b"\xb8\x0b":
                break
        assert image[12:14] == b"\xb8\x0b", image.hex()
        with pytest.raises(dnet.DeviceError) as e:
            m.get(5, 1, 1, 99)
        assert e.value.general == 0x14
        assert m.close() == [5]


def test_waits_release_the_gil(soft_slave):
    # A get from an absent MAC waits on the bus (its timeouts, in real time) in Rust: another
    # Python thread runs meanwhile only if the call released the GIL.
    counter = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            counter[0] += 1

    with dnet.Master(bus=soft_slave, timeout=0.3) as m:
        t = threading.Thread(target=spin)
        t.start()
        try:
            time.sleep(0.05)
            before, started = counter[0], time.monotonic()
            with pytest.raises(dnet.Timeout) as e:
                m.get(9, 1, 1, 1)
            waited, during = time.monotonic() - started, counter[0] - before
        finally:
            stop.set()
            t.join()
    assert e.value.mac == 9
    # The wait is seconds long (network access alone is 2 s); a thread holding the GIL-less
    # loop counts millions in that time, a blocked one a few switch intervals' worth.
    assert waited > 1.0
    assert during > 100_000 * waited, (during, waited)
