"""An independent Sparkplug B host application for the system tests (pysparkplug, PyPI).

Usage: sparkplug_host.py HOST PORT GROUP [--ca FILE]

Subscribes to spBv1.0/GROUP/# and prints one JSON line per message received, decoded by
pysparkplug (its own protobuf code, generated from Eclipse Tahu's sparkplug_b.proto):

    {"topic": "...", "type": "DBIRTH", "device": "mac05", "seq": 1, "bd_seq": null,
     "metrics": [{"name": "...", "datatype": "DOUBLE", "value": 1.0, "historical": false,
                  "null": false, "timestamp": 1714564800123}]}

and for each NBIRTH/DBIRTH a second line {"topic": ..., "units": {"Inputs/phase_a": "A"}}: the
metrics' `engUnit` properties, which pysparkplug's Metric leaves out, read from the raw payload with
pysparkplug's generated protobuf module. Prints {"ready": true} once connected.

Reads commands from stdin, one JSON object a line:
    {"rebirth": "EDGE"}                                  -> NCMD Node Control/Rebirth = true
    {"dcmd": ["EDGE", "mac05"], "name": "Commands/Close", "type": "BOOLEAN", "value": true}
    {"dcmd": [...], "name": "Outputs/Image", "type": "BYTES", "hex": "0001..."}
    {"dcmd": [...], "metrics": [{"name": ..., "type": ..., "value": ...}, ...]}  -> one DCMD, several
"""

import json
import sys
import threading

import pysparkplug as psp
from pysparkplug._protobuf import sparkplug_b_pb2


def main() -> None:
    host, port, group = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    tls = None
    if "--ca" in sys.argv:
        tls = psp.TLSConfig(ca_certs=sys.argv[sys.argv.index("--ca") + 1])
    lock = threading.Lock()

    def emit(obj: dict) -> None:
        with lock:
            sys.stdout.write(json.dumps(obj) + "\n")
            sys.stdout.flush()

    def on_message(_client: psp.Client, message: psp.Message) -> None:
        payload = message.payload
        topic = message.topic
        out = {
            "topic": str(topic),
            "type": str(topic.message_type),
            "device": topic.device_id,
            "seq": getattr(payload, "seq", None),
            "bd_seq": None,
            "metrics": [],
        }
        metrics = list(getattr(payload, "metrics", ()))
        if isinstance(payload, psp.NDeath):
            metrics = [payload.bd_seq_metric]
        for m in metrics:
            value = m.value
            if isinstance(value, (bytes, bytearray)):
                value = value.hex().upper()
            if m.name == "bdSeq":
                out["bd_seq"] = value
            out["metrics"].append(
                {
                    "name": m.name,
                    "datatype": m.datatype.name,
                    "value": value,
                    "historical": m.is_historical,
                    "null": m.is_null,
                    "timestamp": m.timestamp,
                }
            )
        emit(out)

    def on_raw(_client, _userdata, mqtt_message) -> None:
        # Units are properties, which pysparkplug's Metric leaves out: read them from the raw
        # payload of births.
        parts = mqtt_message.topic.split("/")
        if len(parts) < 4 or parts[2] not in ("NBIRTH", "DBIRTH"):
            return
        raw = sparkplug_b_pb2.Payload()
        try:
            raw.ParseFromString(mqtt_message.payload)
        except Exception as e:  # noqa: BLE001 - reported, not hidden
            emit({"topic": mqtt_message.topic, "error": f"undecodable: {e}"})
            return
        units = {}
        for m in raw.metrics:
            props = m.properties
            for k, v in zip(props.keys, props.values):
                if k == "engUnit":
                    units[m.name] = v.string_value
        emit({"topic": mqtt_message.topic, "units": units})

    client = psp.Client(client_id=f"spb-host-{port}", transport_config=tls)

    def connected(c: psp.Client) -> None:
        emit({"ready": True})

    client.subscribe(psp.Topic.from_str(f"spBv1.0/{group}/#"), psp.QoS.AT_LEAST_ONCE, on_message)
    # A second, raw view of the same messages for the births' properties.
    raw_topic = f"spBv1.0/{group}/+/#"
    client._client.message_callback_add(raw_topic, on_raw)
    client.connect(host, port=port, blocking=False, callback=connected)

    for line in sys.stdin:
        line = line.strip()
        if not line:
            continue
        cmd = json.loads(line)
        ts = psp.get_current_timestamp()
        if "rebirth" in cmd:
            topic = psp.Topic(group_id=group, message_type=psp.MessageType.NCMD, edge_node_id=cmd["rebirth"])
            metric = psp.Metric(timestamp=ts, name="Node Control/Rebirth", datatype=psp.DataType.BOOLEAN, value=True)
            payload = psp.NCmd(timestamp=ts, metrics=(metric,))
        else:
            edge, device = cmd["dcmd"]
            topic = psp.Topic(group_id=group, message_type=psp.MessageType.DCMD, edge_node_id=edge, device_id=device)
            metrics = tuple(
                psp.Metric(
                    timestamp=ts,
                    name=m["name"],
                    datatype=psp.DataType[m["type"]],
                    value=bytes.fromhex(m["hex"]) if "hex" in m else m["value"],
                )
                for m in cmd.get("metrics", [cmd])
            )
            payload = psp.DCmd(timestamp=ts, metrics=metrics)
        client.publish(psp.Message(topic=topic, payload=payload, qos=psp.QoS.AT_MOST_ONCE, retain=False), include_dtypes=True)
        emit({"sent": line})
    client.disconnect()


if __name__ == "__main__":
    main()
