#!/usr/bin/env python3
"""An independent Modbus RTU slave (pymodbus) serving servosight's register map.

The map is not written down here: it is read from the JSON that `servosight register-map`
prints (the test writes it from the same Rust module), so the peer and servosight cannot
disagree silently. The sample block publishes one new sample per read (the sequence counter
increments on every read of the block), so a lost reply shows up as a gap on the client side.

Options:
  --port DEV         serial device (one end of a socat pty pair)
  --map FILE         register map JSON
  --slave N          slave id (default 1)
  --baud N           baud rate (ignored by a pty, set for completeness)
  --write-log FILE   append every write request (function, address, values) as a JSON line
  --no-echo          accept commits but never copy staged values to the applied echo
  --sequence-start N first sequence number (default 1)
  --cut-depth-raw N  publish this raw word in the depth-of-cut register instead of the
                     alternating cut (a garbled or out-of-range register, for the client's
                     range check)
"""

import argparse
import asyncio
import json
import math
import sys
import time

from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusSerialServer
from pymodbus.simulator import DataType, SimData, SimDevice


def crc16_modbus(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def to_raw(value, kind, scale):
    raw = int(round(value / scale))
    if kind in ("i16",):
        return [raw & 0xFFFF]
    if kind in ("u16",):
        return [raw & 0xFFFF]
    raw &= 0xFFFFFFFF
    return [(raw >> 16) & 0xFFFF, raw & 0xFFFF]


# The depth of cut the peer publishes while "cutting": sub-millimetre digits, so the client's
# decoding at 0.001 mm is checked, not just the integer part.
CUT_DEPTH_MM = 2.345


def physical_value(name, t):
    """Plausible, smoothly varying signals, so a decoded value can be checked for sanity."""
    if name == "cut_depth_mm":
        # Alternates every quarter second between a cut and no cut (0), like NC blocks do.
        return CUT_DEPTH_MM if int(t * 4.0) % 2 else 0.0
    if name.endswith("stator_temp_C"):
        return 30.0 + 5.0 * math.sin(t / 60.0)
    if name.endswith("speed_rpm"):
        return 1500.0 * math.sin(t)
    if name.endswith("torque_Nm"):
        return 2.5 * math.cos(t)
    if name.endswith("current_A"):
        return 3.0 + math.sin(t)
    if name.endswith("load_pct"):
        return 40.0 + 10.0 * math.sin(t)
    if name.endswith("_mm") or name.endswith("_deg"):
        return 100.0 * math.sin(t / 10.0)
    if name == "ambient_C":
        return 21.5
    if name == "coolant_on":
        return 1.0
    return 0.0


class Peer:
    def __init__(self, layout, sequence_start, echo, write_log, cut_depth_raw=None):
        self.map = layout
        self.cut_depth_raw = cut_depth_raw
        self.sequence = sequence_start - 1
        self.echo = echo
        self.write_log = write_log
        self.started = time.monotonic()
        hs = layout["handshake"]
        self.hs = hs
        self.table_len = hs["table_len"]
        self.holding_start = hs["status"]
        self.holding_len = hs["applied_values_start"] + self.table_len - self.holding_start

    def fill_sample(self, registers, start):
        """Latch a new sample into the input registers (registers[0] is address `start`)."""
        self.sequence = (self.sequence + 1) & 0xFFFFFFFF
        t = time.monotonic() - self.started
        values = {}
        for field in self.map["machine"]:
            name = field["name"]
            if name == "sequence":
                v = self.sequence
            elif name == "clock_ms":
                v = int(t * 1000) & 0xFFFFFFFF
            elif name == "map_version":
                v = self.map["version"]
            elif name == "cut_depth_mm" and self.cut_depth_raw is not None:
                values[field["address"]] = [self.cut_depth_raw & 0xFFFF]
                continue
            else:
                v = physical_value(name, t)
            values[field["address"]] = to_raw(v, field["type"], field["scale"])
        for axis in self.map["axes"]:
            for field in axis["fields"]:
                values[field["address"]] = to_raw(
                    physical_value(field["name"], t), field["type"], field["scale"]
                )
        for address, words in values.items():
            for i, word in enumerate(words):
                registers[address + i - start] = word

    def log_write(self, function, address, values):
        if self.write_log:
            with open(self.write_log, "a", encoding="utf-8") as log:
                log.write(json.dumps({"function": function, "address": address, "values": list(values)}) + "\n")

    async def action(self, function_code, start_address, address, count, registers, set_values):
        block = self.map["sample_block"]
        if function_code == 4:
            if address == block["start"]:
                self.fill_sample(registers, start_address)
            return None
        if set_values is None:
            return None
        # A write (function 6 or 16).
        self.log_write(function_code, address, set_values)
        staged = self.hs["staged_values_start"]
        end = address + len(set_values)
        in_staging = staged <= address and end <= staged + self.table_len
        is_commit = address == self.hs["staged_checksum"] and len(set_values) == 2
        if not (in_staging or is_commit):
            return ExcCodes.ILLEGAL_ADDRESS
        if is_commit:
            checksum, token = set_values
            off = lambda a: a - start_address
            staged_regs = registers[off(staged): off(staged) + self.table_len]
            data = b"".join(r.to_bytes(2, "big") for r in staged_regs)
            status_codes = dict(self.hs["status_codes"])
            if crc16_modbus(data) != checksum:
                registers[off(self.hs["status"])] = status_codes["rejected_checksum"]
            else:
                if self.echo:
                    applied = self.hs["applied_values_start"]
                    registers[off(applied): off(applied) + self.table_len] = staged_regs
                    gen_at = off(self.hs["applied_generation"])
                    generation = ((registers[gen_at] << 16) | registers[gen_at + 1]) + 1
                    registers[gen_at] = (generation >> 16) & 0xFFFF
                    registers[gen_at + 1] = generation & 0xFFFF
                # Without echo the peer claims success but leaves the applied table alone:
                # a controller that silently ignores the commit.
                registers[off(self.hs["status"])] = status_codes["applied"]
            registers[off(self.hs["last_commit_token"])] = token
        return None


async def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--port", required=True)
    parser.add_argument("--map", required=True)
    parser.add_argument("--slave", type=int, default=1)
    parser.add_argument("--baud", type=int, default=115200)
    parser.add_argument("--write-log")
    parser.add_argument("--no-echo", action="store_true")
    parser.add_argument("--sequence-start", type=int, default=1)
    parser.add_argument("--cut-depth-raw", type=int)
    args = parser.parse_args()
    with open(args.map, encoding="utf-8") as f:
        layout = json.load(f)
    peer = Peer(layout, args.sequence_start, not args.no_echo, args.write_log, args.cut_depth_raw)
    block = layout["sample_block"]
    device = SimDevice(
        id=args.slave,
        simdata=(
            [SimData(0, count=16, values=False, datatype=DataType.BITS)],
            [SimData(0, count=16, values=False, datatype=DataType.BITS)],
            [SimData(peer.holding_start, count=peer.holding_len, values=0, datatype=DataType.REGISTERS)],
            [SimData(block["start"], count=block["len"], values=0, datatype=DataType.REGISTERS)],
        ),
        action=peer.action,
    )
    server = ModbusSerialServer(
        device, framer=FramerType.RTU, port=args.port, baudrate=args.baud
    )
    print(f"peer serving {args.port} slave {args.slave}", flush=True)
    await server.serve_forever()


if __name__ == "__main__":
    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        sys.exit(0)
