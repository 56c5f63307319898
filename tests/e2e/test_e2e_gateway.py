"""End-to-end: `dynval run --bus socketcan` against the real firmware_sim on vcan0 (the gateway
package's replay + logger over SocketCAN), then the MCAP is checked: every sample frame logged
in order, the firmware's features and residuals present, record statistics equal to the
library run offline on the same quantised samples (to float32 rounding: firmware_sim here is
the float build, the package's core is double).

Run by tests/e2e/run_e2e.sh (directly on a kernel with vcan, else inside the QEMU VM); skipped
without vcan0 unless DV_E2E_REQUIRE_VCAN=1."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import dv_e2e as E
import numpy as np
import pytest

pytest.importorskip("can")
dynval = pytest.importorskip("dynval")

HAVE_VCAN = Path("/sys/class/net/vcan0").exists()
if not HAVE_VCAN and os.environ.get("DV_E2E_REQUIRE_VCAN") == "1":
    raise RuntimeError("DV_E2E_REQUIRE_VCAN=1 but vcan0 does not exist")
pytestmark = pytest.mark.skipif(not HAVE_VCAN, reason="no vcan0 (run tests/e2e/run_e2e.sh)")

FOLDER = E.ROOT / "data" / "lanl4dof-sim" / "clean"
TEST = FOLDER / "test_low_01.csv"
WIN, SEG, NSEG = 64, 32, 16
# the test's first samples only (4 feature records): each frame is logged by Python in the
# emulated VM, and the whole 8192-sample test took 146 s of its 195 s there
N_SAMPLES = 4 * SEG * NSEG
# a residual frame every 16 observer steps: per-step residuals (4 x 640 frames/s) outrun the
# Python logger in the emulated VM (its socket drops; the firmware itself loses nothing)
DECIM = 16


def test_dynval_run_socketcan_against_firmware_sim(tmp_path):
    from dynval import bus, features
    from dynval.io import read_test
    from dynval.io.mcapfile import Scan, iter_messages

    out = Path(os.environ.get("VCAN_OUT", tmp_path)) / "gateway_run"
    folder = tmp_path / FOLDER.name  # the declared model beside it, as in the bundled folder
    folder.mkdir()
    (folder / "declared_model.json").write_bytes((FOLDER / "declared_model.json").read_bytes())
    test = folder / TEST.name
    with TEST.open() as src:
        test.write_text("".join(line for _, line in zip(range(N_SAMPLES + 1), src)))
    cmd = [sys.executable, "-m", "dynval", "-q", "run", str(test), "--bus", "socketcan",
           "--channel", "vcan0", "--firmware", str(E.SIM_BIN), "--speed", "0.25",
           "--resid-decim", str(DECIM),
           "--win", str(WIN), "--seg", str(SEG), "--nseg", str(NSEG), "-o", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600,
                       env={**os.environ, "TMPDIR": os.environ.get("TMPDIR", "/tmp")})
    assert r.returncode == 0, r.stdout + r.stderr
    assert "bus: socketcan:vcan0, firmware: firmware_sim" in r.stdout
    mc = out / "clean_test_low_01.mcap"
    sc = Scan()
    feats: dict[tuple[int, int, int], float] = {}
    n_resid = 0
    seqs: dict[int, list[int]] = {}
    for m in iter_messages(mc, scan_out=sc):
        if m.topic == "/dv/features":
            feats[(m.data["channel"], m.data["feat_id"], m.data["index"])] = m.data["value"]
        elif m.topic == "/dv/residuals":
            n_resid += 1
        elif m.topic.startswith("/dv/samples/"):
            seqs.setdefault(m.data["channel"], []).append(m.sequence)
    assert sc.complete and sc.error == ""
    rec = read_test(test)
    assert rec.n_samples == N_SAMPLES
    plan = bus.make_plan(rec)
    nf = plan.n_frames_per_channel
    assert sorted(seqs) == [0, 1, 2, 3, 4]
    # one message per sample, its sequence the sample number: nothing lost or reordered
    assert all(v == list(range(3 * nf)) for v in seqs.values())
    # declared model: observer on, cubic hold (one sample late): residuals for steps
    # 0 .. nf*3-3 — the last sample waits for an input that is padding (missing), not data
    assert n_resid == 4 * len(range(0, nf * 3 - 2, DECIM))
    n_rec = rec.n_samples // (SEG * NSEG)
    for c in range(5):
        recs, _ = features.channel_records(plan.values(c), rec.fs_hz, WIN, SEG, NSEG)
        assert len(recs) == n_rec
        for rf in recs:
            got = feats[(c, 0x12, rf.index)]  # record RMS
            assert got == pytest.approx(rf.stats.rms, rel=2e-5)
            assert feats[(c, 0x15, rf.index)] == np.float32(rf.stats.peak)
