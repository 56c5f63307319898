"""`dynval run`: the firmware loop, the logger and the replay of a test, on a real vcan bus
with the firmware_sim program, or in-process: the same loop (firmware_sim/sim_core.c, built
into this package as libdv_simcore-f64) driven by a thread over python-can's virtual bus.

Barrier: after the replay, DV_CTRL STATUS is sent; the firmware handles frames in order, so
once its DV_STATUS answer is logged every result frame before it has been logged too (on the
real bus, followed by a short quiet period to catch a heartbeat racing the answer)."""
from __future__ import annotations

import json
import logging
import re
import select
import signal
import socket
import subprocess
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dynval import __version__, _core, bus
from dynval.bus import ReplayResult
from dynval.cli_common import stop_point
from dynval.contract import IR_COUNTERS, const, named
from dynval.errors import ConfigError, DynvalError
from dynval.io.recording import Recording
from dynval.mcap_log import AsyncLog, McapLog, log_bus
from dynval.topics import T_FEATURES, T_RESID

log = logging.getLogger(__name__)

MAX_CHAN, N_MODEL = const("SIM_MAX_CHAN"), const("SIM_N_MODEL")
N_INPUT, MAX_OUT = const("SIM_N_INPUT"), const("SIM_CORE_MAX_OUT")
#: the observer's model parameters: SIM_MODEL_* offsets (n_dof, mass, k, zeta, q, r, ...)
MODEL = named("SIM_MODEL_")
F32_MAX = 3.4028234663852886e38  # the largest finite IEEE-754 binary32
MAX_DOF = MODEL["k"] - MODEL["mass"]  # masses of DOF 1..n fill the slots before the k's


@dataclass
class FirmwareConfig:
    """What the firmware is told before a test (holding registers / command line)."""

    n_chan: int = 5
    fs_hz: int = 640
    win_len: int = 256
    seg_len: int = 64
    n_seg: int = 64
    ar_order: int = 0
    resid_decim: int = 1
    force_chan: int = 0
    heartbeat_ms: int = 1000
    model: list[float] = field(default_factory=list)  # SIM_MODEL_* order; [] = observer off

    def args(self) -> list[str]:
        """firmware_sim command-line options."""
        a = ["-c", str(self.n_chan), "-f", str(self.fs_hz), "-w", str(self.win_len),
             "-s", str(self.seg_len), "-n", str(self.n_seg), "-A", str(self.ar_order),
             "-d", str(self.resid_decim), "-F", str(self.force_chan),
             "-H", str(self.heartbeat_ms)]
        if self.model:
            a += ["-m", ",".join(repr(float(v)) for v in self.model)]
        return a


def model_params(model: Any, rec: Recording, q: float = 0.0, r: float = 0.0) -> list[float]:
    """The firmware observer's parameters (SIM_MODEL_*) from a dynval Model: a chain with
    modal damping loaded at its input DOF; the firmware measures every non-force channel, in
    order, as the acceleration of DOF 1, 2, ... — so the test's outputs must be exactly that.
    The input hold is the model's: `foh` stays linear; `cubic` and the offline default
    `bandlimited` (which firmware cannot do: it needs the whole record) use the cubic hold,
    which reaches the same noise floor on band-limited forces one sample later."""
    n = model.n_dof
    if n > MAX_DOF:
        raise ConfigError(f"{model.source}: the firmware observer takes at most {MAX_DOF} DOF, "
                          f"not {n}")
    if model.damping.type != "modal" or len(model.damping.zeta) != n:
        raise ConfigError(f"{model.source}: the firmware observer needs modal damping with "
                          f"{n} ratios")
    if model.elements:
        log.warning("%s: the firmware observer is linear; %d element(s) ignored",
                    model.source, len(model.elements))
    if model.input.kind != "force":
        raise ConfigError(f"{model.source}: the firmware observer takes a force input")
    _check_channels(model, rec)
    p = [0.0] * (MODEL["hold"] + 1)
    p[MODEL["n_dof"]] = float(n)
    for i in range(n):
        p[MODEL["mass"] + i] = float(model.masses_kg[i])
        p[MODEL["k"] + i] = float(model.stiffness_n_per_m[i])
        p[MODEL["zeta"] + i] = float(model.damping.zeta[i])
    p[MODEL["q"]], p[MODEL["r"]] = q, r
    p[MODEL["input_dof"]] = float(model.input.dof - 1)
    p[MODEL["hold"]] = 0.0 if model.interpolation == "foh" else 1.0
    _check_binary32(model, p)
    return p


def _check_channels(model: Any, rec: Recording) -> None:
    """The model's declared input is the test's force channel, and every output channel the
    firmware measures (in order, as the acceleration of DOF 1, 2, ...) is declared so by the
    model: the checks simulate and residual make, for the firmware's reading of the test."""
    from dynval.model.residual import input_channel

    where = rec.source or rec.name
    ins = [c.name for c in rec.channels if c.role == "input"]
    inp = input_channel(model, rec)
    if not ins or inp != ins[0]:
        raise ConfigError(f"{where}: the model {model.source} drives DOF {model.input.dof} from "
                          f"'{inp}', the firmware would take '{ins[0] if ins else '?'}' (the "
                          "test's first input channel; use --channel-map)")
    outs = [c.name for c in rec.channels if c.role == "output"]
    for j, name in enumerate(outs, 1):
        o = model.outputs.get(name)
        if o is None or o.kind != "acc" or o.index != j:
            have = "not an output" if o is None else f"{o.kind} of DOF {o.index}"
            raise ConfigError(f"{where}: the firmware reads channel '{name}' as the acceleration "
                              f"of DOF {j}; the model {model.source} declares it {have} (use "
                              "--channel-map to choose and order the channels)")


def _check_binary32(model: Any, p: list[float]) -> None:
    """The firmware holds its parameters as binary32: each must be finite there."""
    big = [i for i, v in enumerate(p) if not abs(v) <= F32_MAX]
    if big:
        names = {MODEL["mass"]: "masses_kg", MODEL["k"]: "stiffness_n_per_m",
                 MODEL["zeta"]: "damping.zeta"}
        i = big[0]
        base = max((b for b in names if b <= i), default=None)
        n = model.n_dof
        field = (f"{names[base]}[{i - base}]" if base is not None and i - base < n
                 else f"firmware parameter {i} (--obs-q/--obs-r?)")
        raise ConfigError(f"{model.source}: field '{field}': {p[i]:.3g} is beyond the "
                          f"firmware's binary32 range (|x| <= {F32_MAX:.4g})")


def firmware_config(rec: Recording, model: Any = None, **kw: Any) -> FirmwareConfig:
    ins = [i for i, c in enumerate(rec.channels) if c.role == "input"]
    q = float(kw.pop("obs_q", 0.0))
    r = float(kw.pop("obs_r", 0.0))
    cfg = FirmwareConfig(n_chan=len(rec.channels), fs_hz=int(round(rec.fs_hz)),
                         force_chan=ins[0] if ins else 0, **kw)
    if model is not None:
        if not ins:
            raise ConfigError(f"{rec.name}: a model needs an input (force) channel")
        cfg.model = model_params(model, rec, q, r)
    return cfg


# ---- in-process firmware ---------------------------------------------------------------------
class SimCore:
    """firmware_sim's loop (sim_core.c) in this process, through the binding (_core.sim_lib)."""

    def __init__(self, cfg: FirmwareConfig) -> None:
        ffi: Any = _core.ffi
        lib: Any = _core.sim_lib
        self.ffi, self.lib = ffi, lib
        c = ffi.new("struct sim_config *")
        lib.sim_config_default(c)
        c.n_chan, c.win_len, c.seg_len, c.n_seg = cfg.n_chan, cfg.win_len, cfg.seg_len, cfg.n_seg
        c.ar_order, c.resid_decim, c.force_chan = cfg.ar_order, cfg.resid_decim, cfg.force_chan
        c.heartbeat_ms = cfg.heartbeat_ms
        for ch in range(MAX_CHAN):
            c.fs_hz[ch] = cfg.fs_hz
        params = [float(v) for v in cfg.model] + [0.0] * (N_MODEL - len(cfg.model))
        for i, pv in enumerate(params):
            c.model[i] = pv
        self.core: Any = lib.sim_core_new(c)
        if self.core == ffi.NULL:
            raise ConfigError(f"the firmware refused the configuration {cfg}")
        self._in: Any = ffi.new("dv_can_frame_t *")
        self._out: Any = ffi.new("dv_can_frame_t[]", MAX_OUT)
        self._ir: Any = ffi.new("uint16_t[]", N_INPUT)

    def handle(self, can_id: int, data: bytes) -> list[tuple[int, bytes]]:
        self._in.id = can_id
        self._in.dlc = min(len(data), 8)
        self.ffi.memmove(self._in.data, data[:8], min(len(data), 8))
        n = self.lib.sim_core_handle(self.core, self._in, self._out)
        return [(int(self._out[i].id), bytes(self.ffi.buffer(self._out[i].data, 8)))
                for i in range(n)]

    def tick(self, now_ns: int) -> list[tuple[int, bytes]]:
        n = self.lib.sim_core_tick(self.core, now_ns, self._out)
        return [(int(self._out[i].id), bytes(self.ffi.buffer(self._out[i].data, 8)))
                for i in range(n)]

    def counters(self) -> dict[str, int]:
        self.lib.sim_core_input_regs(self.core, self._ir)
        ir = self._ir
        return {k: (ir[a] << 16) | ir[a + 1] for k, a in IR_COUNTERS.items()}

    def close(self) -> None:
        if self.core is not None:
            self.lib.sim_core_delete(self.core)
            self.core = None


def _is_status_request(m: Any) -> bool:
    return (m.arbitration_id == bus.ID_CTRL and not m.is_extended_id and len(m.data) > 0
            and m.data[0] == bus.CTRL_STATUS)


class InProcessFirmware:
    """A thread running SimCore on a python-can bus (frames in, result frames out)."""

    def __init__(self, cfg: FirmwareConfig, interface: str, channel: str) -> None:
        import can

        self.core = SimCore(cfg)
        self.bus = bus.open_bus(interface, channel)
        self._can = can
        self._stop = threading.Event()
        self.error: BaseException | None = None
        # set once the status request is handled: every frame before it has been handled
        # and its results are on the bus (the virtual bus queues a sent frame at once)
        self.answered = threading.Event()
        self.thread = threading.Thread(target=self._run, name="dv-firmware", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        can = self._can
        try:
            while not self._stop.is_set():
                m = self.bus.recv(timeout=0.05)
                outs = [] if m is None else self.core.handle(m.arbitration_id | (
                    bus.EFF_FLAG if m.is_extended_id else 0), bytes(m.data))
                outs += self.core.tick(time.monotonic_ns())
                for cid, data in outs:
                    self.bus.send(can.Message(arbitration_id=cid, data=data,
                                              is_extended_id=False))
                if m is not None and _is_status_request(m):
                    self.answered.set()
        except BaseException as exc:  # reported by stop()
            self.error = exc

    def stop(self) -> dict[str, int]:
        self._stop.set()
        self.thread.join(timeout=10)
        counters = self.core.counters()
        self.core.close()
        self.bus.shutdown()
        if self.error is not None:
            raise DynvalError(f"in-process firmware failed: {self.error}") from self.error
        return counters


# ---- the firmware_sim program ------------------------------------------------------------------
def find_firmware(explicit: str | None = None) -> Path | None:
    """$DV_FIRMWARE_SIM, an explicit path, firmware_sim on PATH, or a build of the repository
    this command runs in (build/*/firmware_sim/firmware_sim)."""
    return _core.find_program("firmware_sim", "DV_FIRMWARE_SIM", explicit)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class FirmwareProcess:
    """firmware_sim on a SocketCAN interface, as a child process (SIGTERM to stop)."""

    def __init__(self, exe: Path, cfg: FirmwareConfig, iface: str, log_dir: Path) -> None:
        self.errpath = log_dir / "firmware_sim.stderr"
        self.errf = open(self.errpath, "w+")  # noqa: SIM115
        cmd = [str(exe), "-i", iface, "-p", str(_free_port()), "-v", *cfg.args()]
        log.debug("starting %s", " ".join(cmd))
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=self.errf, text=True)
        deadline = time.monotonic() + 30
        line = ""
        assert self.proc.stdout is not None
        while time.monotonic() < deadline and self.proc.poll() is None:
            r, _, _ = select.select([self.proc.stdout], [], [], 0.2)
            if r:
                line = self.proc.stdout.readline()
                if line.startswith("firmware_sim ready") or line == "":
                    break
        if not line.startswith("firmware_sim ready"):
            self.proc.kill()
            self.proc.wait()
            raise DynvalError(f"firmware_sim did not start (exit {self.proc.returncode}): "
                              f"{self.errpath.read_text().strip()}")

    def stop(self) -> dict[str, int]:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.errf.close()
        if self.proc.returncode not in (0, -signal.SIGTERM):
            log.warning("firmware_sim exit %s: %s", self.proc.returncode,
                        self.errpath.read_text().strip())
        return {}


def have_vcan(iface: str = "vcan0") -> bool:
    """socket(AF_CAN) works on this kernel and the interface exists."""
    if not Path(f"/sys/class/net/{iface}").exists():
        return False
    try:
        s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    except (OSError, AttributeError):
        return False
    s.close()
    return True


@dataclass
class BusChoice:
    interface: str  # socketcan | virtual
    channel: str
    firmware: str  # "firmware_sim <path>" | "in-process libdv_simcore"
    exe: Path | None = None


def choose_bus(mode: str, channel: str = "vcan0", firmware: str | None = None) -> BusChoice:
    """auto: vcan + firmware_sim when the kernel has vcan and the program is found, else the
    in-process loop over the virtual bus."""
    if mode in ("auto", "socketcan"):
        exe = find_firmware(firmware)
        ok = have_vcan(channel)
        if ok and exe is not None:
            return BusChoice("socketcan", channel, f"firmware_sim {exe}", exe)
        if mode == "socketcan":
            why = (f"no {channel} (or no AF_CAN in this kernel)" if not ok
                   else "firmware_sim not found (build it: cmake -DDV_BUILD_SIM=ON, or set "
                   "DV_FIRMWARE_SIM)")
            raise bus.BusError(f"--bus socketcan: {why}")
        log.info("--bus auto: %s; using the in-process firmware loop on the virtual bus",
                 f"no {channel}" if not ok else "firmware_sim not found")
    elif mode != "virtual":
        raise ConfigError(f"unknown --bus {mode!r} (auto, socketcan, virtual)")
    return BusChoice("virtual", f"dynval-{uuid.uuid4().hex[:8]}", "in-process libdv_simcore")


# ---- one test ------------------------------------------------------------------------------------
@dataclass
class RunResult:
    test: str
    mcap: Path
    bus: str
    firmware: str
    replay: ReplayResult
    log_summary: dict[str, Any]
    counters: dict[str, int]
    features: int = 0
    residuals: int = 0
    resid_rms: dict[str, float] = field(default_factory=dict)


def run_test(rec: Recording, out: Path, choice: BusChoice, *, model: Any = None,
             model_meta: dict[str, Any] | None = None, speed: float = 1.0, asap: bool = False,
             fw_kw: dict[str, Any] | None = None, record_id: int = 1,
             on_progress: Callable[[int], None] | None = None,
             stop: threading.Event | None = None) -> RunResult:
    """Firmware + logger + replay of one recording; leaves out (an MCAP). `stop` (set by a
    stop signal, cli_common.stop_signals) ends the run between batches with
    KeyboardInterrupt, after the log is finished."""
    stop = stop or threading.Event()
    import can

    cfg = firmware_config(rec, model, **(fw_kw or {}))
    plan = bus.make_plan(rec, record_id)
    meta = recording_meta(rec, plan)
    meta["model"] = model_meta or {}
    meta["firmware_config"] = json.loads(json.dumps(vars(cfg)))
    meta["bus"] = f"{choice.interface}:{choice.channel} ({choice.firmware})"
    names = [c.name for c in rec.channels]
    out.parent.mkdir(parents=True, exist_ok=True)
    fw: InProcessFirmware | FirmwareProcess
    if choice.interface == "virtual":
        fw = InProcessFirmware(cfg, "virtual", choice.channel)
    else:
        assert choice.exe is not None
        fw = FirmwareProcess(choice.exe, cfg, choice.channel, out.parent)
    counters: dict[str, int] = {}
    logger = McapLog(out, meta=meta, channel_names=names)
    try:
        rx = bus.open_bus(choice.interface, choice.channel, receive_own_messages=False)
        tx = bus.open_bus(choice.interface, choice.channel, receive_own_messages=False)
        done = threading.Event()
        state = _LoggerState()
        t = threading.Thread(target=_logger_loop, args=(rx, logger, done, state),
                             name="dv-logger", daemon=True)
        t.start()
        try:
            res = bus.replay(tx, plan, speed=speed, asap=asap, on_progress=on_progress,
                             hold=lambda off_ns: _hold(logger, state, off_ns, stop))
            state.armed = True
            tx.send(can.Message(arbitration_id=bus.ID_CTRL,
                                data=bus.encode_ctrl(bus.CTRL_STATUS, record_id)[1],
                                is_extended_id=False))
            if isinstance(fw, InProcessFirmware):
                # the firmware thread says when it has handled the request (then all its
                # results are queued for the logger): a heartbeat from a thread still behind
                # the replay on a loaded host lost a third of the residuals without a word
                _wait_for_answer(fw.answered, lambda: fw.error is not None
                                 or state.error is not None, stop, rec.name)
            else:
                _wait_for_answer(state.status, lambda: False, stop, rec.name)
                while time.monotonic() - state.last_rx < QUIET_S:  # a heartbeat may race it
                    stop_point(stop)
                    time.sleep(0.05)
        finally:
            done.set()
            t.join(timeout=30)
            rx.shutdown()
            tx.shutdown()
        if state.error is not None:
            raise state.error
    finally:
        counters = fw.stop()
        summary = logger.close()
    feats = logger.counts.get(T_FEATURES, 0)
    resid = logger.counts.get(T_RESID, 0)
    return RunResult(rec.name, out, f"{choice.interface}:{choice.channel}", choice.firmware,
                     res, summary, counters, feats, resid)


QUIET_S = 0.3  # no frame for this long after the status answer: the firmware is done
MAX_BACKLOG_S = 0.5  # data on the bus not yet logged; with the chunk timer: <= 1 s lost on a kill
STATUS_WAIT_S = 120.0  # the firmware's answer to the status request after a replay
STALL_S = 5.0  # a logger without progress for this long is not waited for (it reports why)


def _wait_for_answer(answered: threading.Event, failed: Callable[[], bool],
                     stop: threading.Event, name: str) -> None:
    """Until ``answered`` (the firmware's answer to the status request) is set, ``failed()``
    (a thread died) or STATUS_WAIT_S pass, this last with a warning."""
    t_end = time.monotonic() + STATUS_WAIT_S
    while not answered.wait(timeout=0.05):
        stop_point(stop)
        if time.monotonic() > t_end or failed():
            log.warning("%s: no DV_STATUS answer within %.0f s; results may be incomplete",
                        name, STATUS_WAIT_S)
            return


def _hold(logger: McapLog, st: _LoggerState, off_ns: int, stop: threading.Event) -> None:
    """Keep the replay at most MAX_BACKLOG_S of data ahead of the logger (any --speed,
    --asap): frames waiting in memory are lost on a kill. A logger that makes no progress
    for STALL_S is not waited for again (no hang; the run reports what was logged)."""
    stop_point(stop)
    last, t_last = logger.frames_logged, time.monotonic()
    while not st.stalled and st.error is None and off_ns / 1e9 - logger.logged_s > MAX_BACKLOG_S:
        stop_point(stop)
        if logger.frames_logged != last:
            last, t_last = logger.frames_logged, time.monotonic()
        elif time.monotonic() - t_last > STALL_S:
            st.stalled = True
            log.warning("the logger made no progress for %.0f s; replaying without waiting "
                        "for it", STALL_S)
        time.sleep(0.001)


class _LoggerState:
    def __init__(self) -> None:
        self.armed = False
        self.status = threading.Event()
        self.last_rx = time.monotonic()
        self.error: Exception | None = None  # what stopped the logger thread (a full disk)
        self.stalled = False  # the logger fell behind without progress (see _hold)
        self.dropped = 0  # frames the writer could not take (counted in the log's events)


def _logger_loop(rx: Any, logger: McapLog, stop: threading.Event, st: _LoggerState) -> None:
    """Read frames until stop and hand them to the writer thread (AsyncLog: the reader never
    waits for the file). An error (a write to a full disk) ends the loop and is handed to
    run_test through st.error, which raises it in the main thread (no waiting for a status
    that will not be logged, no traceback from a dying thread)."""
    w: AsyncLog | None = None
    try:
        w = AsyncLog(logger)
        while True:
            # after stop, what is already on the bus is read before the log closes
            m = rx.recv(timeout=0.0 if stop.is_set() else 0.05)
            if m is None:
                if stop.is_set():
                    break
                w.hand_off()
                continue
            st.last_rx = time.monotonic()
            w.put(m)
            if st.armed and m.arbitration_id == bus.ID_STATUS and not m.is_extended_id:
                st.status.set()
        w.close()
        st.dropped = w.dropped
    except Exception as exc:  # noqa: BLE001 - re-raised in the main thread by run_test
        st.error = exc
        st.status.set()
        if w is not None and w.thread.is_alive():
            w.close_quietly()


def recording_meta(rec: Recording, plan: bus.Plan | None = None) -> dict[str, Any]:
    """The 'dynval' metadata record of a test's MCAP."""
    return {"test": rec.name, "source": str(rec.source or ""), "source_sha256": rec.sha256,
            "fs_hz": repr(float(rec.fs_hz)), "n_samples": str(rec.n_samples),
            "channel_map": [{"channel": i, "name": c.name, "unit": c.unit, "role": c.role,
                             "dof": c.dof, "scale": c.scale,
                             "lsb": plan.lsb[i] if plan else None}
                            for i, c in enumerate(rec.channels)],
            "units": {c.name: c.unit for c in rec.channels},
            "roles": {c.name: c.role for c in rec.channels},
            "reader_warnings": len(rec.warnings), "software": f"dynval {__version__}",
            "record_id": plan.record_id if plan else 0}


def safe_name(s: str) -> str:
    return re.sub(r"[^0-9A-Za-z._-]+", "_", s) or "test"


__all__ = ["BusChoice", "FirmwareConfig", "InProcessFirmware", "RunResult", "SimCore",
           "choose_bus", "find_firmware", "firmware_config", "have_vcan", "log_bus",
           "model_params", "run_test"]
