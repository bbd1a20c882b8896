#!/usr/bin/env python3
"""Fails when a source file includes a header it may not use under the module layering of
docs/architecture.md. The build enforces the same rule (each module target sees only the
public headers of the modules it links, tools/cmake/clutterseg_headers.cmake); this check
names the offending line, and also covers what the compiler would accept:

  1. a module includes "clutterseg/<m>/..." only for <m> itself or a module below it;
  2. nothing outside module <m> (and its tests, tests/<m>/) includes "clutterseg/<m>/internal/";
  3. a public header never includes an internal header (internal headers are not installed);
  4. library code (src/, drivers/) includes no "tools/" or "tests/" header, OpenNI2 only in
     drivers/openni2, LCM (<lcm/...>, generated "clutterseg/<type>_t.hpp") only in src/daemon.

Usage: tools/check_layering.py [REPO_ROOT]; exit 0 when clean, 1 with one line per finding.
"""
import os
import re
import sys

# Module -> the modules it may include (besides itself). Keep in step with the PUBLIC links of
# the module targets (src/*/CMakeLists.txt, drivers/*/CMakeLists.txt).
BELOW = {
    "core": [],
    "io": ["core"],
    "eval": ["core"],
    "synth": ["core"],
    "geometry": ["core"],
    "supervoxel": ["geometry"],
    "graph": ["supervoxel"],
    "optimize": ["graph"],
    "pipeline": ["optimize"],
    "config": ["pipeline"],
    "drivers/oni": ["core"],
    "drivers/openni2": ["core", "drivers/oni"],
    "drivers/replay": ["io", "synth"],
    "daemon": ["config", "io", "drivers/oni", "drivers/openni2", "drivers/replay"],
    "python": ["config", "io", "eval"],
}


def closure(module):
    """The modules `module` may use: the transitive closure of BELOW."""
    seen, todo = set(), list(BELOW[module])
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(BELOW[m])
    return seen


INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')
PROJECT = re.compile(r"^clutterseg/((?:drivers/)?[a-z0-9_]+)/(.*)$")
LCM_TYPE = re.compile(r"^clutterseg/[a-z0-9_]+_t\.hpp$")


def module_of(rel):
    """The library module a repository path belongs to, or None (tools, tests)."""
    parts = rel.split("/")
    if parts[0] == "src" and len(parts) > 2:
        return parts[1]
    if parts[0] == "drivers" and len(parts) > 2:
        return "drivers/" + parts[1]
    return None


def test_module_of(rel):
    """tests/<m>/... -> <m> (tests/drivers/... -> drivers/*), else None."""
    parts = rel.split("/")
    if parts[0] == "tests" and len(parts) > 2:
        return parts[1]
    return None


def check_file(root, rel):
    findings = []
    module = module_of(rel)
    allowed = closure(module) | {module} if module else None
    is_internal = "/internal/" in rel
    is_header = rel.endswith((".h", ".hpp"))
    with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            path = m.group(2)
            close = ">" if m.group(1) == "<" else '"'
            where = f"{rel}:{lineno}: #include {m.group(1)}{path}{close}"
            pm = PROJECT.match(path)
            if pm and not LCM_TYPE.match(path):
                target, inner = pm.group(1), pm.group(2)
                if target not in BELOW and not target.startswith("drivers/"):
                    findings.append(f"{where}: unknown module '{target}'")
                    continue
                if module and target not in allowed:
                    findings.append(f"{where}: '{module}' may not use '{target}' (a layer above "
                                    f"it or beside it; see docs/architecture.md)")
                if inner.startswith("internal/"):
                    tm = test_module_of(rel)
                    own = module == target or (tm is not None and (tm == target or
                                                                   target.startswith(tm + "/")))
                    if not own:
                        findings.append(f"{where}: internal header of '{target}' used outside it")
                    elif module and is_header and not is_internal:
                        findings.append(f"{where}: public header includes an internal header "
                                        f"(internal headers are not installed)")
            if module is None:
                continue
            if path.startswith(("tools/", "tests/")):
                findings.append(f"{where}: library code includes a tool or test header")
            if (path in ("OpenNI.h", "OniCAPI.h", "OniCTypes.h") or path.startswith("openni2/")) \
                    and module != "drivers/openni2":
                findings.append(f"{where}: OpenNI2 outside drivers/openni2")
            if (path.startswith("lcm/") or LCM_TYPE.match(path)) and module != "daemon":
                findings.append(f"{where}: LCM outside src/daemon")
    return findings


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else
                           os.path.join(os.path.dirname(__file__), ".."))
    findings = []
    for top in ("src", "drivers", "tools", "tests"):
        for dirpath, _, files in os.walk(os.path.join(root, top)):
            for name in sorted(files):
                if name.endswith((".h", ".hpp", ".cc", ".cpp")):
                    rel = os.path.relpath(os.path.join(dirpath, name), root)
                    findings.extend(check_file(root, rel))
    for f in findings:
        print(f)
    if findings:
        print(f"check_layering: {len(findings)} include(s) break the module layering",
              file=sys.stderr)
        return 1
    print("check_layering: every include respects the module layering")
    return 0


if __name__ == "__main__":
    sys.exit(main())
