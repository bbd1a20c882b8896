#!/usr/bin/env python3
"""Reads a clutterseg LCM log with the installed Python bindings only (no lcm module):
clutterseg.transport.read_log, the generated classes and clutterseg.label_image_codec.
Checks that each label image's largest id is its frame's object count; prints
  python: <frames> frames, <objects> objects, <label images> label images ok"""
import sys

from clutterseg import label_image_t, objects_t
from clutterseg.label_image_codec import decode
from clutterseg.transport import read_log

objects_per_frame, max_label = {}, {}
frames = objects = 0
for event in read_log(sys.argv[1]):
    if event.channel == "CLUTTERSEG_OBJECTS":
        m = objects_t.decode(event.data)
        objects_per_frame[m.frame_seq] = m.num_objects
        objects += m.num_objects
        frames += 1
        for o in m.objects:
            assert o.track_id >= 1, "objects carry track ids"
    elif event.channel == "CLUTTERSEG_LABELS":
        m = label_image_t.decode(event.data)
        labels = decode(m)
        assert len(labels) == m.width * m.height
        max_label[m.frame_seq] = max(labels) if len(labels) else 0
for seq, top in max_label.items():
    if objects_per_frame.get(seq) != top:
        print("python: frame %d: label image max %d but %s objects" % (seq, top, objects_per_frame.get(seq)))
        sys.exit(1)
print("python: %d frames, %d objects, %d label images ok" % (frames, objects, len(max_label)))
sys.exit(0 if frames > 0 and objects > 0 else 1)
