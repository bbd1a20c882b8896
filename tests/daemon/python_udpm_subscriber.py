#!/usr/bin/env python3
"""Subscribes over udpm with the installed/built Python bindings only (clutterseg.transport,
no lcm module) and checks what clutterseg daemons publish, per camera.

  python_udpm_subscriber.py URL READY_FILE FRAMES CAMERA [CAMERA ...]

Writes READY_FILE once it listens; exits 0 after FRAMES objects_t and their label images
(decoded with clutterseg.label_image_codec, largest id = object count) arrived from every
CAMERA, 1 on a mismatch, 2 after 60 s. Prints one line per camera."""
import sys
import time

from clutterseg import label_image_t, objects_t
from clutterseg.label_image_codec import decode
from clutterseg.transport import Subscriber

url, ready, frames, cameras = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
objects = {c: {} for c in cameras}
labels = {c: {} for c in cameras}
with Subscriber(url, channels=["CLUTTERSEG_OBJECTS", "CLUTTERSEG_LABELS"]) as sub:
    open(ready, "w").close()
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        done = all(len(objects[c]) >= frames and len(labels[c]) >= frames for c in cameras)
        if done:
            break
        message = sub.receive(timeout_s=0.5)
        if message is None:
            continue
        channel, data = message
        if channel == "CLUTTERSEG_OBJECTS":
            m = objects_t.decode(data)
            if m.camera_name in objects:
                objects[m.camera_name][m.frame_seq] = m.num_objects
        else:
            m = label_image_t.decode(data)
            if m.camera_name in labels:
                ids = decode(m)
                labels[m.camera_name][m.frame_seq] = max(ids) if len(ids) else 0
    else:
        print("python: timed out: " + ", ".join("%s %d/%d" % (c, len(objects[c]), len(labels[c]))
                                                  for c in cameras))
        sys.exit(2)
    ok = True
    for c in cameras:
        mismatch = [s for s in labels[c] if objects[c].get(s) != labels[c][s]]
        print("python: camera %s: %d frames, %d objects, %d label images, %d fragments lost%s" % (
            c, len(objects[c]), sum(objects[c].values()), len(labels[c]), sub.fragments_lost,
            ", mismatching frames %s" % mismatch if mismatch else ""))
        ok = ok and not mismatch and sum(objects[c].values()) > 0
sys.exit(0 if ok else 1)
