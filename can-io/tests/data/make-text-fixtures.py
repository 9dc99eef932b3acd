"""Makes the text trace fixtures of can-io/tests/trace_text.rs from bring-up.log.

Run from the repository root with a python that has python-can 4.6.x:

    python can-io/tests/data/make-text-fixtures.py

Written by python-can's own writers (the independent tool):
    text/bring-up.asc        can.ASCWriter
    text/bring-up-v10.trc    can.TRCWriter, file version 1.0 (python-can writes 1.0 and 2.1 only)
    text/bring-up-v21.trc    can.TRCWriter, file version 2.1
    text/bring-up.csv        can.CSVWriter

Written by hand-made formatting in this script (python-can has no writer for them), each laid out
as the examples of PEAK's "PEAK CAN TRC File Format" for that version, with the log's times as the
offsets, truncated to the version's resolution:
    text/bring-up-v11.trc, text/bring-up-v12.trc, text/bring-up-v13.trc, text/bring-up-v20.trc

Hand-written (constant text below): the foreign-line fixtures, each with lines that are not
DeviceNet traffic and a half-written last line (no newline), and a ZLG CANTest-style CSV.
"""

import os
import can
from can.io.trc import TRCFileVersion

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "text")


def messages():
    return list(can.CanutilsLogReader(os.path.join(HERE, "bring-up.log")))


def write_with(writer_class, name, version=None):
    path = os.path.join(OUT, name)
    writer = writer_class(path)
    if version is not None:
        writer.file_version = version
    for msg in messages():
        writer.on_message_received(msg)
    writer.stop()
    # python-can's trc 1.0 header names the file by its absolute path: keep only the file name.
    with open(path, encoding="utf-8", newline="") as f:
        text = f.read()
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.write(text.replace(path, name))


def micros(msg):
    return round(msg.timestamp * 1_000_000)


def hexdata(msg):
    return " ".join(f"{b:02X}" for b in msg.data)


def hand_made_trc():
    msgs = messages()
    layouts = {
        "bring-up-v11.trc": (
            ";$FILEVERSION=1.1\n;$STARTTIME=37704.5364870833\n;\n;   Start time: 24.03.2003 12:52:32.484\n"
            ";   Message Number\n;   |         Time Offset (ms)\n;   |         |        Type\n"
            ";   |         |        |        ID (hex)\n;   |         |        |        |     Data Length\n"
            ";   |         |        |        |     |   Data Bytes (hex) ...\n"
            ";---+--   ----+----  --+--  ----+---  +  -+ -- -- -- -- -- -- --\n",
            lambda n, m: f"{n:>6})  {micros(m) // 100 // 10:>7}.{micros(m) // 100 % 10}  Rx  {m.arbitration_id:>8X}  {m.dlc}  {hexdata(m)}",
        ),
        "bring-up-v12.trc": (
            ";$FILEVERSION=1.2\n;$STARTTIME=39878.6772258947;\n;   Start time: 06.03.2009 16:15:12.317.3\n"
            ";   +-Message Number\n;   |         +Time Offset (ms)\n;   |         |        +Bus\n"
            ";   |         |        |    +Type\n;   |         |        |    |        +ID (hex)\n",
            lambda n, m: f"{n:>6})  {micros(m) // 1000:>7}.{micros(m) % 1000:03}  1  Rx  {m.arbitration_id:>8X}  {m.dlc}  {hexdata(m)}",
        ),
        "bring-up-v13.trc": (
            ";$FILEVERSION=1.3\n;$STARTTIME=40023.5245451516\n",
            lambda n, m: f"{n:>6})  {micros(m) // 1000:>7}.{micros(m) % 1000:03} 1  Tx  {m.arbitration_id:04X} -  {m.dlc}    {hexdata(m)}",
        ),
        "bring-up-v20.trc": (
            ";$FILEVERSION=2.0\n;$STARTTIME=42209.4075997106\n;$COLUMNS=N,O,T,I,d,l,D\n",
            lambda n, m: f"{n:>7} {micros(m) // 1000:>9}.{micros(m) % 1000:03} DT {m.arbitration_id:>8X} Rx {m.dlc}  {hexdata(m)}",
        ),
    }
    for name, (header, line) in layouts.items():
        with open(os.path.join(OUT, name), "w", newline="\r\n") as f:
            f.write(header)
            for n, m in enumerate(msgs, 1):
                f.write(line(n, m).rstrip() + "\n")


FOREIGN = {
    # Lines follow PEAK's 1.1 example (Warng, Error, RTR) plus an extended ID and a half-written line.
    "foreign-v11.trc": (
        ";$FILEVERSION=1.1\n;$STARTTIME=37704.5364870833\n"
        "     1)      1059.9  Rx         0300  7  00 00 00 00 04 00 00\n"
        "     2)      1346.8  Warng  FFFFFFFF  4  00 00 00 04  BUSLIGHT\n"
        "     3)      1349.2  Error      0008  4  00 19 08 08\n"
        "     4)      1352.7  Rx         0100  3  RTR\n"
        "     5)      1353.0  Rx     18EFC034  1  00\n"
        "     6)      1354.1  Tx         042B  3  00 CB"
    ),
    # Lines follow PEAK's 2.1 example (FD, ER, EV, ST, EC, extended DT, RR) and a half-written line.
    "foreign-v21.trc": (
        ";$FILEVERSION=2.1\n;$STARTTIME=41766.4648963872\n;$COLUMNS=N,O,T,B,I,d,R,L,D\n"
        "      1      1059.900 DT 1      0300 Rx -  7    00 00 00 00 04 00 00\n"
        "      5      1334.416 FD 1      0500 Tx -  9    01 02 03 04 05 06 07 08 09 0A 0B 0C\n"
        "      6      1334.222 ER 1         - Rx -  5    04 00 02 00 00\n"
        "      7      1334.224 EV 1  User-defined event for bus 1\n"
        "      9      1334.231 ST 1         - Rx -  4    00 00 00 08\n"
        "     11      1334.643 EC 1         - Rx -  2    02 02\n"
        "     12      1335.156 DT 1  18EFC034 Tx -  8    01 02 03 04 05 06 07 08\n"
        "     13      1336.543 RR 1      0100 Rx -  3\n"
        "     14      1337.000 DT 1      042B Rx -  3    00 C"
    ),
    # Event lines as python-can's ASC test files and writer lay them out.
    "foreign.asc": (
        "date Mon Jan 05 14:20:33.123 2026\nbase hex  timestamps absolute\ninternal events logged\n"
        "// version 9.0.0\nBegin Triggerblock Mon Jan 05 14:20:33.123 2026\n   0.000000 Start of measurement\n"
        "   0.001000 1  42B             Rx   d 3 00 CB 00\n"
        "   0.002000 1  ErrorFrame\n"
        "   0.003000 1  18EFC034x       Rx   d 1 00\n"
        "   0.004000 1  100             Rx   r 3\n"
        "   0.005000 CANFD   1 Rx        500                                   1 0 9 12 01 02 03 04 05 06 07 08 09 0A 0B 0C        0    0     3000        0        0        0        0        0\n"
        "   0.006000 1  Statistic: D 1 R 0 XD 0 XR 0 E 0 O 0 B 0.10%\n"
        "   0.007000 1  42B             Rx   d 3 00 CB"
    ),
    "foreign.csv": (
        "timestamp,arbitration_id,extended,remote,error,dlc,data\n"
        "0.001,0x42b,0,0,0,3,AMsA\n"
        "0.002,0x20000080,0,0,1,8,AAAAAAAAAAA=\n"
        "0.003,0x18efc034,1,0,0,1,AA==\n"
        "0.004,0x100,0,1,0,3,\n"
        "0.005,0x42b,0,0,0,3,not base64\n"
        "0.006,0x42b,0,0,0,3,AMs"
    ),
    # ZLG CANTest-style export: the header and the row forms of a public tool that writes this
    # layout (序号,传输方向,时间标识,名称,帧ID(靠右对齐),帧格式,帧类型,数据长度,数据(HEX); time
    # HH:mm:ss:fff; ID 0x...; 数据帧/扩展帧), with ZLG's "x| " data prefix on one row.
    "zlg.csv": (
        "序号,传输方向,时间标识,名称,帧ID(靠右对齐),帧格式,帧类型,数据长度,数据(HEX)\n"
        "0,发送,15:07:39:123,,0x407,数据帧,标准帧,7,00 01 00 04 03 02 01\n"
        "1,接收,15:07:39:125,,0x42B,数据帧,标准帧,3,x| 00 CB 00\n"
        "2,发送,15:07:39:126,,0x18DB33F1,数据帧,扩展帧,8,02 06 01 00 00 00 00 00\n"
        "3,接收,15:07:39:127,,0x42B,远程帧,标准帧,0,\n"
    ),
}


def main():
    os.makedirs(OUT, exist_ok=True)
    write_with(can.ASCWriter, "bring-up.asc")
    write_with(can.TRCWriter, "bring-up-v10.trc", TRCFileVersion.V1_0)
    write_with(can.TRCWriter, "bring-up-v21.trc")
    write_with(can.CSVWriter, "bring-up.csv")
    hand_made_trc()
    for name, text in FOREIGN.items():
        with open(os.path.join(OUT, name), "w", encoding="utf-8", newline="\n") as f:
            f.write(text)


if __name__ == "__main__":
    main()
