#!/usr/bin/env python3
"""Writes docs/configuration.md from config/clutterseg.yaml, whose comments document every
key and whose values are the defaults (a test keeps them equal to the code's defaults).
Usage: tools/gen_config_doc.py > docs/configuration.md"""
import pathlib
import re

root = pathlib.Path(__file__).resolve().parent.parent
lines = (root / "config" / "clutterseg.yaml").read_text().splitlines()

rows, comment, stack = [], [], []
for line in lines:
    if not line.strip():
        comment = [] if not stack else comment
        continue
    indent = len(line) - len(line.lstrip())
    text = line.strip()
    if text.startswith("#"):
        comment.append(text.lstrip("#").strip())
        continue
    m = re.match(r"([A-Za-z0-9_]+):\s*(.*)$", text)
    if not m:
        continue
    key, value = m.groups()
    level = indent // 2
    stack = stack[:level] + [key]
    if value == "":  # a section
        comment = []
        continue
    rows.append((".".join(stack), value, " ".join(comment)))
    comment = []

print("# Configuration reference\n")
print("Generated from `config/clutterseg.yaml` by `tools/gen_config_doc.py`; that file is the")
print("documented default configuration (a test checks every default against the code). Keys")
print("are written as dotted paths; set them in a YAML file given with `--config FILE`, or on")
print("the command line with `--set key.path=value` (the daemon) or `--set supervoxel.x=...`")
print("(clutterseg-segment, relative to `segmenter`). Unknown keys, wrong types and values out")
print("of range are rejected with a message naming the file, key and value (exit code 2).")
print("`segmenter.*` keys are re-read on SIGHUP and applied between frames.\n")
print("`config/paper.yaml` holds the seed paper's choices (docs/method.md).\n")
print("| key | default | meaning |")
print("|---|---|---|")
for key, value, text in rows:
    print(f"| `{key}` | `{value}` | {text} |")
