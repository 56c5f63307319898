"""can/dynval.dbc loads with cantools and agrees byte for byte with the C codec (dv_codec.c).

The C side runs through tests/tools/dv_codec_dump.c, compiled here from the codec sources only
(set DV_CODEC_DUMP to use a prebuilt one). Random messages are encoded by both and compared as
bytes; random payloads are decoded by both and compared field by field.
"""

from __future__ import annotations

import os
import random
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

cantools = pytest.importorskip("cantools")

ROOT = Path(__file__).resolve().parents[2]
DBC = ROOT / "can" / "dynval.dbc"
N = 2000

KIND_OF = {
    "DV_STATUS": "status",
    "DV_CTRL": "ctrl",
    "DV_CHCFG": "chcfg",
    "DV_SAMPLES": "samples",
    "DV_FEATURE": "feature",
    "DV_RESID": "resid",
}
# field order of the dump tool, per kind; floats travel as binary32 bit patterns
FIELDS = {
    "status": ["state", "beat", "lost", "dup", "late", "bad_dlc", "unknown"],
    "ctrl": ["cmd", "record_id"],
    "chcfg": ["channel", "flags", "fs_hz", "lsb"],
    "samples": ["channel", "seq", "s0", "s1", "s2"],
    "feature": ["feat_id", "channel", "index", "value"],
    "resid": ["channel", "flags", "step", "value"],
}
FLOATS = {"lsb", "value"}


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(str(DBC))


@pytest.fixture(scope="module")
def dump(tmp_path_factory):
    exe = os.environ.get("DV_CODEC_DUMP")
    if exe:
        return exe
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        pytest.skip("no C compiler")
    out = tmp_path_factory.mktemp("dump") / "dv_codec_dump"
    subprocess.run(
        [cc, "-std=c99", "-O1", f"-I{ROOT / 'include'}", str(ROOT / "tests/tools/dv_codec_dump.c"),
         str(ROOT / "src/dv_codec.c"), str(ROOT / "src/dv_common.c"), "-lm", "-o", str(out)],
        check=True,
    )
    return str(out)


def run_c(exe: str, lines: list[str]) -> list[str]:
    r = subprocess.run([exe], input="\n".join(lines) + "\n", capture_output=True, text=True,
                       check=True)
    out = r.stdout.splitlines()
    assert len(out) == len(lines)
    return out


def f2b(x: float) -> int:
    return struct.unpack("<I", struct.pack("<f", x))[0]


def b2f(b: int) -> float:
    return struct.unpack("<f", struct.pack("<I", b))[0]


def rand_finite_f32(rng: random.Random) -> int:
    while True:
        b = rng.getrandbits(32)
        if (b >> 23) & 0xFF != 0xFF:
            return b


def rand_fields(rng: random.Random, msg) -> dict[str, int]:
    vals: dict[str, int] = {}
    for s in msg.signals:
        if s.name in FLOATS:
            vals[s.name] = rand_finite_f32(rng)
        elif s.is_signed:
            vals[s.name] = rng.randint(-(1 << (s.length - 1)), (1 << (s.length - 1)) - 1)
        else:
            vals[s.name] = rng.randint(0, (1 << s.length) - 1)
    if msg.name == "DV_CTRL":
        vals["cmd"] = rng.randint(1, 4)
    if msg.name == "DV_CHCFG":
        vals["lsb"] = f2b(rng.choice([2.0**-10, 1e-3, 0.05, 3.0e-5]))
        vals["fs_hz"] = rng.randint(1, 65535)
    return vals


def test_dbc_loads_and_matches_header_ids(db):
    hdr = (ROOT / "include/dynval/dv_codec.h").read_text()
    ids = {m.group(1): int(m.group(2), 16)
           for m in re.finditer(r"#define DV_CAN_ID_(\w+) (0x[0-9A-Fa-f]+)u", hdr)}
    assert {f"DV_{k}": v for k, v in ids.items()} == {m.name: m.frame_id for m in db.messages}
    for m in db.messages:
        assert m.length == 8 and not m.is_extended_frame
        used = sum(s.length for s in m.signals)
        assert used <= 64


def test_dbc_encode_matches_c_byte_for_byte(db, dump):
    rng = random.Random(5)
    reqs, want = [], []
    for _ in range(N):
        msg = rng.choice(db.messages)
        kind = KIND_OF[msg.name]
        vals = rand_fields(rng, msg)
        phys = {k: (b2f(v) if k in FLOATS else v) for k, v in vals.items()}
        data = msg.encode(phys, scaling=False, strict=False, padding=False)
        want.append(f"OK {msg.frame_id:03X} {bytes(data).hex().upper()}")
        args = " ".join(f"{vals[f]:08X}" if f in FLOATS else str(vals[f]) for f in FIELDS[kind])
        reqs.append(f"E {kind} {args}")
    got = run_c(dump, reqs)
    bad = [(r, w, g) for r, w, g in zip(reqs, want, got) if w != g]
    assert not bad, bad[:5]


def test_dbc_decode_matches_c(db, dump):
    rng = random.Random(6)
    reqs, frames = [], []
    for _ in range(N):
        msg = rng.choice(db.messages)
        data = bytes(rng.getrandbits(8) for _ in range(8))
        if msg.name == "DV_CHCFG" and rng.random() < 0.7:
            data = data[:4] + struct.pack("<f", 2.0**-rng.randint(0, 20))  # mostly valid
        if msg.name == "DV_CTRL" and rng.random() < 0.7:
            data = bytes([rng.randint(1, 4)]) + data[1:]
        reqs.append(f"D {msg.frame_id:X} 8 {data.hex()}")
        frames.append((msg, data))
    got = run_c(dump, reqs)
    n_ok = 0
    for (msg, data), g in zip(frames, got):
        dec = msg.decode(data, decode_choices=False, scaling=False)
        kind = KIND_OF[msg.name]
        if msg.name == "DV_CTRL" and not 1 <= dec["cmd"] <= 4:
            assert g == "ERR DV_ERANGE"
            continue
        if msg.name == "DV_CHCFG":
            lsb = dec["lsb"]
            if not (lsb > 0 and lsb != float("inf")) or dec["fs_hz"] == 0:
                assert g == "ERR DV_ENUMERIC"
                continue
        parts = g.split()
        assert parts[:2] == ["OK", kind], g
        for name, text in zip(FIELDS[kind], parts[2:]):
            if name in FLOATS:
                want_bits = f2b(dec[name]) if dec[name] == dec[name] else None
                if want_bits is None:  # NaN: compare the raw payload bits instead
                    want_bits = struct.unpack("<I", data[4:8])[0]
                assert int(text, 16) == want_bits, (msg.name, name, g)
            else:
                assert int(text) == dec[name], (msg.name, name, g)
        n_ok += 1
    assert n_ok > N // 2


def test_dbc_unknown_ids_and_bad_dlc(db, dump):
    known = {m.frame_id for m in db.messages}
    rng = random.Random(7)
    unknown = [i for i in rng.sample(range(0x800), 300) if i not in known]
    reqs = [f"D {i:X} 8 0102030405060708" for i in unknown]
    reqs += [f"D {m.frame_id:X} {dlc} 0102030405060708"
             for m in db.messages for dlc in range(0, 8)]
    reqs += [f"D {0x80000000 | 0x200:X} 8 0102030405060708", "D 200 9 0102030405060708"]
    got = run_c(dump, reqs)
    n_u = len(unknown)
    assert all(g == "ERR DV_ERANGE" for g in got[:n_u])
    for i in unknown[:20]:
        with pytest.raises(KeyError):
            db.get_message_by_frame_id(i)
    assert all(g == "ERR DV_ESIZE" for g in got[n_u:-2])
    assert got[-2:] == ["ERR DV_ERANGE", "ERR DV_EINVAL"]
