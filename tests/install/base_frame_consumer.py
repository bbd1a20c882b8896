#!/usr/bin/env python3
"""Reads objects in the robot's base frame with the installed Python bindings only (no lcm
module), as docs/lcm.md shows it: from an LCM log (a path) or the daemon's udpm group (a URL,
or nothing for LCM_DEFAULT_URL). Prints each frame's frame_id and, per object, the centroid and
the gravity-aligned box:
  python: frame 3 in base_link: 4 objects
  python:   track 7: centroid (0.612 -0.118 0.054) m, upright box 0.081 x 0.062 x 0.104 m"""
import sys

from clutterseg import objects_t
from clutterseg.transport import Subscriber, read_log


def events(source):
    if source and "://" not in source:
        for event in read_log(source):
            yield event.channel, event.data
    else:
        with Subscriber(source or None, channels=["CLUTTERSEG_OBJECTS"]) as bus:
            yield from bus.messages(timeout_s=10.0)


frames = 0
for channel, data in events(sys.argv[1] if len(sys.argv) > 1 else ""):
    if channel != "CLUTTERSEG_OBJECTS":
        continue
    m = objects_t.decode(data)
    print("python: frame %d in %s: %d objects" % (m.frame_seq, m.frame_id, m.num_objects))
    for o in m.objects:
        line = "python:   track %d: centroid (%.3f %.3f %.3f) m" % ((o.track_id,) + tuple(o.centroid))
        if o.has_gravity_box:
            line += ", upright box %.3f x %.3f x %.3f m" % tuple(o.gbox_extents)
        print(line)
    frames += 1
sys.exit(0 if frames > 0 else 1)
