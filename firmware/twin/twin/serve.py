"""`firmware/twin/run --serve PTY`: the twin's USART2 behind a pseudo-terminal, the way
`firmware/qemu/serve-link` serves the QEMU build, so `gantry --port PTY …` talks to the
release firmware over the very path it takes to a board's UART. The bytes cross at the
UART's own timing (BRR from PCLK1): the host sees the board's link, only slower in wall
time (the twin runs at about 0.1 x real time)."""

import json
import os
import signal
import sys
import time
import tty

from .machine import Twin
from .plant import Plant
from .regs import PowerCut, TwinError
from .rtt import RttReader

# machine time between two looks at the pty (a byte at 921,600 baud takes 10.9 µs: 1 ms
# holds 92 bytes, far more than the link's 64-byte frames arrive in)
POLL_S = 1e-3
# bytes USART2 sent that wait for a pty nobody reads (then the oldest go)
OUT_BACKLOG = 1 << 20


# the settings store's sectors 10 and 11 (firmware/memory.x): what --flash keeps
STORE_OFF, STORE_LEN = 0xC_0000, 0x4_0000


def load_store(path):
    """The store's sectors and the option bytes a previous --serve left in `path`."""
    if path is None or not os.path.exists(path):
        return None, None
    with open(path, "rb") as f:
        raw = f.read()
    if len(raw) != STORE_LEN + 4:
        raise SystemExit(f"--flash {path}: {len(raw)} bytes, not a twin flash file ({STORE_LEN + 4})")
    return [(STORE_OFF, raw[:STORE_LEN])], int.from_bytes(raw[STORE_LEN:], "little")


def save_store(path, t):
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(bytes(t.flash_mem[STORE_OFF : STORE_OFF + STORE_LEN]))
        f.write(t.option_bytes.to_bytes(4, "little"))
    os.replace(tmp, path)


class Control:
    """`PTY.ctl`: what the outside does to the board while it serves, one command a line,
    appended by a test and read at every poll (machine time: a command lands within
    POLL_S of the machine time its line was read at):

        drive B12 1                     the e-stop (or any input pin) driven high / low
        inject {"encoder_stuck": {"axis": "x"}}
                                        a fault in the machine (controller-core's
                                        `Injection` as JSON, to the plant)
        flash-sr 0x80                   FLASH_SR error bits set, as a stray store leaves them
        power-cut erase                 the power goes half way through the next sector
                                        erase (its first half erased, the rest as it was)
        hardfault                       a HardFault (an imprecise bus fault) at the next
                                        instruction, whatever the core is running
        power-cut program N             ... while the N-th word program from now runs
                                        (half its bytes programmed): the twin stops, the
                                        flash file keeps that state

    Each command is echoed to `PTY.ctl.done` as `t_s command` once it has landed (or `t_s
    error: …` naming the line: a bad line changes nothing). `PTY.outputs` gets every change
    of a machine output from boot on, `t_s signal value` a line (the twin's output log)."""

    def __init__(self, pty_path):
        self.path = pty_path + ".ctl"
        self.done_path = pty_path + ".ctl.done"
        self.outputs_path = pty_path + ".outputs"
        for p in (self.path, self.done_path, self.outputs_path):
            if os.path.exists(p):
                os.remove(p)
        self.offset = 0
        self.partial = b""
        self.line_no = 0
        self.logged = 0
        self.done = open(self.done_path, "w")
        self.outputs = open(self.outputs_path, "w")

    def poll(self, tw):
        for tt, k, v in tw.log[self.logged:]:
            self.outputs.write(f"{tt:.9f} {k} {v}\n")
        if len(tw.log) > self.logged:
            self.logged = len(tw.log)
            self.outputs.flush()
        try:
            with open(self.path, "rb") as f:
                f.seek(self.offset)
                data = f.read()
        except FileNotFoundError:
            return
        self.offset += len(data)
        data = self.partial + data
        *lines, self.partial = data.split(b"\n")
        for raw in lines:
            self.line_no += 1
            line = raw.decode(errors="replace").strip()
            if not line:
                continue
            try:
                self.apply(tw, line)
                self.done.write(f"{tw.t_s:.9f} {line}\n")
            except (ValueError, KeyError, TwinError) as e:
                self.done.write(f"{tw.t_s:.9f} error: {self.path} line {self.line_no}: {line!r}: {e}\n")
        self.done.flush()

    @staticmethod
    def apply(tw, line):
        cmd, _, arg = line.partition(" ")
        if cmd == "drive":
            pin, level = arg.split()
            port, n = pin[0].upper(), int(pin[1:])
            if port not in "ABCDE" or not 0 <= n <= 15 or level not in ("0", "1"):
                raise ValueError("want `drive <A-E><0-15> <0|1>`")
            tw.drive((port, n), int(level))
        elif cmd == "inject":
            tw.plant.inject(json.loads(arg))
        elif cmd == "flash-sr":
            bits = int(arg, 0)
            if bits & ~0xF2:
                raise ValueError("FLASH_SR error bits are 0xF2 (OPERR, WRPERR, PGAERR, PGPERR, PGSERR)")
            tw.flash["SR"] |= bits
        elif cmd == "power-cut":
            tw.flash.power_cut(arg)
        elif cmd == "hardfault" and not arg:
            tw.call_after_insns = (1, lambda t: t.hard_fault(t.pc, "injected by PTY.ctl: an imprecise bus fault"))
        else:
            raise ValueError("unknown command (drive, inject, flash-sr, power-cut, hardfault)")

    def close(self):
        self.done.close()
        self.outputs.close()


class _Stop:
    """SIGTERM: the run stops at its next poll. (Raised from the signal handler, the
    exception would land inside one of unicorn's callbacks, which ctypes swallows.)"""

    asked = False

    def __call__(self, _sig, _frame):
        self.asked = True


def serve(elf, pty_path, seconds, log_path, flash_path=None):
    image, optcr = load_store(flash_path)
    t = Twin(elf, flash_image=image, **({"option_bytes": optcr} if optcr is not None else {}))
    t.plant = Plant(t)
    stop = _Stop()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    if os.path.lexists(pty_path):
        os.remove(pty_path)
    os.symlink(os.ttyname(slave), pty_path)
    out = bytearray()
    t.usart2_sink = out.append
    rtt = RttReader(t, elf, log_path)
    # before the clock appears (a test takes the clock as "up" and writes commands)
    ctl = Control(pty_path)
    # the machine clock gantry --twin counts its timeouts in (ms, u32 little-endian)
    clock_path = pty_path + ".clock"
    clock = os.open(clock_path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o644)
    os.pwrite(clock, (0).to_bytes(4, "little"), 0)
    print(f"twin: the release firmware's USART2 is at {pty_path}", flush=True)

    stats = {"next_s": 1.0, "in": 0, "out": 0, "backlog": 0, "dropped": 0}

    dump = {"want": False}
    signal.signal(signal.SIGUSR1, lambda *_: dump.update(want=True))

    def poll(tw):
        if stop.asked:
            raise KeyboardInterrupt
        if dump["want"]:
            dump["want"] = False
            print("twin: " + tw.describe(), flush=True)
        if tw.t_s >= stats["next_s"] and os.environ.get("TWIN_LINK_STATS"):
            stats["next_s"] += 1.0
            print(f"twin: {tw.t_s:.0f} s: host bytes in {stats['in']}, out {stats['out']} (largest backlog {stats['backlog']}, "
                  f"dropped {stats['dropped']}), overruns {tw.usart_overruns}", flush=True)
        rtt.poll()
        ctl.poll(tw)
        os.pwrite(clock, (int(tw.t_s * 1000) & 0xFFFF_FFFF).to_bytes(4, "little"), 0)
        if out:
            try:
                n = os.write(master, bytes(out))
                stats["out"] += n
                del out[:n]
            except BlockingIOError:
                # the pty is full: its reader is behind (the host runs in wall time, the
                # board in machine time, and a busy machine deschedules the host), or
                # there is none yet. The bytes wait for it, as in a host's serial
                # driver, rather than be lost to a host that only fell behind in wall
                # time. Beyond OUT_BACKLOG (nobody reads) the oldest go.
                if len(out) > OUT_BACKLOG:
                    stats["dropped"] += len(out) - OUT_BACKLOG
                    del out[: len(out) - OUT_BACKLOG]
                stats["backlog"] = max(stats["backlog"], len(out))
            except OSError:
                out.clear()
        try:
            data = os.read(master, 4096)
        except (BlockingIOError, OSError):
            data = b""
        if data:
            stats["in"] += len(data)
            tw.usart2.send(data)

    w = time.time()
    try:
        t.run(seconds, poll=poll, poll_every_s=POLL_S)
    except KeyboardInterrupt:
        print(f"twin: stopped at {t.t_s:.3f} machine s", flush=True)
        if stats["backlog"]:
            print(f"twin: USART2's bytes waited for the pty's reader: {stats['backlog']} at most, "
                  f"{stats['dropped']} dropped", file=sys.stderr, flush=True)
    except PowerCut as e:
        print(f"twin: {e} at {t.t_s:.6f} machine s", flush=True)
    finally:
        if flash_path is not None:
            # the power goes off: the flash keeps what was written
            save_store(flash_path, t)
        rtt.close()
        ctl.close()
        t.plant.close()
        if os.environ.get("TWIN_DUMP_TX"):
            with open(os.environ["TWIN_DUMP_TX"], "wb") as f:
                f.write(bytes(t.usart2.sent))
        os.remove(pty_path)
        os.close(clock)
        os.remove(clock_path)
        os.close(master)
        os.close(slave)
    return t, time.time() - w
