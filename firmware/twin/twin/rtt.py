"""The RTT control block (SEGGER RTT, as defmt-rtt lays it out) read out of the twin's
RAM, the way probe-rs reads it from a board: up-channel 0's bytes between RdOff and
WrOff, RdOff advanced. The bytes are defmt frames; `defmt-print -e ELF` decodes them."""

import shutil
import subprocess

from .regs import TwinError

# SEGGER_RTT_CB: acID[16], MaxNumUpBuffers, MaxNumDownBuffers, then the up buffers
# (sName, pBuffer, SizeOfBuffer, WrOff, RdOff, Flags: 6 words each)
UP0 = 24


class RttReader:
    def __init__(self, twin, elf, log_path):
        self.twin = twin
        self.addr = twin.symbols.get("_SEGGER_RTT")
        if self.addr is None:
            raise TwinError("the ELF has no _SEGGER_RTT (defmt-rtt) control block")
        self.raw = bytearray()
        self.decoder = None
        self.log_path = log_path
        if shutil.which("defmt-print"):
            self.out = open(log_path, "w")
            self.decoder = subprocess.Popen(
                ["defmt-print", "-e", elf, "--show-skipped-frames"],
                stdin=subprocess.PIPE,
                stdout=self.out,
                stderr=subprocess.STDOUT,
            )

    def poll(self, _twin=None):
        uc = self.twin.uc
        ident = bytes(uc.mem_read(self.addr, 16))
        if not ident.startswith(b"SEGGER RTT"):
            return  # not set up yet (defmt-rtt writes it at the first log)
        w = [int.from_bytes(uc.mem_read(self.addr + UP0 + 4 * i, 4), "little") for i in range(6)]
        _name, buf, size, wr, rd, _flags = w
        if size == 0 or wr >= size or rd >= size or wr == rd:
            return
        if wr > rd:
            data = bytes(uc.mem_read(buf + rd, wr - rd))
        else:
            data = bytes(uc.mem_read(buf + rd, size - rd)) + bytes(uc.mem_read(buf, wr))
        uc.mem_write(self.addr + UP0 + 16, wr.to_bytes(4, "little"))
        self.raw += data
        if self.decoder is not None:
            self.decoder.stdin.write(data)
            self.decoder.stdin.flush()

    def close(self):
        """Decoded lines (empty without defmt-print)."""
        if self.decoder is None:
            return []
        self.decoder.stdin.close()
        self.decoder.wait(timeout=30)
        self.out.close()
        with open(self.log_path) as f:
            return f.read().splitlines()
