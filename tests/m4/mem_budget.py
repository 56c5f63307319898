#!/usr/bin/env python3
"""Memory budget and instruction counts of the Cortex-M4F build; writes bench/RESULTS.m4.md.

One command:  tests/m4/mem_budget.py   (builds with tests/m4/run_m4.sh --build-only first;
--no-build to reuse build/m4; --out FILE to write elsewhere). Also rewrites the summary table
in README.md (between its m4-budget markers; --no-readme leaves it).

* Flash per module: the input sections (.text*, .rodata*) that the linker kept in the
  "typical firmware set" image (tests/m4/m4_typical.c, --gc-sections), summed per library
  object from the map file, at -Os and -O2; and each library object whole (arm-none-eabi-size
  of the archive: every function, as a firmware linking without --gc-sections would pay).
* RAM: the sizes of the image's ram_* objects (nm -S): instances and caller buffers (the
  observer's persistent storage only), per channel and for the set; the init-time scratch the
  observer's inits share (tmp_init_scratch) is reported apart, as a transient.
* Instructions per call: the -DM4_ICOUNT image under qemu-system-arm -singlestep
  -d exec,nochain (one trace line per executed instruction, taken or not); the lines between a
  mark_* entry and the next mark_end entry are counted, and the call overhead measured around an
  empty function of the same shape (minus its own 2 instructions) is subtracted.
"""
import argparse
import re
import statistics
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
B = ROOT / "build" / "m4"
QEMU = ["qemu-system-arm", "-M", "mps2-an386", "-cpu", "cortex-m4", "-nographic", "-monitor",
        "none", "-serial", "none", "-semihosting-config", "enable=on,target=native"]
CFG = dict(n_ch=5, win=64, seg_len=64, n_seg=64, ar_p=32, n_dof=4, n_elem=1, n_sub=8, n_out=4)
RUNTIME = "toolchain runtime (newlib libm/libc, libgcc)"
APP = "application + start-up (not the library)"


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout


def map_sections(path):
    """(module, kind) -> bytes from the kept input sections of a GNU ld map file."""
    out = defaultdict(int)
    text = Path(path).read_text().splitlines()
    start = next(i for i, l in enumerate(text) if l.startswith("Linker script and memory map"))
    pending = None
    one = re.compile(r"^ (\.\S+)\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S.*)$")
    name_only = re.compile(r"^ (\.\S+)$")
    cont = re.compile(r"^\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S.*)$")
    for line in text[start:]:
        m = one.match(line)
        if m:
            sec, size, obj = m.group(1), int(m.group(3), 16), m.group(4)
        elif name_only.match(line):
            pending = name_only.match(line).group(1)
            continue
        elif pending and cont.match(line):
            m = cont.match(line)
            sec, size, obj = pending, int(m.group(2), 16), m.group(3)
        else:
            pending = None
            continue
        pending = None
        if size == 0:
            continue
        kind = ("text" if sec.startswith(".text") else "rodata" if sec.startswith(".rodata")
                else "data" if sec.startswith(".data") else "bss" if sec.startswith(".bss")
                else "other")
        mm = re.search(r"libdynval-f32\.a\((\w+)\.c\.obj\)", obj)
        if mm:
            mod = mm.group(1)
        elif re.search(r"lib(m|c|c_nano|g|gcc|nosys)\.a|crt", obj):
            mod = RUNTIME
        else:
            mod = APP
        out[(mod, kind)] += size
    return out


def archive_sizes(lib):
    """module -> (text, data, bss) of each archive member (arm-none-eabi-size -t)."""
    res = {}
    for line in run(["arm-none-eabi-size", str(lib)]).splitlines()[1:]:
        w = line.split()
        m = re.search(r"(\w+)\.c\.obj", line)
        if m:
            res[m.group(1)] = (int(w[0]), int(w[1]), int(w[2]))
    return res


def nm_sizes(elf):
    res = {}
    for line in run(["arm-none-eabi-nm", "-S", str(elf)]).splitlines():
        w = line.split()
        if len(w) == 4:
            res[w[3]] = int(w[1], 16)
    return res


def live_line(elf):
    out = subprocess.run(QEMU + ["-kernel", str(elf)], capture_output=True, text=True,
                         timeout=300)
    text = out.stdout + out.stderr  # semihosting console output goes to stderr
    if out.returncode != 0 or "TYPICAL PASS" not in text:
        sys.exit(f"{elf}: typical set failed under QEMU:\n{text}")
    w = re.search(r"LIVE model (\d+) obs (\d+) model_scratch (\d+) obs_scratch (\d+)", text)
    st = re.search(r"STACK init (\d+) run (\d+)", text)
    return tuple(int(x) for x in w.groups() + st.groups())


def icount(elf):
    """marker -> list of instruction counts per call (trace lines between the markers)."""
    cmd = QEMU + ["-singlestep", "-d", "exec,nochain", "-D", "/dev/stderr", "-kernel", str(elf)]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    counts = defaultdict(list)
    cur, n, done = None, 0, False
    for line in p.stderr:  # the trace and the semihosting console
        if line.startswith(b"ICOUNT DONE"):
            done = True
        if b"] mark_" in line:
            sym = line.rsplit(None, 1)[-1].decode()
            if sym == "mark_end":
                if cur is not None:
                    counts[cur].append(n)
                cur = None
            else:
                cur, n = sym, 0
            continue
        if cur is not None:
            n += 1
    out = p.stdout.read().decode()
    if p.wait(timeout=600) != 0 or not done:
        sys.exit(f"{elf}: instruction-count run failed {out}")
    return counts


def kib(b):
    return f"{b / 1024:.2f}"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-build", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS.m4.md"))
    ap.add_argument("--no-readme", action="store_true", help="leave README.md's table alone")
    a = ap.parse_args()
    if not a.no_build:
        subprocess.run([str(ROOT / "tests/m4/run_m4.sh"), "--build-only"], check=True,
                       stdout=subprocess.DEVNULL)
    gcc = run(["arm-none-eabi-gcc", "--version"]).splitlines()[0]
    qemu = run(["qemu-system-arm", "--version"]).splitlines()[0]
    c = CFG
    L = []
    L.append("# dynval on a Cortex-M4F: memory budget and instructions per sample\n")
    L.append(f"Generated by `tests/m4/mem_budget.py` ({gcc}; {qemu}, board `mps2-an386`). "
             "Float library, `-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard`, "
             "presets `cross-m4` (-Os) and `cross-m4-o2` (-O2).\n")
    L.append(f"**Typical firmware set** (`tests/m4/m4_typical.c`): {c['n_ch']} channels, each "
             f"with every waveform feature through `dv_chan` (record statistics, a sliding window "
             f"of **{c['win']} samples** (0.1 s at 640 Hz, 3 periods of the 29.8 Hz first storey "
             f"mode), segmented STD {c['n_seg']} x {c['seg_len']} = a {c['n_seg'] * c['seg_len']}"
             f"-sample record, temporal moments) and the AR({c['ar_p']}) residual "
             f"(`dv_ar_resid`, coefficients fitted off-line and loaded); the report's "
             f"{c['n_dof']}-DOF observer with one contact (bumper, {c['n_sub']} sub-steps) and "
             f"the steady-state Kalman gain, built on the target (`dv_model_init` eigen-solution "
             f"+ expm, `dv_obs_init` DARE), {c['n_out']} measured accelerations.\n")

    # ---- flash -------------------------------------------------------------------------
    maps = {v: map_sections(B / f"typical-{v}.map") for v in ("os", "o2")}
    whole = archive_sizes(B / "lib-os" / "libdynval-f32.a")
    whole2 = archive_sizes(B / "lib-o2" / "libdynval-f32.a")
    mods = sorted({m for (m, _) in maps["os"] if m.startswith("dv_")} | set(whole))
    L.append("## Flash\n")
    L.append("Bytes of `.text` + `.rodata`. *In the set*: what the linker kept of each object "
             "for the typical set (map file, `--gc-sections`). *Whole module*: the object with "
             "every function (`arm-none-eabi-size` of the archive).\n")
    L.append("| module | in the set, -Os: text | rodata | in the set, -O2: text | rodata | "
             "whole module -Os | whole module -O2 |")
    L.append("|---|---:|---:|---:|---:|---:|---:|")
    tot = {"os": [0, 0], "o2": [0, 0]}
    for m in mods:
        r = []
        for v in ("os", "o2"):
            t, ro = maps[v].get((m, "text"), 0), maps[v].get((m, "rodata"), 0)
            tot[v][0] += t
            tot[v][1] += ro
            r += [t, ro]
        w = whole.get(m, (0, 0, 0))[0]
        w2 = whole2.get(m, (0, 0, 0))[0]
        L.append(f"| {m} | {r[0]} | {r[1]} | {r[2]} | {r[3]} | {w} | {w2} |")
    wt = sum(x[0] for x in whole.values())
    wt2 = sum(x[0] for x in whole2.values())
    L.append(f"| **library total** | **{tot['os'][0]}** | **{tot['os'][1]}** | "
             f"**{tot['o2'][0]}** | **{tot['o2'][1]}** | {wt} | {wt2} |")
    rt = {v: maps[v].get((RUNTIME, "text"), 0) + maps[v].get((RUNTIME, "rodata"), 0)
          for v in ("os", "o2")}
    L.append(f"| {RUNTIME} | {maps['os'].get((RUNTIME, 'text'), 0)} | "
             f"{maps['os'].get((RUNTIME, 'rodata'), 0)} | {maps['o2'].get((RUNTIME, 'text'), 0)} "
             f"| {maps['o2'].get((RUNTIME, 'rodata'), 0)} | | |")
    fl = {v: sum(tot[v]) + rt[v] for v in ("os", "o2")}
    L.append(f"| **typical set (library + runtime)** | **{fl['os']}** = {kib(fl['os'])} KiB | | "
             f"**{fl['o2']}** = {kib(fl['o2'])} KiB | | | |\n")
    ok_f = fl["os"] <= 24 * 1024
    L.append(f"Flash target 24 KiB: **{'met' if ok_f else 'missed'}** at -Os "
             f"({kib(fl['os'])} KiB), {'met' if fl['o2'] <= 24 * 1024 else 'missed'} at -O2 "
             f"({kib(fl['o2'])} KiB). Not counted: the application's own code and constants, "
             f"start-up and vector table ({maps['os'].get((APP, 'text'), 0)} + "
             f"{maps['os'].get((APP, 'rodata'), 0)} B here).\n")

    # ---- RAM ---------------------------------------------------------------------------
    sz = nm_sizes(B / "typical-os.elf")
    lm, lo, ms, osc, st_init, st_run = live_line(B / "typical-os.elf")
    st2 = live_line(B / "typical-o2.elf")[4:]
    n = c["n_ch"]
    rows = [("dv_chan_t (instance)", sz["ram_chan"] // n),
            (f"dv_chan buffer DV_CHAN_BUF_LEN({c['win']}, 0) = {c['win']} ring + 2 x "
             f"{-(-c['win'] // 16)} block-extreme floats (no_seg_vectors: each segment STD is "
             f"published as it completes)", sz["ram_chan_buf"] // n),
            ("dv_ar_resid_t (instance)", sz["ram_ar"] // n),
            (f"AR buffer DV_AR_RESID_BUF_LEN({c['ar_p']}) = {c['ar_p']} coefficients + "
             f"a ring of {c['ar_p']} history floats", sz["ram_ar_buf"] // n)]
    per_ch = sum(r[1] for r in rows)
    assert sz["ram_model_buf"] == 4 * lm and sz["ram_obs_buf"] == 4 * lo
    obs_live = sz["ram_model"] + sz["ram_obs"] + sz["ram_model_buf"] + sz["ram_obs_buf"]
    build = sz["tmp_model_build"]
    scr = sz["tmp_init_scratch"] + build
    L.append("## RAM\n")
    L.append("Static state and caller buffers (`arm-none-eabi-nm -S` of the image; float, "
             "bytes). The library has no other RAM: no globals, no heap (checked by "
             "`tests/scripts/check_lib_symbols.sh`). Only what the steps read stays allocated: "
             "the model is built (`dv_model_init_ex`) in a transient area with one init-time "
             "scratch area that `dv_obs_init_ex` shares (`DV_MODEL_SCRATCH_LEN`, "
             "`DV_OBS_SCRATCH_LEN`: eigen-solutions, matrix exponentials, DARE); after the "
             "observer is bound, `dv_model_keep_step_only` moves the part its steps read "
             "(`DV_MODEL_STEP_LEN`: output and contact sub-node matrices) to the persistent "
             "buffer. The image then overwrites the transient areas with NaN and the set still "
             "passes (the self-test also checks the steps stay bit-identical). A firmware overlays "
             "the transient areas on buffers not live during init, or puts them on the stack; "
             "they are listed apart. Stack: below the table.\n")
    L.append("| item | bytes |")
    L.append("|---|---:|")
    for name, b in rows:
        L.append(f"| per channel: {name} | {b} |")
    L.append(f"| **per channel** | **{per_ch}** |")
    L.append(f"| **{n} channels** | **{n * per_ch}** = {kib(n * per_ch)} KiB |")
    L.append(f"| observer: dv_model_t + dv_obs_t | {sz['ram_model'] + sz['ram_obs']} |")
    L.append(f"| observer: the model's step part DV_MODEL_STEP_LEN = {lm} floats "
             f"| {sz['ram_model_buf']} |")
    L.append(f"| observer: observer persistent storage DV_OBS_PERSIST_LEN = {lo} floats "
             f"| {sz['ram_obs_buf']} |")
    L.append(f"| **observer, persistent** | **{obs_live}** = {kib(obs_live)} KiB |")
    total = n * per_ch + obs_live
    L.append(f"| **typical set, persistent RAM** | **{total}** = **{kib(total)} KiB** |")
    L.append(f"| transient: the model's build storage DV_MODEL_PERSIST_LEN = {build // 4} floats, "
             f"and the init scratch shared by both inits, max(DV_MODEL_SCRATCH_LEN = {ms}, "
             f"DV_OBS_SCRATCH_LEN = {osc}) floats | {scr} = {kib(scr)} KiB |\n")
    L.append(f"Stack, measured (high-water mark of a painted stack in the image, including "
             f"main's frame; the transient areas are the static objects above, not on the stack): init "
             f"of the whole set {st_init} B at -Os / {st2[0]} B at -O2; the per-sample loop "
             f"{st_run} B / {st2[1]} B. Peak RAM with the transient areas on the stack instead: "
             f"{total} + {scr} + {st_init} B = {kib(total + scr + st_init)} KiB during init, "
             f"{kib(total + st_run)} KiB while running.\n")
    inst = sz["ram_chan"] // n + sz["ram_ar"] // n
    L.append(f"RAM target 8 KiB: **{'met' if total <= 8192 else 'missed'}** "
             f"({kib(total)} KiB persistent). The observer keeps {kib(obs_live)} KiB (one folded "
             f"step matrix with the gain, the state, and the model's step part). Per channel the "
             f"cost is {inst} B of instances + 4 B per window sample and 8 B per 16 (the ring "
             f"and its block extremes) + 8 B per AR order (coefficients and the history ring).\n")
    budget = {"flash_os": fl["os"], "flash_o2": fl["o2"], "per_ch": per_ch, "n": n,
              "obs": obs_live, "total": total, "scratch": scr}

    # ---- instruction counts -------------------------------------------------------------
    L.append("## Instructions per call on the Cortex-M4 (-Os and -O2)\n")
    L.append("Counted, not estimated: QEMU `-singlestep -d exec,nochain` logs every executed "
             "instruction of the `-DM4_ICOUNT` image; the instructions between two marker "
             "calls around one library call are counted, minus the call overhead measured the "
             "same way around an empty function (argument set-up, `bl`, return, storing the "
             "status). These are instructions, not cycles: QEMU is not cycle-accurate. On a "
             "Cortex-M4F most of these execute in 1 cycle (loads 2, VFP divide and square root "
             "14), so cycles are roughly 1.1-1.5x the count; with zero-wait-state memory.\n")
    L.append("| hot function | calls | -Os mean | -Os min | -Os max | -O2 mean | -O2 min | "
             "-O2 max | at 640 Hz, -O2 mean: instr/s |")
    L.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    res = {}
    for v in ("os", "o2"):
        cts = icount(B / f"icount-{v}.elf")
        cal = statistics.mean(cts["mark_cal"]) - 2.0
        res[v] = {k: [x - cal for x in vals] for k, vals in cts.items() if k != "mark_cal"}
        res[v]["_cal"] = cal
    labels = [("mark_chan", f"dv_chan_update (all features; window {c['win']}, "
                            f"{c['n_seg']} x {c['seg_len']}; one whole record)"),
              ("mark_ar", f"dv_ar_resid_update, AR({c['ar_p']})"),
              ("mark_obs_linear", "dv_obs_step, 4-DOF, Kalman gain, no contact"),
              ("mark_obs_contact", f"dv_obs_step, 4-DOF, Kalman gain, 1 contact, "
                                   f"{c['n_sub']} sub-steps (this input leaves it open)"),
              ("mark_obs_engaged", f"dv_obs_step, the same with the contact engaged every step "
                                   f"(zero gap, both sides): the worst case")]
    for key, label in labels:
        a_, b_ = res["os"][key], res["o2"][key]
        L.append(f"| {label} | {len(a_)} | {statistics.mean(a_):.0f} | {min(a_):.0f} | "
                 f"{max(a_):.0f} | {statistics.mean(b_):.0f} | {min(b_):.0f} | {max(b_):.0f} | "
                 f"{640 * statistics.mean(b_):.3g} |")
    per_sample = {v: n * (statistics.mean(res[v]["mark_chan"]) + statistics.mean(res[v]["mark_ar"]))
                  + max(res[v]["mark_obs_engaged"]) for v in ("os", "o2")}
    L.append(f"\nWhole typical set per sample, for budgeting ({n} x (dv_chan_update + "
             f"AR({c['ar_p']})) + one observer step with the contact engaged, its max): "
             f"{per_sample['os']:.0f} instructions at -Os, "
             f"{per_sample['o2']:.0f} at -O2; at 640 Hz that is "
             f"{640 * per_sample['o2'] / 1e6:.2f} M instructions/s (-O2), at 2560 Hz "
             f"{2560 * per_sample['o2'] / 1e6:.2f} M/s. Call overhead subtracted: "
             f"{res['os']['_cal']:.0f} (-Os), {res['o2']['_cal']:.0f} (-O2) instructions. "
             f"The max of dv_chan_update is the sample that closes a record (every statistic and "
             f"temporal moment of the record is finalised there).\n")
    Path(a.out).write_text("\n".join(L) + "\n")
    if not a.no_readme:
        readme_table(budget, per_sample)
    print("\n".join(L))


def readme_table(b, per_sample):
    """The summary table in README.md, between its m4-budget markers."""
    readme = ROOT / "README.md"
    text = readme.read_text()
    start, end = "<!-- m4-budget:start -->", "<!-- m4-budget:end -->"
    if start not in text or end not in text:
        sys.exit("README.md has no m4-budget markers")
    c = CFG
    rows = [
        "| typical set (tests/m4/m4_typical.c) | measured | target |",
        "|---|---:|---:|",
        f"| flash, library + runtime, -Os | {kib(b['flash_os'])} KiB | 24 KiB |",
        f"| flash, library + runtime, -O2 | {kib(b['flash_o2'])} KiB | |",
        f"| RAM per channel (all features, window {c['win']}, {c['n_seg']} x {c['seg_len']} "
        f"segments, AR({c['ar_p']})) | {b['per_ch']} B | |",
        f"| RAM, observer (4-DOF, 1 contact, Kalman gain) | {kib(b['obs'])} KiB | |",
        f"| RAM, whole set ({b['n']} channels + observer), persistent | {kib(b['total'])} KiB "
        f"| 8 KiB |",
        f"| RAM, init-time transient (model build storage + shared scratch) | "
        f"{kib(b['scratch'])} KiB | |",
        f"| instructions per sample, whole set, contact engaged, -O2 | {per_sample['o2']:.0f} | |",
    ]
    body = "\n".join(rows)
    i, j = text.index(start) + len(start), text.index(end)
    readme.write_text(text[:i] + "\n" + body + "\n" + text[j:])


if __name__ == "__main__":
    main()
