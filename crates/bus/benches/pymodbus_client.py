"""A third-party Modbus TCP client for the gateway bench: pymodbus reads one holding register
range of one unit again and again for a number of seconds and prints one line per read,
`ok V1 V2 ...` or `error WHAT`, then `done N`.

Usage: python3 pymodbus_client.py HOST PORT UNIT ADDRESS COUNT SECONDS [EVERY]
(EVERY: seconds between the starts of two reads; 0 or none reads back to back)
"""

import sys
import time

from pymodbus.client import ModbusTcpClient


def main():
    host, port, unit, address, count, seconds = sys.argv[1:7]
    port, unit, address, count = int(port), int(unit), int(address), int(count)
    every = float(sys.argv[7]) if len(sys.argv) > 7 else 0.0
    client = ModbusTcpClient(host, port=port, timeout=2, retries=0)
    if not client.connect():
        print("error cannot connect", flush=True)
        return 1
    reads = 0
    until = time.monotonic() + float(seconds)
    out = []
    next_read = time.monotonic()
    while time.monotonic() < until:
        if every > 0:
            time.sleep(max(0.0, next_read - time.monotonic()))
            next_read += every
        try:
            reply = client.read_holding_registers(address, count=count, device_id=unit)
        except TypeError:  # pymodbus before 3.10 calls it `slave`
            reply = client.read_holding_registers(address, count=count, slave=unit)
        except Exception as error:  # a lost connection: say so and go on
            out.append(f"error {error!r}")
            continue
        reads += 1
        if reply.isError():
            out.append(f"error {reply}")
        else:
            out.append("ok " + " ".join(str(v) for v in reply.registers))
    client.close()
    print("\n".join(out))
    print(f"done {reads}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
