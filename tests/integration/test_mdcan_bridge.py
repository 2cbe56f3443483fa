#!/usr/bin/env python3
"""Integration test of `mdcan bridge` (docs/pil.md) on the UDP bus, in a
private network namespace (scripts/netns-run.sh): two serial lines as Unix
sockets served here, as QEMU serves the Cortex-M7 image's UARTs.

1. Frames from the serial side (md_link packets on line 0, with bytes that
   need SLIP escapes) reach the bus exactly (`mdcan dump`).
2. Frames sent on the bus come out on the serial side striped over both
   lines (byte k on line k mod 2) and decode to the same frames.
3. A packet with a wrong CRC is dropped, counted, and fails the bridge's
   exit status.

    test_mdcan_bridge.py PATH/TO/mdcan
"""
import os
import socket
import subprocess
import sys
import tempfile
import time

END, ESC, ESC_END, ESC_ESC = 0xC0, 0xDB, 0xDC, 0xDD
FD, BRS, EXT = 0x01, 0x04, 0x02


def crc16(data):
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def encode(fid, flags, data, corrupt=False):
    pkt = bytes([flags, len(data)]) + fid.to_bytes(4, "little") + bytes(data)
    crc = crc16(pkt) ^ (1 if corrupt else 0)
    pkt += crc.to_bytes(2, "little")
    out = bytearray([END])
    for b in pkt:
        out += bytes([ESC, ESC_END]) if b == END else bytes([ESC, ESC_ESC]) if b == ESC else bytes([b])
    out.append(END)
    return bytes(out)


def decode_stream(stream):
    frames, cur, esc = [], bytearray(), False
    for b in stream:
        if b == END:
            if cur:
                assert crc16(cur[:-2]) == int.from_bytes(cur[-2:], "little"), "bad CRC from the bridge"
                n = cur[1]
                frames.append((int.from_bytes(cur[2:6], "little"), cur[0], bytes(cur[6:6 + n])))
            cur, esc = bytearray(), False
        elif esc:
            cur.append(END if b == ESC_END else ESC)
            esc = False
        elif b == ESC:
            esc = True
        else:
            cur.append(b)
    return frames


def fail(msg, *logs):
    print(f"FAIL: {msg}", file=sys.stderr)
    for path in logs:
        if path and os.path.exists(path):
            print(f"--- {path}\n{open(path).read()}", file=sys.stderr)
    sys.exit(1)


def wait_for(path, text, proc, what):
    for _ in range(500):
        if os.path.exists(path) and text in open(path).read():
            return
        if proc.poll() is not None:
            fail(f"{what} exited early ({proc.returncode})", path)
        time.sleep(0.02)
    fail(f"{what} did not start", path)


def start_bridge(mdcan, tmp, tag, lines):
    servers, paths = [], []
    for j in range(lines):
        p = os.path.join(tmp, f"{tag}{j}.sock")
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.bind(p)
        s.listen(1)
        servers.append(s)
        paths.append(p)
    log = os.path.join(tmp, f"bridge-{tag}.log")
    args = [mdcan, "bridge"]
    for p in paths:
        args += ["--serial", p]
    proc = subprocess.Popen(args + ["--bus", "udp"], stdout=open(log, "w"), stderr=subprocess.STDOUT)
    conns = []
    for s in servers:
        s.settimeout(10)
        c, _ = s.accept()
        c.settimeout(0.2)
        conns.append(c)
    wait_for(log, "bus udp", proc, "bridge")
    return proc, conns, log


def stop(proc, log):
    proc.terminate()
    try:
        return proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        fail("bridge did not stop on SIGTERM", log)


def main(mdcan):
    tmp = tempfile.mkdtemp(prefix="md-bridge-")
    # 1 + 2: two lines, frames both ways
    proc, conns, log = start_bridge(mdcan, tmp, "a", 2)
    dump_log, dump_err = os.path.join(tmp, "dump.out"), os.path.join(tmp, "dump.err")
    dump = subprocess.Popen([mdcan, "dump", "--bus", "udp", "--count", "2", "--timeout-ms", "5000"],
                            stdout=open(dump_log, "w"), stderr=open(dump_err, "w"))
    wait_for(dump_err, "listening on", dump, "dump")
    fd_data = bytes([0xC0, 0xDB, 0x00, 0xFF] * 16)
    conns[0].sendall(encode(0x123, 0, b"\xDE\xAD\xBE\xEF") + encode(0x321, FD | BRS, fd_data))
    if dump.wait(timeout=10) != 0:
        fail("dump did not see both frames", dump_log, dump_err, log)
    got = [line.split()[2] for line in open(dump_log)]
    want = ["123#DEADBEEF", "321##5" + fd_data.hex().upper()]  # md_bus_text: flags nibble FD|BRS
    if got != want:
        fail(f"bus frames {got} != {want}", log)

    sent = subprocess.run([mdcan, "send", "--bus", "udp", "7FF#00C0DB", "1ABCDEF0#0102",
                           "456##0" + ("C0" * 64)], capture_output=True, text=True)
    if sent.returncode != 0:
        fail(f"mdcan send: {sent.stderr}", log)
    streams = [bytearray(), bytearray()]
    deadline = time.time() + 10
    while time.time() < deadline and len(decode_stream(interleave(streams))) < 3:
        for j, c in enumerate(conns):
            try:
                streams[j] += c.recv(65536)
            except socket.timeout:
                pass
    frames = decode_stream(interleave(streams))
    want_frames = [(0x7FF, 0, bytes([0x00, 0xC0, 0xDB])), (0x1ABCDEF0, EXT, bytes([1, 2])), (0x456, FD, bytes([0xC0] * 64))]
    if frames != want_frames:
        fail(f"serial frames {frames} != {want_frames}", log)
    if abs(len(streams[0]) - len(streams[1])) > 1:
        fail(f"not striped: {len(streams[0])} and {len(streams[1])} bytes", log)
    rc = stop(proc, log)
    if rc != 0:
        fail(f"bridge exit {rc} after a clean run", log)
    if "serial->bus 2 frames" not in open(log).read() or "bus->serial 3 frames" not in open(log).read():
        fail("bridge counters", log)

    # 3: a corrupt packet is dropped, counted, and fails the exit status
    proc, conns, log = start_bridge(mdcan, tmp, "b", 1)
    conns[0].sendall(encode(0x100, 0, b"\x01", corrupt=True) + encode(0x101, 0, b"\x02"))
    time.sleep(0.5)
    rc = stop(proc, log)
    text = open(log).read()
    if rc != 1 or "crc 1" not in text or "serial->bus 1 frames" not in text:
        fail(f"corrupt packet: exit {rc}", log)
    print("test_mdcan_bridge: frames both ways, striping over 2 lines, a corrupt packet counted: ok")


def interleave(streams):
    out, n = bytearray(), max(len(s) for s in streams)
    for k in range(n):
        for s in streams:
            if k < len(s):
                out.append(s[k])
    return out


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1])
