"""dnet on the simulated bus: the reference device (or a description's) at virtual time."""

from pathlib import Path

import pytest

import dnet

from conftest import REPO

# The reference converter's identity, as its description gives it
# (slave-fw/soft-slave/tests/descriptions/breaker-with-status.toml has the same identity).
VENDOR, DEVICE_TYPE, PRODUCT_NAME = 0x1234, 0x000C, b"Serial-DeviceNet Bridge"


def u16(b: bytes) -> int:
    assert len(b) == 2, b
    return int.from_bytes(b, "little")


def test_connect_reports_every_frame_checked():
    with dnet.Master() as m:
        r = m.connect(5)
        assert r["ok"] and r["failures"] == 0
        frames = r["frames"]
        # The start-up sequence of the guide's protocol reference has 28 frames.
        assert len(frames) == 28
        assert frames[0]["frame"] == "407#00010004030201" and frames[0]["direction"] == "M->"
        assert {f["verdict"] for f in frames} <= {"sent", "ok"}
        assert all(f["notes"] for f in frames if f["direction"] == "S->")
        dev = r["device"]
        # The report agrees with what the device answers to plain gets.
        assert (dev["vendor_id"], dev["device_type"]) == (VENDOR, DEVICE_TYPE)
        assert u16(m.get(5, 1, 1, 1)) == dev["vendor_id"]
        assert u16(m.get(5, 5, 2, 7)) == dev["produced_size"] == len(dev["last_input"])
        assert m.get(5, 1, 1, 7)[1:] == PRODUCT_NAME
        assert m.close() == [5]


def test_parameter_set_and_get_back():
    with dnet.Master() as m:
        before = m.get(5, 0x0F, 4, 1)
        wanted = (int.from_bytes(before, "little") + 250).to_bytes(4, "little")
        assert m.set(5, 0x0F, 4, 1, wanted) == b""
        assert m.get(5, 0x0F, 4, 1) == wanted
        # Out of range: the device's error, by code and by name.
        with pytest.raises(dnet.DeviceError) as e:
            m.set(5, 0x0F, 4, 1, bytearray(4))
        assert e.value.general == 0x09 and e.value.general_name == "invalid attribute value"
        assert e.value.mac == 5


def test_error_response_names_codes():
    with dnet.Master() as m:
        with pytest.raises(dnet.DeviceError) as e:
            m.get(5, 1, 1, 99)
        err = e.value
        assert (err.general, err.additional) == (0x14, 0xFF)
        assert err.general_name == "attribute not supported"
        assert err.additional_name == "no additional code"
        assert "attr 99" in err.request and isinstance(err, dnet.Error)


def test_absent_device_times_out():
    with dnet.Master() as m:
        with pytest.raises(dnet.Timeout) as e:
            m.get(9, 1, 1, 1)
        assert e.value.mac == 9 and e.value.timeout


@pytest.mark.parametrize(
    "call, exc, arg",
    [
        (lambda m: m.get(64, 1, 1, 1), ValueError, "mac"),
        (lambda m: m.get(5, 0x10000, 1, 1), ValueError, "cls"),
        (lambda m: m.get(5, 1, 1, 256), ValueError, "attr"),
        (lambda m: m.set(5, 1, 1, 1, "text"), TypeError, "value"),
        (lambda m: m.poll(5), ValueError, r"connect\(5\)"),
        (lambda m: m.get(0, 1, 1, 1), ValueError, "MAC 0"),
        (lambda m: m.scan(10, 64), ValueError, "last"),
        (lambda m: m.scan(10, 5), ValueError, "first, last"),
        (lambda m: m.monitor(5, count=-1), ValueError, "count"),
        (lambda m: m.connect(5, io="fast"), ValueError, "io"),
    ],
)
def test_bad_arguments_name_the_argument(call, exc, arg):
    with dnet.Master() as m:
        with pytest.raises(exc, match=arg):
            call(m)


@pytest.mark.parametrize(
    "kwargs, arg",
    [({"bus": "can0"}, "bus"), ({"bitrate": "300k"}, "bitrate"), ({"master_mac": -1}, "master_mac"),
     ({"slave_config": "/nonexistent.toml"}, "slave_config"), ({"timeout": 0}, "timeout")],
)
def test_bad_master_arguments(kwargs, arg):
    with pytest.raises(ValueError, match=arg):
        dnet.Master(**kwargs)


def test_poll_output_and_parameter_command():
    with dnet.Master() as m:
        m.connect(5)
        with pytest.raises(ValueError, match="output: 1 bytes"):
            m.poll(5, b"\x01")
        # Command 3 (set parameter 0 to 0x1234, sequence 1): the breaker's image shows it
        # (bytes 10-11) once the instrument answered.
        image = b""
        for _ in range(20):
            image = m.poll(5, bytes([3, 1, 0, 0x34, 0x12, 0, 0, 0]))
            if image[10:12] == b"\x34\x12":
                break
        assert image[10:12] == b"\x34\x12", image.hex()


@pytest.mark.parametrize("io, kind, size", [("strobe", "strobe", 8), ("cos", "change_of_state", 18),
                                            ("cyclic", "cyclic", 18)])
def test_other_io_connections(io, kind, size):
    with dnet.Master() as m:
        r = m.connect(5, io=io)
        assert r["ok"] and r["device"]["io"]["kind"] == kind
        # A bit-strobe response carries the first 8 input bytes; a production the whole image.
        assert len(m.poll(5)) == size
        samples = list(m.monitor(5, count=2))
        assert len(samples) == 2 and samples[1]["time_us"] > samples[0]["time_us"]
        # Decoded by the profile, but a strobe response (8 bytes) is shown raw.
        assert bool(samples[0]["fields"]) == (io != "strobe") and samples[0].get("note") is None


def test_scan_finds_every_simulated_device():
    with dnet.Master(slave_macs=[5, 7]) as m:
        found = m.scan()
        assert [d["mac"] for d in found] == [5, 7]
        for d in found:
            assert d["status"] == "ok"
            assert d["product_name"].encode() == m.get(d["mac"], 1, 1, 7)[1:]


def test_scan_forgets_the_connections_it_released():
    with dnet.Master() as m:
        m.connect(5)
        m.scan(5, 5)
        with pytest.raises(ValueError, match="connect"):
            m.poll(5)


def test_monitor_count_and_duration_at_the_epr():
    with dnet.Master() as m:
        samples = list(m.monitor(5, count=3, epr=50))
        assert len(samples) == 3
        times = [s["time_us"] for s in samples]
        assert [b - a for a, b in zip(times, times[1:])] == [50_000, 50_000]
        assert [f["name"] for f in samples[0]["fields"]][-1] == "switch"
        assert samples[0]["raw"][9] in (0x0F, 0xF0)
    with dnet.Master() as m:
        # 0.45 s from the first sample at one every 100 ms: samples at 0, 100, ..., 400 ms.
        assert len(list(m.monitor(5, duration=0.45))) == 5


def test_slave_config_describes_the_simulated_device(tmp_path: Path):
    text = (REPO / "slave-fw/soft-slave/tests/descriptions/breaker-with-status.toml").read_text()
    text = text.replace("mac_id = 5", "mac_id = 12").replace("Serial-DeviceNet Bridge", "Python Test Bridge")
    desc = tmp_path / "device.toml"
    desc.write_text(text)
    with dnet.Master(slave_config=desc) as m:
        r = m.connect(12)
        assert r["ok"] and r["device"]["produced_size"] == 20
        assert m.get(12, 1, 1, 7)[1:] == b"Python Test Bridge"
        sample = next(m.monitor(12))
        # Assembly 101: the status byte and the freshness counter are decoded.
        assert sample["link"] is not None and sample["link"]["status"] == sample["raw"][18]


def test_closed_master_refuses_calls():
    m = dnet.Master()
    m.connect(5)
    assert m.close() == [5]
    assert m.close() == []
    with pytest.raises(dnet.Error, match="closed"):
        m.get(5, 1, 1, 1)


def test_decode_reads_the_masters_own_log(tmp_path: Path):
    log = tmp_path / "connect.log"
    with dnet.Master(log=log) as m:
        report = m.connect(5)
    text = log.read_text()
    messages = list(dnet.decode(text))
    # The log holds the bring-up and the release on close; the decoder's meaning of each
    # bring-up frame is the one the session recorded.
    assert len(messages) > len(report["frames"])
    for frame, msg in zip(report["frames"], messages):
        assert msg["frame"] == frame["frame"]
        whole = f' => {msg["message"]}' if msg["message"] else ""
        assert msg["meaning"] + whole == frame["meaning"]
    assert messages[0]["kind"] == "dup-mac" and messages[0]["mac"] == 0 and messages[0]["group"] == 2
    assert isinstance(messages[0]["data"], bytes)
    assert [m["frame"] for m in dnet.decode(text.encode())] == [m["frame"] for m in messages]
    it = dnet.decode(text)
    assert it.format == "candump" and it.skipped == 0


def test_decode_reassembles_and_refuses_garbage(tmp_path: Path):
    log = tmp_path / "get.log"
    with dnet.Master(log=log) as m:
        m.get(5, 1, 1, 7)
    messages = list(dnet.decode(log.read_text()))
    # The product name comes in fragments: the last one completes the message.
    whole = [msg["message"] for msg in messages if msg["message"]]
    assert len(whole) == 1 and "Serial-DeviceNet Bridge" in whole[0], whole
    with pytest.raises(ValueError, match="source"):
        list(dnet.decode("(0.000100) can0 42B#80\nthis is no frame\n", strict=True))
    with pytest.raises(ValueError, match="format"):
        dnet.decode("", format="xyz")
    with pytest.raises(TypeError, match="source"):
        dnet.decode(42)
