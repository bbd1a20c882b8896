#!/usr/bin/env python3
"""A hostile campaign over every clutterseg binary and the Python module.

    tools/hostile_campaign.py BUILD_DIR [--only REGEX] [--keep] [--list]

BUILD_DIR is a build tree (build/release). The script makes its own inputs with
clutterseg-synth and by damaging copies of them (no other data), runs each case as a process
and checks:

- the exit code is documented (0..5; src/core/exit_codes.h, docs/daemon.md) and is the one
  the case expects; a case that fails must print a message with the words that name the
  problem (the file, key or field);
- the counts of the daemon's final line agree with what reached its file:// LCM log
  (objects_t, label_image_t and the last status_t counted in the file), and captured =
  processed + dropped + discarded;
- a SIGTERM ends the process within 2 s, also with two busy loops loading both cores;
- the peak RSS of the process (wait4) stays under the case's bound;
- nothing hangs (every process has a time limit).

It prints one line per case (case, expected, got, verdict) and a summary per binary, and exits
1 when any case fails. Standard library only; the generated LCM message classes of the build
tree (BUILD_DIR/python) decode the log.
"""

import argparse
import dataclasses
import importlib
import json
import os
import re
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from typing import Callable, List, Optional

DOCUMENTED_EXIT_CODES = {0, 1, 2, 3, 4, 5}
# The interpreter the module is built for (docs/python.md), whatever python3 comes first.
PYTHON = "/usr/bin/python3" if os.access("/usr/bin/python3", os.X_OK) else sys.executable
SIGTERM_LIMIT_S = 2.0
SYNC = 0xEDA1DA01


# ---- processes ---------------------------------------------------------------------------


@dataclasses.dataclass
class Result:
    rc: int = -1              # exit code; 128 + signal when killed by one; -1 on a hang
    out: str = ""
    err: str = ""
    max_rss_mib: float = 0.0
    seconds: float = 0.0
    hung: bool = False
    stop_s: Optional[float] = None  # SIGTERM to exit


class Load:
    """Two busy loops (one per core) for the duration of a `with` block."""

    def __enter__(self):
        self.procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
                      for _ in range(max(2, os.cpu_count() or 2))]
        time.sleep(0.3)
        return self

    def __exit__(self, *exc):
        for p in self.procs:
            p.kill()
        for p in self.procs:
            p.wait()


def wait_child(proc, deadline):
    """Waits for `proc` until `deadline` (monotonic); returns (status, rusage) or None."""
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid == proc.pid:
            proc.returncode = status  # keeps Popen from waiting again
            return status, usage
        if time.monotonic() >= deadline:
            return None
        time.sleep(0.005)


def run(argv, timeout=60.0, env=None, stop=None, cwd=None, stdin_data=None):
    """Runs argv. `stop`: a callable(proc, elapsed_s) -> bool that, once true, sends SIGTERM
    (then the time to the exit is measured)."""
    res = Result()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        start = time.monotonic()
        proc = subprocess.Popen(argv, stdout=out, stderr=err, env=env, cwd=cwd,
                                stdin=subprocess.PIPE if stdin_data is not None
                                else subprocess.DEVNULL)
        if stdin_data is not None:
            try:
                proc.stdin.write(stdin_data)
            except BrokenPipeError:
                pass
            proc.stdin.close()
        got = None
        if stop is not None:
            while True:
                pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
                if pid == proc.pid:
                    proc.returncode = status
                    got = (status, usage)
                    break
                if stop(proc, time.monotonic() - start):
                    t0 = time.monotonic()
                    os.kill(proc.pid, signal.SIGTERM)
                    got = wait_child(proc, t0 + 30)
                    if got is not None:
                        res.stop_s = time.monotonic() - t0
                    break
                if time.monotonic() - start > timeout:
                    break
                time.sleep(0.01)
        else:
            got = wait_child(proc, start + timeout)
        if got is None:
            res.hung = True
            proc.kill()
            got = wait_child(proc, time.monotonic() + 10)
        res.seconds = time.monotonic() - start
        if got is not None:
            status, usage = got
            if os.WIFEXITED(status):
                res.rc = os.WEXITSTATUS(status)
            elif os.WIFSIGNALED(status):
                res.rc = 128 + os.WTERMSIG(status)
            res.max_rss_mib = usage.ru_maxrss / 1024.0
        if res.hung:
            res.rc = -1
        out.seek(0)
        err.seek(0)
        res.out = out.read().decode(errors="replace")
        res.err = err.read().decode(errors="replace")
    return res


# ---- LCM logs ----------------------------------------------------------------------------


def read_log(path):
    """The whole events of an LCM log: [(channel, data)], and whether every byte was read."""
    events = []
    with open(path, "rb") as f:
        data = f.read()
    i = 0
    while i + 28 <= len(data):
        sync, _, _, clen, dlen = struct.unpack(">IqqII", data[i:i + 28])
        if sync != SYNC or i + 28 + clen + dlen > len(data):
            break
        channel = data[i + 28:i + 28 + clen].decode(errors="replace")
        events.append((channel, data[i + 28 + clen:i + 28 + clen + dlen]))
        i += 28 + clen + dlen
    return events, i == len(data)


def write_log(path, events):
    with open(path, "wb") as f:
        for n, (channel, data) in enumerate(events):
            c = channel.encode()
            f.write(struct.pack(">IqqII", SYNC, n, 1000 * n, len(c), len(data)) + c + data)


DONE_RE = re.compile(r"done: (\d+) captured, (\d+) processed, (\d+) published, (\d+) dropped, "
                     r"(\d+) publish failures(?:, (\d+) discarded at the stop)?")


class Campaign:
    def __init__(self, build, work, keep):
        self.build = os.path.abspath(build)
        self.work = work
        self.keep = keep
        self.exe = {
            "clutterseg": f"{self.build}/src/daemon/clutterseg",
            "segment": f"{self.build}/tools/clutterseg-segment",
            "eval": f"{self.build}/tools/clutterseg-eval",
            "listen": f"{self.build}/tools/clutterseg-listen",
            "record": f"{self.build}/tools/clutterseg-record",
            "regress": f"{self.build}/tools/clutterseg-regress",
            "synth": f"{self.build}/tools/clutterseg-synth",
            "bench": f"{self.build}/tools/clutterseg-bench",
        }
        for name, path in self.exe.items():
            if not os.access(path, os.X_OK):
                sys.exit(f"hostile_campaign: {path} is missing: build the target {name}")
        self.python_dir = f"{self.build}/python"
        sys.path.insert(0, self.python_dir)
        try:
            self.status_t = importlib.import_module("clutterseg.status_t").status_t
            self.objects_t = importlib.import_module("clutterseg.objects_t").objects_t
        except ImportError as e:
            sys.exit(f"hostile_campaign: cannot import the LCM types from {self.python_dir}: {e}")
        self.env = dict(os.environ)
        self.env["RUNTIME_DIRECTORY"] = os.path.join(work, "run")  # the daemons' lock directory
        os.makedirs(self.env["RUNTIME_DIRECTORY"], exist_ok=True)
        self.env["PYTHONPATH"] = self.python_dir
        self.results = []

    def p(self, *parts):
        return os.path.join(self.work, *parts)

    # ---- inputs ----------------------------------------------------------------------

    def make_inputs(self):
        synth = self.exe["synth"]
        steps = [
            [synth, "--oni", self.p("small.oni"), "--count", "1", "--sequence", "--frames", "10",
             "--width", "160", "--height", "120", "--seed", "3"],
            [synth, "--oni", self.p("room.oni"), "--count", "1", "--sequence", "--frames", "30",
             "--seed", "4"],
            [synth, "--out", self.p("scenes"), "--count", "3", "--seed", "5", "--width", "160",
             "--height", "120", "--png"],
        ]
        for argv in steps:
            r = run(argv, timeout=300)
            if r.rc != 0:
                sys.exit(f"hostile_campaign: {' '.join(argv)} failed ({r.rc}): {r.err}")
        scenes = sorted(f for f in os.listdir(self.p("scenes")) if f.endswith(".pcd"))
        self.pcd = self.p("scenes", scenes[0])
        pngs = sorted(f for f in os.listdir(self.p("scenes")) if "depth" in f and
                      f.endswith(".png"))
        self.depth_png = self.p("scenes", pngs[0]) if pngs else None
        os.makedirs(self.p("garbage_pcds"), exist_ok=True)
        for i in range(3):
            with open(self.p("garbage_pcds", f"f{i}.pcd"), "wb") as f:
                f.write(os.urandom(2000))
        os.makedirs(self.p("dpng"), exist_ok=True)
        for f in os.listdir(self.p("scenes")):
            if f.endswith("_depth.png") or f == "intrinsics.json":
                shutil.copy(self.p("scenes", f), self.p("dpng", f))
        os.makedirs(self.p("pcds"), exist_ok=True)
        for f in scenes:
            shutil.copy(self.p("scenes", f), self.p("pcds", f))
        # A reference log of the small recording, and a 430 MB log (an hour's soak) built by
        # repeating it, to be appended to.
        r = run([self.exe["clutterseg"], "--source", self.p("small.oni"), "--speed", "max",
                 "--lcm-url", f"file://{self.p('ref.lcmlog')}?mode=w"], env=self.env)
        if r.rc != 0:
            sys.exit(f"hostile_campaign: the reference run failed ({r.rc}): {r.err}")
        shutil.copy(self.p("ref.lcmlog"), self.p("ref2.lcmlog"))
        events, _ = read_log(self.p("ref.lcmlog"))
        self.ref_events = events
        with open(self.p("ref.lcmlog"), "rb") as f:
            ref = f.read()
        with open(self.p("big.lcmlog.src"), "wb") as f:
            for _ in range(max(1, (430 << 20) // max(1, len(ref)))):
                f.write(ref)

    def write(self, name, text, mode="w"):
        path = self.p(name)
        with open(path, mode) as f:
            f.write(text)
        return path

    def damaged(self, name, src, fn):
        with open(src, "rb") as f:
            data = bytearray(f.read())
        data = fn(data)
        path = self.p(name)
        with open(path, "wb") as f:
            f.write(data)
        return path

    # ---- checks ----------------------------------------------------------------------

    def check_log(self, res, log, problems):
        """The daemon's final line against its file:// log."""
        m = None
        for m in DONE_RE.finditer(res.err):
            pass
        if m is None:
            problems.append("no final 'done:' line")
            return
        captured, processed, published, dropped, failures = (int(m.group(i)) for i in range(1, 6))
        discarded = int(m.group(6) or 0)
        if captured != processed + dropped + discarded:
            problems.append(f"captured {captured} != processed {processed} + dropped {dropped} "
                            f"+ discarded {discarded}")
        if not os.path.exists(log):
            problems.append(f"no log {log}")
            return
        events, whole = read_log(log)
        if not whole:
            problems.append("the log is not whole")
        objects = [d for c, d in events if c == "CLUTTERSEG_OBJECTS"]
        labels = sum(1 for c, _ in events if c == "CLUTTERSEG_LABELS")
        statuses = [d for c, d in events if c == "CLUTTERSEG_STATUS"]
        if len(objects) != published:
            problems.append(f"'{published} published' but the log holds {len(objects)} objects_t")
        if labels not in (0, len(objects)):
            problems.append(f"{labels} label_image_t for {len(objects)} objects_t")
        if statuses:
            last = self.status_t.decode(statuses[-1])
            if last.frames_published != published:
                problems.append(f"the last status_t says {last.frames_published} published, the "
                                f"final line {published}")
            if last.frames_captured != captured:
                problems.append(f"the last status_t says {last.frames_captured} captured, the "
                                f"final line {captured}")
        seqs = [self.objects_t.decode(d).frame_seq for d in objects]
        if any(b <= a for a, b in zip(seqs, seqs[1:])):
            problems.append("frame_seq goes back or repeats in the log")
        res.log_objects = len(objects)
        res.log_statuses = statuses
        res.log_seqs = seqs
        res.objects_msgs = objects

    # ---- running a case --------------------------------------------------------------

    def case(self, name, binary, argv, expect=0, words=(), log=None, stop=None, load=False,
             rss_mib=1024.0, timeout=90.0, check: Optional[Callable] = None, env=None,
             stdin_data=None, python=False):
        problems = []
        cmd = [PYTHON, "-c", argv] if python else [self.exe[binary]] + argv
        if load:
            with Load():
                res = run(cmd, timeout=timeout, env=env or self.env, stop=stop,
                          stdin_data=stdin_data)
        else:
            res = run(cmd, timeout=timeout, env=env or self.env, stop=stop,
                      stdin_data=stdin_data)
        expects = expect if isinstance(expect, (set, frozenset, tuple, list)) else {expect}
        if res.hung:
            problems.append(f"hung (killed after {timeout:.0f} s)")
        elif res.rc not in DOCUMENTED_EXIT_CODES:
            problems.append(f"exit {res.rc} is not a documented exit code")
        if not res.hung and res.rc not in expects:
            problems.append(f"exit {res.rc}, expected {sorted(expects)}")
        text = (res.out + res.err).lower()
        for w in words:
            if w.lower() not in text:
                problems.append(f"the message does not say '{w}'")
        if stop is not None:
            if res.stop_s is None:
                problems.append("no SIGTERM was sent (it ended before)")
            elif res.stop_s > SIGTERM_LIMIT_S:
                problems.append(f"SIGTERM to exit took {res.stop_s:.2f} s")
        if res.max_rss_mib > rss_mib:
            problems.append(f"peak RSS {res.max_rss_mib:.0f} MiB > {rss_mib:.0f} MiB")
        if log is not None and not res.hung:
            self.check_log(res, log, problems)
        if check is not None and not problems:
            try:
                more = check(res)
                if more:
                    problems.append(more)
            except Exception as e:  # a check that cannot run is a failure of the case
                problems.append(f"check failed: {type(e).__name__}: {e}")
        got = "hang" if res.hung else str(res.rc)
        if res.stop_s is not None:
            got += f" ({res.stop_s:.2f} s after SIGTERM{' under load' if load else ''})"
        self.results.append(dict(case=name, binary=binary, expected=sorted(expects), got=got,
                                 ok=not problems, problems=problems, rss=res.max_rss_mib,
                                 stop_s=res.stop_s, load=load))
        verdict = "pass" if not problems else "FAIL: " + "; ".join(problems)
        print(f"{name:<44} {'/'.join(map(str, sorted(expects))):<8} {got:<36} {verdict}",
              flush=True)
        if problems and os.environ.get("HOSTILE_VERBOSE"):
            print("    stderr: " + res.err[-1500:].replace("\n", "\n    "))
        return res


def after_events(log, n):
    """A stop condition: the log holds n events."""
    def cond(proc, elapsed):
        try:
            return os.path.getsize(log) > 0 and len(read_log(log)[0]) >= n
        except OSError:
            return False
    return cond


def after_seconds(s):
    return lambda proc, elapsed: elapsed >= s


# ---- the cases ---------------------------------------------------------------------------


def daemon_cases(c: Campaign):
    D = "clutterseg"
    small, room = c.p("small.oni"), c.p("room.oni")

    def url(name, mode="w"):
        return f"file://{c.p(name)}?mode={mode}"

    def replay(src, log, *extra):
        return ["--source", src, "--speed", "max", "--lcm-url", url(log)] + list(extra)

    # --default KEY=VALUE
    cfg_name = c.write("name.yaml", "camera_name: fromfile\n")
    c.case("daemon.default.config-wins", D, ["--config", cfg_name, "--default",
           "camera_name=dflt", "--print-config"], 0, ["camera_name: fromfile"])
    c.case("daemon.default.set-wins", D, ["--default", "camera_name=a", "--set",
           "camera_name=b", "--print-config"], 0, ["camera_name: b"])
    c.case("daemon.default.twice-last-wins", D, ["--default", "camera_name=a", "--default",
           "camera_name=b", "--print-config"], 0, ["camera_name: b"])
    c.case("daemon.default.no-equals", D, ["--default", "camera_name", "--print-config"], 2,
           ["camera_name"])
    c.case("daemon.default.unknown-key", D, ["--default", "camera.nonsense_key=1",
           "--print-config"], 2, ["camera.nonsense_key"])
    c.case("daemon.default.bad-value", D, ["--default", "processing.queue_capacity=-3",
           "--print-config"], 2, ["processing.queue_capacity"])
    c.case("daemon.default.nan", D, ["--default", "segmenter.points.max_depth_m=nan",
           "--print-config"], 2, ["segmenter.points.max_depth_m"])
    c.case("daemon.default.control-character-name", D, ["--default", "camera_name=arm\x01left",
           "--print-config"], 2, ["camera_name", "control character"])
    c.case("daemon.default.realtime-99", D, ["--default", "processing.realtime_priority=99",
           "--print-config"], 2, ["processing.realtime_priority", "99"])
    c.case("daemon.default.empty-name", D, ["--default", "camera_name=", "--print-config"], 2,
           ["camera_name"])
    # configuration files
    c.case("daemon.config.binary-garbage", D, ["--config", c.write("garbage.yaml",
           bytes(range(256)) * 4, "wb"), "--print-config"], 2, ["garbage.yaml"])
    c.case("daemon.config.list-not-map", D, ["--config", c.write("list.yaml", "- a\n- b\n"),
           "--print-config"], 2, ["list.yaml"])
    c.case("daemon.config.missing", D, ["--config", c.p("nope.yaml"), "--print-config"], 2,
           ["nope.yaml"])
    c.case("daemon.config.section-is-scalar", D, ["--config", c.write("scalar.yaml",
           "camera: 5\n"), "--print-config"], 2, ["camera"])
    # intrinsics files (camera.intrinsics_file)
    c.case("daemon.intrinsics.missing", D, replay(small, "i1.lcmlog", "--set",
           f"camera.intrinsics_file={c.p('none.json')}"), 2,
           ["camera.intrinsics_file", "none.json"])
    c.case("daemon.intrinsics.json-negative-fx", D, replay(small, "i2.lcmlog", "--set",
           "camera.intrinsics_file=" + c.write("negfx.json",
           '{"fx": -525, "fy": 525, "cx": 80, "cy": 60, "width": 160, "height": 120}')), 2,
           ["negfx.json", "fx"])
    c.case("daemon.intrinsics.caminfo-zero-size", D, replay(small, "i3.lcmlog", "--set",
           "camera.intrinsics_file=" + c.write("zero.yaml",
           "image_width: 0\nimage_height: 0\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
           "  data: [131, 0, 80, 0, 131, 60, 0, 0, 1]\n")), 2, ["zero.yaml", "image_width"])
    c.case("daemon.intrinsics.caminfo-strings", D, replay(small, "i4.lcmlog", "--set",
           "camera.intrinsics_file=" + c.write("str.yaml",
           "image_width: 160\nimage_height: 120\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
           "  data: [a, 0, 80, 0, 131, 60, 0, 0, 1]\n")), 2, ["str.yaml", "camera_matrix"])
    c.case("daemon.intrinsics.directory", D, replay(small, "i5.lcmlog", "--set",
           f"camera.intrinsics_file={c.work}"), 2, ["camera.intrinsics_file"])
    c.case("daemon.intrinsics.fifo-json", D, replay(small, "i7.lcmlog", "--set",
           f"camera.intrinsics_file={_fifo(c.p('k.fifo.json'))}"), 2, ["k.fifo.json"],
           timeout=30)
    c.case("daemon.intrinsics.good-caminfo", D, replay(small, "i6.lcmlog", "--set",
           "camera.intrinsics_file=" + c.write("good.yaml",
           "image_width: 160\nimage_height: 120\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
           "  data: [131.25, 0, 79.5, 0, 131.25, 59.5, 0, 0, 1]\n")), 0, log=c.p("i6.lcmlog"))
    # extrinsics files (camera.extrinsics_file)
    good_q = "[0.0, 0.0, 0.0, 1.0]"
    ext = {
        "missing-rotation": ('e1.json', '{"parent_frame": "base_link", '
                             '"translation": [0, 0, 1]}', ["e1.json", "rotation"]),
        "zero-quaternion": ('e2.json', '{"parent_frame": "base_link", "translation": [0, 0, 1],'
                            ' "rotation_xyzw": [0, 0, 0, 0]}', ["e2.json", "rotation"]),
        "millimetres": ('e3.json', '{"parent_frame": "base_link", "translation": [420, -100,'
                        ' 850], "rotation_xyzw": ' + good_q + '}', ["e3.json", "translation"]),
        "two-numbers": ('e4.json', '{"parent_frame": "base_link", "translation": [0, 1],'
                        ' "rotation_xyzw": ' + good_q + '}', ["e4.json", "translation"]),
        "no-parent": ('e5.json', '{"translation": [0, 0, 1], "rotation_xyzw": ' + good_q + '}',
                      ["e5.json", "parent"]),
        "tf-no-frame": ('e6.yaml', "transform:\n  translation: {x: 0, y: 0, z: 1}\n"
                        "  rotation: {x: 0, y: 0, z: 0, w: 1}\n", ["e6.yaml", "frame"]),
        "tf-string-number": ('e7.yaml', "header: {frame_id: base_link}\ntransform:\n"
                             "  translation: {x: zero, y: 0, z: 1}\n"
                             "  rotation: {x: 0, y: 0, z: 0, w: 1}\n",
                             ["e7.yaml", "translation"]),
        "handeye-no-effector": ('e8.yaml', "parameters:\n  eye_on_hand: true\n"
                                "  robot_base_frame: base_link\n"
                                "  tracking_base_frame: camera_depth_optical_frame\n"
                                "transformation: {x: 0.1, y: 0, z: 0.5, qx: 0, qy: 0, qz: 0,"
                                " qw: 1}\n", ["e8.yaml", "robot_effector_frame"]),
        "handeye-inf": ('e9.yaml', "parameters:\n  eye_on_hand: false\n"
                        "  robot_base_frame: base_link\n"
                        "transformation: {x: .inf, y: 0, z: 0.5, qx: 0, qy: 0, qz: 0, qw: 1}\n",
                        ["e9.yaml", "transformation"]),
        "nul-in-frame-name": ('e12.json', '{"parent_frame": "base\\u0000link", '
                              '"translation": [0, 0, 1], "rotation_xyzw": ' + good_q + '}',
                              ["e12.json", "parent_frame", "control character"]),
        "yaml-named-json": ('e10.json', "header: {frame_id: base_link}\n", ["e10.json"]),
        "empty": ('e11.json', "", ["e11.json"]),
    }
    for key, (fname, text, words) in ext.items():
        c.case(f"daemon.extrinsics.{key}", D, replay(small, f"x_{key}.lcmlog", "--set",
               "camera.extrinsics_file=" + c.write(fname, text)), 2,
               ["camera.extrinsics_file"] + words)
    c.case("daemon.extrinsics.fifo-json", D, replay(small, "x_fifo.lcmlog", "--set",
           f"camera.extrinsics_file={_fifo(c.p('x.fifo.json'))}"), 2, ["x.fifo.json"],
           timeout=30)
    c.case("daemon.extrinsics.directory", D, replay(small, "x_dir.lcmlog", "--set",
           f"camera.extrinsics_file={c.work}"), 2, ["camera.extrinsics_file"])

    def frame_id_is(name):
        def check(res):
            ids = {c.objects_t.decode(d).frame_id for d in res.objects_msgs}
            return None if ids == {name} else f"frame_id {ids}, expected {{'{name}'}}"
        return check
    c.case("daemon.extrinsics.good-json", D, replay(small, "x_good.lcmlog", "--set",
           "camera.extrinsics_file=" + c.write("ok.json", '{"parent_frame": "base_link", '
           '"translation": [0.42, -0.1, 0.85], "rotation_xyzw": [0.9848078, 0.0, 0.0, '
           '-0.1736482]}')), 0, log=c.p("x_good.lcmlog"), check=frame_id_is("base_link"))
    c.case("daemon.extrinsics.good-handeye", D, replay(small, "x_he.lcmlog", "--set",
           "camera.extrinsics_file=" + c.write("he.yaml", "parameters:\n  eye_on_hand: true\n"
           "  robot_base_frame: base_link\n  robot_effector_frame: tool0\n"
           "  tracking_base_frame: camera_depth_optical_frame\n"
           "transformation: {x: 0.9, y: 0.05, z: 0.6, qx: -0.5, qy: 0.5, qz: -0.5, qw: 0.5}\n")),
           0, log=c.p("x_he.lcmlog"), check=frame_id_is("tool0"))
    # sources
    c.case("daemon.source.empty-oni", D, replay(c.write("empty.oni", ""), "s1.lcmlog"), 3,
           ["empty.oni"])
    c.case("daemon.source.png-named-oni", D, replay(c.damaged(
           "png.oni", c.depth_png or c.pcd, lambda d: d), "s2.lcmlog"), 3, ["png.oni"])
    c.case("daemon.source.fifo-oni", D, replay(_fifo(c.p("fifo.oni")), "s3.lcmlog"), 3,
           ["fifo.oni"], timeout=30)
    c.case("daemon.source.all-pcds-garbage", D, replay(c.p("garbage_pcds"), "s4.lcmlog"), 3,
           ["f0.pcd"])
    c.case("daemon.source.no-device", D, ["--source", "device:/dev/nonexistent-camera",
           "--lcm-url", url("s5.lcmlog"), "--max-frames", "1"], 3, ["device"], timeout=60)
    c.case("daemon.source.synthetic", D, ["--source", "synthetic", "--max-frames", "3",
           "--lcm-url", url("s6.lcmlog")], 0, log=c.p("s6.lcmlog"))
    # outputs
    c.case("daemon.output.png-dir-is-file", D, replay(small, "o1.lcmlog", "--png-dir",
           c.pcd), {2, 5}, ["png"])
    c.case("daemon.output.log-in-proc", D, ["--source", small, "--speed", "max", "--lcm-url",
           "file:///proc/clutterseg-hostile.lcmlog?mode=w"], 4, ["/proc/clutterseg-hostile"])

    # loops (lead a): every pass delivered, nothing counted missing, frame_seq increasing
    def seq_check(n):
        def check(res):
            if res.log_objects != n:
                return f"{res.log_objects} objects_t, expected {n}"
            return None
        return check
    c.case("daemon.loop.lockstep-25-of-10", D, replay(small, "l1.lcmlog", "--loop",
           "--max-frames", "25"), 0, log=c.p("l1.lcmlog"), check=seq_check(25))

    def loop_honest(res):
        last = c.status_t.decode(res.log_statuses[-1])
        if last.frames_not_delivered != 0:
            return f"frames_not_delivered {last.frames_not_delivered} in the last status_t"
        if "incomplete" in res.err:
            return "an 'incomplete' line"
        return None
    c.case("daemon.loop.recorded-from-pcd", D, replay(c.p("slow.oni"), "l5.lcmlog", "--loop",
           "--max-frames", "10"), 0, log=c.p("l5.lcmlog"), check=seq_check(10))
    c.case("daemon.loop.pcd-directory", D, replay(c.p("pcds"), "l6.lcmlog", "--loop",
           "--max-frames", "7"), 0, log=c.p("l6.lcmlog"), check=seq_check(7))
    c.case("daemon.loop.depth-png-directory", D, replay(c.p("dpng"), "l7.lcmlog", "--loop",
           "--max-frames", "7"), 0, log=c.p("l7.lcmlog"), check=seq_check(7))
    c.case("regress.looped-run-vs-itself", "regress", [c.p("l1.lcmlog"), c.p("l1.lcmlog")], 0)
    c.case("daemon.loop.realtime-room-3-passes", D, ["--source", room, "--speed", "realtime",
           "--loop", "--lcm-url", url("l2.lcmlog")], 0, log=c.p("l2.lcmlog"),
           stop=after_events(c.p("l2.lcmlog"), 2 * 95), check=loop_honest, timeout=60)
    c.case("daemon.loop.lockstep-sigterm-load", D, replay(small, "l3.lcmlog", "--loop"), 0,
           log=c.p("l3.lcmlog"), stop=after_events(c.p("l3.lcmlog"), 60), load=True,
           check=loop_honest)

    # the temporal filter across a loop seam: pass 2 gives the objects of pass 1
    def passes_agree(res):
        counts = [c.objects_t.decode(d).num_objects for d in res.objects_msgs]
        if len(counts) < 20:
            return f"only {len(counts)} frames"
        diff = [i for i in range(10) if abs(counts[i] - counts[i + 10]) > 1]
        return None if not diff else f"objects per frame differ between passes: {counts[:20]}"
    c.case("daemon.loop.temporal-across-seam", D, replay(small, "l4.lcmlog", "--loop",
           "--max-frames", "20"), 0, log=c.p("l4.lcmlog"), check=passes_agree)

    # SIGTERM (lead c), with and without load
    c.case("daemon.sigterm.realtime-room", D, ["--source", room, "--speed", "realtime",
           "--loop", "--lcm-url", url("t1.lcmlog")], 0, log=c.p("t1.lcmlog"),
           stop=after_events(c.p("t1.lcmlog"), 40))
    c.case("daemon.sigterm.realtime-room-load", D, ["--source", room, "--speed", "realtime",
           "--loop", "--lcm-url", url("t2.lcmlog")], 0, log=c.p("t2.lcmlog"),
           stop=after_events(c.p("t2.lcmlog"), 40), load=True)
    c.case("daemon.sigterm.lockstep-room-load", D, replay(room, "t3.lcmlog", "--loop"), 0,
           log=c.p("t3.lcmlog"), stop=after_events(c.p("t3.lcmlog"), 30), load=True)
    shutil.copy(c.p("big.lcmlog.src"), c.p("t4.lcmlog"))
    c.case("daemon.sigterm.append-430MB-log-load", D, ["--source", room, "--speed",
           "realtime", "--loop", "--lcm-url", url("t4.lcmlog", "a")], 0, load=True,
           stop=after_seconds(4.0), timeout=120)
    os.remove(c.p("t4.lcmlog"))
    c.case("daemon.sigterm.startup-load", D, replay(room, "t5.lcmlog", "--loop"), 0,
           stop=after_seconds(0.25), load=True)
    c.case("daemon.sigterm.png-overlays-load", D, replay(room, "t6.lcmlog", "--loop",
           "--png-dir", c.p("overlays")), {0, 5}, log=c.p("t6.lcmlog"),
           stop=after_events(c.p("t6.lcmlog"), 20), load=True)
    # a camera whose frames come slowly (1 frame a second): SIGTERM while it waits
    c.case("daemon.sigterm.slow-source-1hz", D, ["--source", c.p("slow.oni"), "--speed",
           "realtime", "--lcm-url", url("t7.lcmlog")], 0, log=c.p("t7.lcmlog"),
           stop=after_seconds(1.6))
    # reload: a configuration that turned bad is named and the run goes on
    reload_cfg = c.write("reload.yaml", "camera_name: reload\n")

    def hup_then_term(proc, elapsed):
        if elapsed >= 1.0 and not getattr(proc, "hupped", False):
            c.write("reload.yaml", "camera_name: reload\nsegmenter: {planes: {max_planes: x}}\n")
            os.kill(proc.pid, signal.SIGHUP)
            proc.hupped = True
        return elapsed >= 2.0
    def term_twice(proc, elapsed):
        if elapsed >= 1.0:
            os.kill(proc.pid, signal.SIGTERM)  # the campaign sends the second one
            return True
        return False
    c.case("daemon.sigterm.twice-load", D, ["--source", room, "--speed", "realtime", "--loop",
           "--lcm-url", url("t8.lcmlog")], {0, 1}, stop=term_twice, load=True)

    def hup_early(proc, elapsed):
        if elapsed >= 0.15 and not getattr(proc, "hupped", False):
            os.kill(proc.pid, signal.SIGHUP)
            proc.hupped = True
        return elapsed >= 1.5
    c.case("daemon.sighup.during-start-up", D, ["--source", room, "--speed", "realtime",
           "--loop", "--lcm-url", url("h2.lcmlog")], 0, log=c.p("h2.lcmlog"), stop=hup_early)
    # reload: an extrinsics file that turned bad is named and the pose in use is kept
    c.write("pose.json", '{"parent_frame": "base_link", "translation": [0.4, 0, 0.8], '
            '"rotation_xyzw": [0, 0, 0, 1]}')
    pose_cfg = c.write("pose.yaml", "camera:\n  extrinsics_file: " + c.p("pose.json") + "\n")

    def hup_bad_pose_then_term(proc, elapsed):
        if elapsed >= 1.0 and not getattr(proc, "hupped", False):
            c.write("pose.json", '{"parent_frame": "base_link", "translation": [0.4, 0, 0.8], '
                    '"rotation_xyzw": [0, 0, 0, 2]}')
            os.kill(proc.pid, signal.SIGHUP)
            proc.hupped = True
        return elapsed >= 2.0
    c.case("daemon.sighup.bad-extrinsics-keeps-the-pose", D, ["--config", pose_cfg, "--source",
           room, "--speed", "realtime", "--loop", "--lcm-url", url("h3.lcmlog")], 0,
           ["reload failed", "pose.json", "quaternion"], log=c.p("h3.lcmlog"),
           stop=hup_bad_pose_then_term, check=frame_id_is("base_link"))
    # SCHED_FIFO (the template unit's setting) under load, with overlays: the stop still
    # ends the run at once and the normal-class overlay writer does not hold it back
    c.case("daemon.sigterm.sched-fifo-overlays-load", D, ["--source", room, "--speed",
           "realtime", "--loop", "--set", "processing.realtime_priority=10", "--png-dir",
           c.p("overlays_fifo"), "--lcm-url", url("t9.lcmlog")], {0, 5}, log=c.p("t9.lcmlog"),
           stop=after_events(c.p("t9.lcmlog"), 40), load=True)
    c.case("daemon.sighup.bad-file-then-sigterm", D, ["--config", reload_cfg, "--source", room,
           "--speed", "realtime", "--loop", "--lcm-url", url("h1.lcmlog")], 0,
           ["reload.yaml", "max_planes"], log=c.p("h1.lcmlog"), stop=hup_then_term)


def _fifo(path):
    if not os.path.exists(path):
        os.mkfifo(path)
    return path


def tool_cases(c: Campaign):
    S, E, L, R, REC, SY, B = "segment", "eval", "listen", "regress", "record", "synth", "bench"
    pcd = c.pcd
    # clutterseg-segment (lead b: a bad --intrinsics is a usage error, as for the daemon)
    c.case("segment.intrinsics.cx-1e30", S, [pcd, c.p("seg1.pcd"), "--intrinsics", c.write(
           "k1.json", '{"fx": 525, "fy": 525, "cx": 1e30, "cy": 239.5}')], 2, ["k1.json", "cx"])
    c.case("segment.intrinsics.missing", S, [pcd, c.p("seg2.pcd"), "--intrinsics",
           c.p("k_none.json")], 2, ["k_none.json"])
    c.case("segment.intrinsics.fifo", S, [pcd, c.p("seg9.pcd"), "--intrinsics",
           _fifo(c.p("k9.fifo.json"))], 2, ["k9.fifo.json"], timeout=30)
    c.case("segment.intrinsics.yaml-as-json", S, [pcd, c.p("seg3.pcd"), "--intrinsics",
           c.write("k3.json", "fx: 525\n")], 2, ["k3.json"])
    nan_pcd = c.write("nan.pcd", "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                      "COUNT 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\n"
                      "DATA ascii\n" + "nan nan nan\n" * 4)
    c.case("segment.input.nan-only", S, [nan_pcd, c.p("seg4.pcd")], 1, ["nan.pcd"])
    c.case("segment.input.points-overclaimed", S, [c.write("over.pcd", "# .PCD v0.7\nVERSION "
           "0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1000\nHEIGHT 1\n"
           "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1000\nDATA ascii\n0 0 1\n"), c.p("seg5.pcd")], 1,
           ["over.pcd"])
    c.case("segment.input.fifo", S, [_fifo(c.p("in.fifo.pcd")), c.p("seg6.pcd")], {1, 3},
           ["in.fifo.pcd"], timeout=30)
    c.case("segment.input.png-8bit", S, [c.write("eight.png", _png_gray8(8, 8), "wb"),
           c.p("seg7.pcd")], 1, ["eight.png"])
    c.case("segment.set.unknown-key", S, [pcd, c.p("seg8.pcd"), "--set",
           "supervoxel.no_such_key=1"], 2, ["no_such_key"])
    c.case("segment.output.dir-is-file", S, [c.p("pcds"), pcd], {1, 2}, [os.path.basename(pcd)])
    c.case("segment.dir.three-frames", S, [c.p("pcds"), c.p("seg_out"), "--json",
           c.p("seg_json")], 0,
           check=lambda r: None if len(os.listdir(c.p("seg_json"))) == 3 else "not 3 JSON files")
    # clutterseg-eval
    other = c.p("scenes", sorted(f for f in os.listdir(c.p("scenes")) if f.endswith(".pcd"))[1])
    c.case("eval.size-mismatch", E, [pcd, c.write("tiny.pcd", "# .PCD v0.7\nVERSION 0.7\n"
           "FIELDS x y z label\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 1\nHEIGHT 1\n"
           "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n0 0 1 1\n")], {1, 2},
           ["tiny.pcd"])
    c.case("eval.gt-missing", E, [c.p("gt_none.pcd"), pcd], 3, ["gt_none.pcd"])
    c.case("eval.gt-fifo", E, [_fifo(c.p("gt.fifo.pcd")), pcd], {1, 3}, ["gt.fifo.pcd"],
           timeout=30)
    os.makedirs(c.p("pred_partial"), exist_ok=True)
    shutil.copy(pcd, c.p("pred_partial", os.path.basename(pcd)))
    c.case("eval.dir-prediction-missing", E, [c.p("pcds"), c.p("pred_partial")], {1, 2, 3, 5},
           [os.path.basename(other)])
    c.case("eval.csv-to-dev-full", E, [pcd, pcd, "--csv", "/dev/full"], {1, 5}, ["/dev/full"])
    c.case("eval.ocid-background-garbage", E, [pcd, pcd, "--gt-convention", "ocid",
           "--ocid-background", "x,y"], 2, ["ocid-background"])
    c.case("eval.same-file", E, [pcd, pcd], 0, ['"f1"'])
    # clutterseg-listen: the LCM log reader
    ref = c.p("ref.lcmlog")
    c.case("listen.log.good", L, ["--lcm-url", f"file://{ref}?speed=0", "--count", "5"], 0,
           check=lambda r: None if r.out.count("frame") >= 5 or r.out.count("objects") >= 5
           else "fewer than 5 frames printed")
    trunc = c.damaged("trunc.lcmlog", ref, lambda d: d[:len(d) // 2 + 7])
    c.case("listen.log.truncated", L, ["--lcm-url", f"file://{trunc}?speed=0"], {0, 1, 5},
           timeout=30)
    rnd = c.write("random.lcmlog", os.urandom(100000), "wb")
    c.case("listen.log.random", L, ["--lcm-url", f"file://{rnd}?speed=0"], {0, 1, 2, 4, 5},
           timeout=30)
    c.case("listen.log.fifo", L, ["--lcm-url", f"file://{_fifo(c.p('listen.fifo'))}?speed=0"],
           4, ["listen.fifo"], timeout=30)
    c.case("listen.log.directory", L, ["--lcm-url", f"file://{c.work}?speed=0"], 4, [c.work],
           timeout=30)
    c.case("listen.log.missing", L, ["--lcm-url", f"file://{c.p('no.lcmlog')}?speed=0"], 4,
           ["no.lcmlog"], timeout=30)
    c.case("listen.count.negative", L, ["--lcm-url", f"file://{ref}?speed=0", "--count", "-1"],
           2, ["count"])
    c.case("listen.sigterm.realtime-log-load", L, ["--lcm-url", f"file://{c.p('ref2.lcmlog')}"
           "?speed=0.05"], 0, stop=after_seconds(1.0), load=True, timeout=60)
    # clutterseg-regress: the LCM log reader
    c.case("regress.same-log", R, [ref, ref], 0)
    half = c.p("half.lcmlog")
    write_log(half, [e for e in c.ref_events if e[0] != "CLUTTERSEG_OBJECTS"] +
              [e for e in c.ref_events if e[0] == "CLUTTERSEG_OBJECTS"][:5])
    c.case("regress.frames-missing", R, [ref, half], 1, ["frame"])
    c.case("regress.empty-file", R, [ref, c.write("empty.lcmlog", "")], 1,
           ["only in the first log"])
    c.case("regress.random-bytes", R, [ref, rnd], 2, ["random.lcmlog"])
    c.case("regress.status-only", R, [ref, _status_only(c)], 1, ["only in the first log"])
    c.case("regress.fifo", R, [ref, _fifo(c.p("log.fifo"))], 2, ["log.fifo"], timeout=30)
    c.case("regress.directory", R, [ref, c.work], 2, [c.work])
    # clutterseg-record
    os.makedirs(c.p("empty_dir"), exist_ok=True)
    c.case("record.from-pcd.empty-dir", REC, [c.p("rec1.oni"), "--from-pcd", c.p("empty_dir")],
           {1, 2, 3}, ["empty_dir"])
    c.case("record.from-pcd.garbage", REC, [c.p("rec2.oni"), "--from-pcd",
           c.p("garbage_pcds")], {1, 3, 5}, ["f0.pcd"])
    c.case("record.out-missing-dir", REC, [c.p("nodir", "rec3.oni"), "--from-pcd", c.p("pcds")],
           {1, 2}, ["nodir"])
    c.case("record.no-device", REC, [c.p("rec4.oni"), "--frames", "1", "--device",
           "/dev/nonexistent-camera"], 3, ["device"], timeout=60)
    c.case("record.from-pcd.good", REC, [c.p("slow.oni"), "--from-pcd", c.p("pcds"), "--fps",
           "1"], 0)
    # clutterseg-synth
    c.case("synth.count-zero", SY, ["--out", c.p("syn0"), "--count", "0"], 2, ["count"])
    c.case("synth.objects-reversed", SY, ["--out", c.p("syn1"), "--objects", "5:2"], 2,
           ["objects"])
    c.case("synth.oni-to-dev-full", SY, ["--oni", "/dev/full", "--count", "1", "--width", "64",
           "--height", "48"], {1, 5}, ["/dev/full"])
    c.case("synth.out-is-file", SY, ["--out", pcd, "--count", "1"], {1, 2}, [pcd])
    # clutterseg-bench
    c.case("bench.synthetic-small", B, ["--synthetic", "2", "--repeat", "1", "--warmup", "0",
           "--no-pipelined", "--no-unorganized"], 0, timeout=300)
    c.case("bench.empty-dir", B, [c.p("empty_dir")], {1, 3}, ["empty_dir"])
    c.case("bench.set-unknown", B, ["--synthetic", "1", "--set", "no.such=1"], 2, ["no.such"])


def _png_gray8(w, h):
    import zlib
    raw = b"".join(b"\x00" + bytes([128] * w) for _ in range(h))

    def chunk(t, d):
        return (struct.pack(">I", len(d)) + t + d +
                struct.pack(">I", zlib.crc32(t + d) & 0xffffffff))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def _status_only(c):
    path = c.p("status_only.lcmlog")
    write_log(path, [e for e in c.ref_events if e[0] == "CLUTTERSEG_STATUS"])
    return path


PY_PRELUDE = "import numpy as np, clutterseg\ns = clutterseg.Segmenter(threads=1)\n"


def python_cases(c: Campaign):
    P = "python"

    def py(name, body, expect=0, words=(), rss_mib=1024.0, timeout=120):
        c.case(f"python.{name}", P, PY_PRELUDE + body, expect, words, rss_mib=rss_mib,
               timeout=timeout, python=True)

    # errors must be exceptions naming the argument (exit 1 from the interpreter, the type and
    # the message on stderr), never a crash
    py("int32-points", "s.segment(np.zeros((10, 3), np.int32))", 1, ["TypeError", "points"])
    py("organized-4-channels", "s.segment(np.zeros((48, 64, 4), np.float32))", 1,
       ["ValueError", "points"])
    py("colors-float", "s.segment(np.zeros((48, 64, 3), np.float32), "
       "np.zeros((48, 64, 3), np.float32))", 1, ["TypeError", "colors"])
    py("bytes-not-array", "s.segment(b'\\x00' * 120)", 1, ["points"])
    py("masked-array", "import numpy.ma as ma\n"
       "p = ma.masked_array(np.random.rand(1000, 3).astype(np.float32) + 1, mask=False)\n"
       "r = s.segment(p)\nassert r.labels.shape == (1000,)")
    py("intrinsics-fx-nan", "s.segment(np.ones((48, 64, 3), np.float32), intrinsics=dict("
       "fx=float('nan'), fy=525, cx=32, cy=24))", 1, ["ValueError", "fx"])
    py("intrinsics-width-zero", "s.segment_depth(np.full((48, 64), 1000, np.uint16), "
       "clutterseg.Intrinsics(fx=70, fy=70, cx=32, cy=24, width=0, height=48))", 1, ["width"])
    py("depth-float", "s.segment_depth(np.ones((48, 64), np.float32), dict(fx=70, fy=70, "
       "cx=32, cy=24))", 1, ["TypeError", "depth_mm"])
    py("config-missing", "clutterseg.Segmenter(config='/nonexistent/c.yaml')", 1,
       ["FileNotFoundError", "/nonexistent/c.yaml"])
    py("override-unknown", "clutterseg.Segmenter(no_such_key=1)", 1, ["KeyError", "no_such_key"])
    py("threads-negative", "clutterseg.Segmenter(threads=-1)", 1, ["ValueError", "threads"])
    py("intrinsics-extra-key", "s.segment(np.ones((48, 64, 3), np.float32), intrinsics=dict("
       "fx=70, fy=70, cx=32, cy=24, bogus=1))", 1, ["KeyError", "bogus"])
    py("intrinsics-fx-1e30", "s.segment_depth(np.full((48, 64), 1000, np.uint16), dict("
       "fx=1e30, fy=70, cx=32, cy=24))", 1, ["ValueError", "fx"])
    # values
    py("single-pixel-organized", "r = s.segment(np.ones((1, 1, 3), np.float32))\n"
       "assert r.labels.shape == (1, 1) and len(r.objects) == 0")
    py("nan-only-organized", "r = s.segment(np.full((120, 160, 3), np.nan, np.float32))\n"
       "assert len(r.objects) == 0 and (r.labels == 0).all()")
    py("z-1e30-only", "p = np.zeros((120, 160, 3), np.float32); p[..., 2] = 1e30\n"
       "r = s.segment(p)\nassert len(r.objects) == 0")
    py("every-other-1e30", "p = np.random.rand(20000, 3).astype(np.float32) + 0.5\n"
       "p[::2] = 1e30\nr = s.segment(p)\n"
       "assert (r.labels[::2] == 0).all()\n"
       "assert all(np.isfinite(o.centroid).all() for o in r.objects)")
    py("strided-view-equals-copy", "pc = clutterseg.read_pcd(%r)\n"
       "p = np.repeat(pc.points, 2, axis=1)[:, ::2]\n"
       "assert not p.flags.c_contiguous\n"
       "a = s.segment(p).labels; b = s.segment(np.ascontiguousarray(p)).labels\n"
       "assert (a == b).all()" % c.pcd)
    py("readonly-mmap", "import mmap, tempfile\n"
       "f = tempfile.TemporaryFile(); f.write(np.random.rand(3000, 3).astype(np.float32)"
       ".tobytes() + b''); f.flush()\n"
       "m = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)\n"
       "p = np.frombuffer(m, np.float32).reshape(-1, 3)\nassert not p.flags.writeable\n"
       "r = s.segment(p + 0)\nr = s.segment(p)\nassert r.labels.shape == (3000,)")
    # size: ten million points, peak RSS bounded (input 120 MB)
    py("ten-million-points", "rng = np.random.default_rng(1)\n"
       "p = rng.random((10_000_000, 3), np.float32); p[:, 2] += 1.0\n"
       "r = s.segment(p)\nassert r.labels.shape == (10_000_000,)", 0, rss_mib=1536.0,
       timeout=600)
    py("huge-organized-refused", "p = np.broadcast_to(np.float32(1), (20000, 20000, 3))\n"
       "s.segment(p)", 1, ["points"], rss_mib=512.0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("build", help="build directory (e.g. build/release)")
    ap.add_argument("--only", help="run only the cases whose name matches this regex")
    ap.add_argument("--keep", action="store_true", help="keep the scratch directory")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="clutterseg-hostile-")
    c = Campaign(args.build, work, args.keep)
    if args.only:
        pattern = re.compile(args.only)
        original = c.case

        def filtered(name, *a, **k):
            if pattern.search(name):
                return original(name, *a, **k)
            return None
        c.case = filtered
    t0 = time.monotonic()
    try:
        c.make_inputs()
        print(f"inputs made in {time.monotonic() - t0:.1f} s in {work}")
        print(f"{'case':<44} {'expected':<8} {'got':<36} verdict")
        tool_cases(c)  # makes slow.oni and l1.lcmlog users come after it: order matters
        daemon_cases(c)
        python_cases(c)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    by_binary = {}
    for r in c.results:
        n, ok = by_binary.get(r["binary"], (0, 0))
        by_binary[r["binary"]] = (n + 1, ok + (1 if r["ok"] else 0))
    print("\nper binary: " + ", ".join(f"{b} {ok}/{n}" for b, (n, ok) in by_binary.items()))
    peak = {}
    for r in c.results:
        peak[r["binary"]] = max(peak.get(r["binary"], 0.0), r["rss"])
    print("peak RSS per binary: " + ", ".join(f"{b} {m:.0f} MiB" for b, m in peak.items()))
    stops = [r for r in c.results if r["stop_s"] is not None]
    if stops:
        worst = max(stops, key=lambda r: r["stop_s"])
        loaded = [r["stop_s"] for r in stops if r["load"]]
        print(f"SIGTERM to exit: {len(stops)} cases, worst {worst['stop_s']:.2f} s "
              f"({worst['case']}); under load: "
              + ", ".join(f"{s:.2f}" for s in loaded) + " s")
    failed = [r for r in c.results if not r["ok"]]
    print(f"{len(c.results)} cases, {len(c.results) - len(failed)} pass, {len(failed)} fail "
          f"({time.monotonic() - t0:.0f} s)")
    for r in failed:
        print(f"FAIL {r['case']}: {'; '.join(r['problems'])}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
