"""Helpers of the firmware_sim end-to-end tests: test signal, quantisation, frame streams with
injected faults, the offline reference, the firmware process and Modbus register decoding.

Binaries come from DV_E2E_BUILD (default build/e2e, made by tests/e2e/run_e2e.sh).
"""

from __future__ import annotations

import math
import os
import re
import select
import signal
import socket
import struct
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("DV_E2E_BUILD", ROOT / "build" / "e2e"))
SIM_BIN = BUILD / "firmware_sim" / "firmware_sim"
OFFLINE_BIN = BUILD / "firmware_sim" / "dv_sim_offline"
REGMAP_H = ROOT / "firmware_sim" / "sim_regmap.h"

CODEC_H = ROOT / "include" / "dynval" / "dv_codec.h"


def _codec_define(name: str) -> int:
    """An integer #define of dv_codec.h (the one source of the CAN contract)."""
    m = re.search(rf"#define {name} (0[xX][0-9a-fA-F]+|\d+)u?\b", CODEC_H.read_text())
    if m is None:
        raise KeyError(f"{name} is not an integer #define of {CODEC_H}")
    return int(m.group(1), 0)


ID_STATUS, ID_CTRL, ID_CHCFG, ID_SAMPLES, ID_FEATURE, ID_RESID = (
    _codec_define(f"DV_CAN_ID_{n}") for n in ("STATUS", "CTRL", "CHCFG", "SAMPLES", "FEATURE",
                                              "RESID"))
CTRL_START, CTRL_STOP, CTRL_CLEAR, CTRL_STATUS = (
    _codec_define(f"DV_CTRL_{n}") for n in ("START", "STOP", "CLEAR", "STATUS"))
MISSING = -32768

# small records so a VM run stays short: window 64, 16 segments of 32 = 512-sample records
N_CHAN, FS_HZ, WIN, SEG, NSEG = 5, 640, 64, 32, 16
SIM_ARGS = ["-c", str(N_CHAN), "-f", str(FS_HZ), "-w", str(WIN), "-s", str(SEG),
            "-n", str(NSEG), "-H", "0"]


def regmap() -> dict[str, int]:
    """The #defines of sim_regmap.h that are plain integers (the one source of the map)."""
    out: dict[str, int] = {}
    for m in re.finditer(r"#define (SIM_\w+) (\d+)\b", REGMAP_H.read_text()):
        out[m.group(1)] = int(m.group(2))
    return out


def test_signal(n: int, n_chan: int = N_CHAN, seed: int = 5) -> np.ndarray:
    """n x n_chan: force-like random input and four decaying multi-mode responses.
    DV_E2E_CSV=path uses columns 1.. of a recorded test instead (e.g. lanl4dof test_high_01)."""
    csv = os.environ.get("DV_E2E_CSV")
    if csv:
        data = np.loadtxt(csv, delimiter=",", skiprows=1)[:n, 1:1 + n_chan]
        return data
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_HZ
    x = np.empty((n, n_chan))
    x[:, 0] = 40.0 * rng.standard_normal(n)
    for c in range(1, n_chan):
        f1, f2 = 18.0 + 9 * c, 95.0 + 13 * c
        x[:, c] = (3.0 * np.sin(2 * np.pi * f1 * t) * np.exp(-0.15 * t)
                   + 0.8 * np.sin(2 * np.pi * f2 * t + c) + 0.05 * c
                   + 0.2 * rng.standard_normal(n))
    return x


def lsb_for(col: np.ndarray) -> float:
    """Power-of-two lsb putting the peak near 30000 counts (exact in binary32)."""
    peak = float(np.max(np.abs(col))) or 1.0
    return 2.0 ** math.ceil(math.log2(peak / 30000.0))


def quantise(x: np.ndarray, lsbs: list[float]) -> np.ndarray:
    raw = np.empty(x.shape, dtype=np.int64)
    for c, lsb in enumerate(lsbs):
        v = x[:, c] / lsb
        raw[:, c] = np.where(v >= 0, np.floor(v + 0.5), -np.floor(-v + 0.5))
    return np.clip(raw, -32767, 32767)


def f32_bits(x: float) -> int:
    return struct.unpack("<I", struct.pack("<f", x))[0]


def bits_f32(b: int) -> float:
    return struct.unpack("<f", struct.pack("<I", b))[0]


@dataclass
class Frame:
    id: int
    data: bytes
    extended: bool = False
    # for sample frames: the channel and raw samples, and whether firmware should use them
    ch: int = -1
    raw: tuple[int, ...] = ()
    use: bool = False


def ctrl(cmd: int, record_id: int = 0) -> Frame:
    return Frame(ID_CTRL, struct.pack("<BBIH", cmd, 0, record_id, 0))


def chcfg(ch: int, fs: int, lsb: float, flags: int = 1) -> Frame:
    return Frame(ID_CHCFG, struct.pack("<BBHf", ch, flags, fs, lsb))


def samples(ch: int, seq: int, raw: tuple[int, int, int], use: bool = True) -> Frame:
    return Frame(ID_SAMPLES, struct.pack("<BBhhh", ch, seq & 0xFF, *raw), ch=ch, raw=raw,
                 use=use)


def sample_frames(raw: np.ndarray) -> list[Frame]:
    """Channels interleaved frame by frame, 3 samples per frame, seq per channel."""
    n = raw.shape[0] // 3
    out = []
    for k in range(n):
        for c in range(raw.shape[1]):
            out.append(samples(c, k, tuple(int(v) for v in raw[3 * k:3 * k + 3, c])))
    return out


@dataclass
class Injected:
    lost: int = 0
    dup: int = 0
    late: int = 0
    bad_dlc: int = 0
    unknown: int = 0
    nan: int = 0
    per_chan_lost: dict[int, int] = field(default_factory=dict)


def inject_faults(frames: list[Frame], start: int, rng: np.random.Generator,
                  n_each: int = 6) -> tuple[list[Frame], Injected]:
    """Damage the stream after index @p start: drops, duplicates, adjacent swaps (same channel),
    unknown ids, wrong DLC (extra frames), missing samples. Faults are spaced so none overlap,
    and @p use marks what the firmware must accept."""
    inj = Injected()
    out = list(frames[:start])
    rest = frames[start:]
    kinds = (["drop", "dup", "swap", "unknown", "dlc", "nan"] * n_each)
    rng.shuffle(kinds)
    gap = max(len(rest) // (len(kinds) + 1), 3 * N_CHAN)
    i = 0
    for j, f in enumerate(rest):
        if j % gap != gap // 2 or i >= len(kinds) or f.id != ID_SAMPLES or not f.use:
            out.append(f)
            continue
        k = kinds[i]
        i += 1
        if k == "drop":
            inj.lost += 1
            inj.per_chan_lost[f.ch] = inj.per_chan_lost.get(f.ch, 0) + 1
            continue  # f never sent
        if k == "dup":
            out.append(f)
            out.append(Frame(f.id, f.data, ch=f.ch, raw=f.raw, use=False))
            inj.dup += 1
        elif k == "swap":
            # hold f back until the next frame of its channel went out: f arrives late
            q = next((q for q in range(j + 1, len(rest)) if rest[q].ch == f.ch), None)
            if q is None:
                out.append(f)
                continue
            rest.insert(q + 1, Frame(f.id, f.data, ch=f.ch, raw=f.raw, use=False))
            inj.late += 1
        elif k == "unknown":
            out.append(f)
            out.append(Frame(0x7FF, b"\x00" * 8))
            out.append(Frame(0x1234567, b"\x01" * 8, extended=True))
            out.append(Frame(0x201, f.data))
            inj.unknown += 3
        elif k == "dlc":
            out.append(f)
            out.append(Frame(ID_SAMPLES, f.data[:6]))
            out.append(Frame(ID_CHCFG, b"\x00\x01"))
            inj.bad_dlc += 2
        elif k == "nan":
            raw = (f.raw[0], MISSING, f.raw[2])
            g = samples(f.ch, f.data[1], raw)
            out.append(g)
            inj.nan += 1
    return out, inj


def accepted_stream(frames: list[Frame], placeholders: bool = False) -> dict[int, list[int]]:
    """Per channel, the raw samples firmware_sim feeds its stages, in order. With
    @p placeholders, a sequence gap adds 3 missing samples per lost frame, as the firmware
    does for the observer (the features drop missing samples, so they are unaffected)."""
    per: dict[int, list[int]] = {}
    last: dict[int, int] = {}
    for f in frames:
        if f.id == ID_SAMPLES and f.use:
            seq = f.data[1]
            if placeholders and f.ch in last:
                per[f.ch].extend([MISSING] * (3 * ((seq - last[f.ch] - 1) & 0xFF)))
            last[f.ch] = seq
            per.setdefault(f.ch, []).extend(f.raw)
    return per


# LANL 4-DOF frame (../shared/data/synthetic/lanl4dof-*/declared_model.json) as the 32 model
# registers of sim_regmap.h: n_dof, 8 masses, 8 k, 8 zeta, q, r, input_dof, 4 reserved
LANL_MODEL = ([4.0] + [6.54, 6.66, 6.86, 6.8] + [0.0] * 4
              + [10.0, 399790.0, 399790.0, 399790.0] + [0.0] * 4
              + [0.01, 0.05, 0.01, 0.01] + [0.0] * 4 + [1.0, 0.04, 0.0] + [0.0] * 4)
AR_ORDER, OUTLIER_X100 = 8, 300


def model_arg(model: list[float]) -> str:
    return ",".join(repr(v) for v in model)


def offline_run(streams: dict[int, list[int]], lsbs: list[float], n_chan: int = N_CHAN,
                win: int = WIN, seg: int = SEG, nseg: int = NSEG, fs: int = FS_HZ,
                ar: tuple[int, int] | None = None, model: list[float] | None = None,
                force_chan: int = 0, decim: int = 1):
    """Feature frames {(channel, feat_id, index): value bits} and observer residual frames
    {(channel, step): value bits} from tests/e2e/offline_features.c."""
    lines = [f"config {n_chan} {win} {seg} {nseg}"]
    lines += [f"chan {c} {fs} {f32_bits(lsbs[c]):08X}" for c in range(n_chan)]
    if ar:
        lines.append(f"ar {ar[0]} {ar[1]}")
    if model:
        lines.append(f"model {force_chan} {decim} "
                     + " ".join(f"{f32_bits(v):08X}" for v in model))
    for c, s in streams.items():
        lines += [f"s {c} {v}" for v in s]
    r = subprocess.run([str(OFFLINE_BIN)], input="\n".join(lines) + "\n", capture_output=True,
                       text=True, check=True)
    feats, resid = {}, {}
    for ln in r.stdout.splitlines():
        p = ln.split()
        if p[0] == "F":
            feats[(int(p[2]), int(p[1]), int(p[3]))] = int(p[4], 16)
        else:
            resid[(int(p[1]), int(p[2]))] = int(p[3], 16)
    return feats, resid


def offline_features(streams: dict[int, list[int]], lsbs: list[float], **kw):
    return offline_run(streams, lsbs, **kw)[0]


def resid_key(data: bytes) -> tuple[tuple[int, int], int]:
    ch, _flags, step, bits = struct.unpack("<BBHI", data)
    return (ch, step), bits


def feature_key(data: bytes) -> tuple[tuple[int, int, int], int]:
    fid, ch, idx, bits = struct.unpack("<BBHI", data)
    return (ch, fid, idx), bits


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Sim:
    """firmware_sim as a child process: started, waited for ("ready" line), stopped by SIGTERM."""

    def __init__(self, args: list[str], log_dir: Path, timeout: float = 30.0):
        self.port = free_port()
        self.log = log_dir / f"sim_{self.port}.log"
        self.errf = open(log_dir / f"sim_{self.port}.stderr", "w+")
        cmd = [str(SIM_BIN), "-p", str(self.port), "--log", str(self.log), "-v", *args]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=self.errf, text=True)
        deadline = time.monotonic() + timeout
        line = ""
        while time.monotonic() < deadline:
            r, _, _ = select.select([self.proc.stdout], [], [], 0.2)
            if r:
                line = self.proc.stdout.readline()
                if line.startswith("firmware_sim ready") or line == "":
                    break
            if self.proc.poll() is not None:
                break
        if not line.startswith("firmware_sim ready"):
            self.proc.kill()
            self.proc.wait()
            self.errf.seek(0)
            raise RuntimeError(f"firmware_sim did not start (rc {self.proc.returncode}): "
                               f"{self.errf.read()}")

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                return -9
        self.errf.close()
        return self.proc.returncode

    def stderr(self) -> str:
        self.errf.flush()
        return Path(self.errf.name).read_text()


def u32(regs, addr: int) -> int:
    return (regs[addr] << 16) | regs[addr + 1]


def f32(regs, addr: int) -> float:
    return bits_f32(u32(regs, addr))


def read_inputs(client, n: int) -> list[int]:
    """All n input registers in chunks of 100 (Modbus allows 125 per request)."""
    regs: list[int] = []
    for a in range(0, n, 100):
        rr = client.read_input_registers(a, count=min(100, n - a))
        assert not rr.isError(), rr
        regs += list(rr.registers)
    return regs


def raw_modbus(port: int, pdu: bytes, tid: int = 7) -> bytes:
    """Send one raw Modbus TCP request (unit 1) and return the response PDU."""
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu)
        hdr = b""
        while len(hdr) < 7:
            chunk = s.recv(7 - len(hdr))
            if not chunk:
                raise ConnectionError("closed")
            hdr += chunk
        _, _, ln, _ = struct.unpack(">HHHB", hdr)
        body = b""
        while len(body) < ln - 1:
            body += s.recv(ln - 1 - len(body))
        return body
