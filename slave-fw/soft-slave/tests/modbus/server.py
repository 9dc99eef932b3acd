#!/usr/bin/env python3
"""A real Modbus RTU slave for the soft slave's tests: pymodbus serving one unit on a serial port
(one end of a socat pty pair).

Unit 1 (``--unit``) holds:

==================  =========  =======================================
table               addresses  values
==================  =========  =======================================
input registers     0..3       0x0102, 0x0304, 0x0506, 0x0708
holding registers   16..17     0, 0 (the gateway writes here)
holding registers   100..101   0xABCD, 0x1234
==================  =========  =======================================

Every other address is invalid: reading it is answered with exception 02 (illegal data address).
Requests to any other unit address go unanswered, as on a multi-drop line where no such slave is
connected, so the master sees a timeout.

Prints ``ready`` once the port is open, then one line per write, flushed at once::

    write unit=1 function=16 address=16 values=0x2211,0x4433

Needs pymodbus 3.16 and pyserial (installed by scripts/check into .venv).
"""

import argparse
import asyncio
import sys

from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer
from pymodbus.simulator import DataType, SimData, SimDevice

INPUT_REGISTERS = [0x0102, 0x0304, 0x0506, 0x0708]
HOLDING_16 = [0, 0]
HOLDING_100 = [0xABCD, 0x1234]


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--port", required=True, help="serial port or pty path")
    p.add_argument("--baud", type=int, default=19200, help="baud rate (default 19200)")
    p.add_argument("--parity", choices="NEO", default="N", help="parity (default N: ptys refuse parity)")
    p.add_argument("--unit", type=int, default=1, help="the unit address served (default 1)")
    return p.parse_args()


def device(unit):
    async def on_access(function_code, _start, address, _count, _registers, set_values):
        if set_values is not None:
            values = ",".join(f"0x{int(v):04X}" for v in set_values)
            print(f"write unit={unit} function={function_code} address={address} values={values}", flush=True)
        return None

    bits = [SimData(address=0, values=[False], datatype=DataType.BITS)]
    holding = [
        SimData(address=16, values=list(HOLDING_16), datatype=DataType.REGISTERS),
        SimData(address=100, values=list(HOLDING_100), datatype=DataType.REGISTERS),
    ]
    inputs = [SimData(address=0, values=list(INPUT_REGISTERS), datatype=DataType.REGISTERS)]
    return SimDevice(id=unit, simdata=(bits, list(bits), holding, inputs), action=on_access)


async def serve(args):
    def unknown_units_stay_silent(sending, pdu):
        # A request to a unit that is not on the line is dropped unanswered (no exception 0x0B).
        if not sending and pdu.dev_id != args.unit:
            return None
        return pdu

    server = ModbusSerialServer(
        device(args.unit),
        framer=FramerType.RTU,
        port=args.port,
        baudrate=args.baud,
        parity=args.parity,
        bytesize=8,
        stopbits=1,
        trace_pdu=unknown_units_stay_silent,
    )
    await server.serve_forever(background=True)
    print("ready", flush=True)
    await asyncio.Event().wait()


def main():
    args = parse_args()
    try:
        asyncio.run(serve(args))
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
