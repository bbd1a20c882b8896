#!/usr/bin/env bash
# Installs a built clutterseg into a staging root (DESTDIR, or the Debian packages extracted
# with dpkg-deb) and uses it as a separate robotics project would:
#   - builds tests/install/consumer with find_package(clutterseg) and, separately, with
#     pkg-config clutterseg, and runs both on a tabletop frame the installed clutterseg-synth
#     writes (no downloaded data);
#   - runs the installed daemon on a recording: it must load OpenNI2's recordings-only
#     drivers from the installed prefix, never from the build tree;
#   - decodes the daemon's log with the installed Python bindings (no lcm module) and with
#     the installed Java jar and LCM's Java library;
#   - checks the installed systemd unit with systemd-analyze verify.
#
# Usage: check_install.sh MODE BUILD_DIR SOURCE_DIR WORK_DIR
#   MODE install  DESTDIR=WORK/root cmake --install BUILD_DIR
#   MODE deb      cpack -G DEB in BUILD_DIR, check the three packages, extract them
# Exit 0 when everything works; the first failure is printed with what was expected.
set -euo pipefail
mode=$1 build=$(realpath "$2") src=$(realpath "$3") work=$4
fail() { echo "FAIL: $*" >&2; exit 1; }
rm -rf "$work"
mkdir -p "$work"
root="$work/root"
prefix=$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$build/CMakeCache.txt")
# The Python module is built when python3-dev and pybind11-dev are present.
pymodule=$(find "$build/lcmtypes/python/clutterseg" -name '_core*.so' 2> /dev/null | head -1)
[ -n "$prefix" ] || fail "no CMAKE_INSTALL_PREFIX in $build/CMakeCache.txt"

case "$mode" in
  install)
    DESTDIR="$root" cmake --install "$build" > "$work/install.log"
    ;;
  deb)
    (cd "$build" && cpack -G DEB -B "$work/debs" > "$work/cpack.log" 2>&1) ||
      { tail -20 "$work/cpack.log"; fail "cpack -G DEB"; }
    shopt -s nullglob
    debs=("$work"/debs/*.deb)
    pkgs=(clutterseg libclutterseg-dev clutterseg-lcmtypes)
    if [ -n "$pymodule" ]; then pkgs+=(python3-clutterseg); fi
    [ "${#debs[@]}" -eq "${#pkgs[@]}" ] || fail "expected ${pkgs[*]}, got: ${debs[*]}"
    for pkg in "${pkgs[@]}"; do
      deb=$(ls "$work"/debs/${pkg}_*.deb 2> /dev/null | head -1)
      [ -n "$deb" ] || fail "package $pkg missing"
      dpkg-deb -x "$deb" "$root"
      dpkg-deb -f "$deb" Package Version Depends > "$work/$pkg.control"
    done
    grep -q "libopenni2-0" "$work/clutterseg.control" || fail "clutterseg does not depend on libopenni2-0"
    grep -q "liblcm1" "$work/clutterseg.control" || fail "clutterseg does not depend on liblcm1 (shlibdeps)"
    grep -q "clutterseg-lcmtypes" "$work/libclutterseg-dev.control" || fail "-dev does not depend on the bindings"
    if [ -n "$pymodule" ]; then
      grep -q "clutterseg-lcmtypes (= .*python3-numpy" "$work/python3-clutterseg.control" ||
        fail "python3-clutterseg does not depend on the bindings and numpy: $(cat "$work/python3-clutterseg.control")"
    fi
    dpkg-deb -c "$work"/debs/clutterseg_*.deb > "$work/clutterseg.contents"
    grep -q "usr/bin/clutterseg$" "$work/clutterseg.contents" || fail "no /usr/bin/clutterseg in the package"
    grep -q "etc/clutterseg/clutterseg.yaml" "$work/clutterseg.contents" ||
      fail "no /etc/clutterseg/clutterseg.yaml in the package"
    ;;
  *)
    fail "unknown mode $mode"
    ;;
esac
p="$root$prefix"
for f in bin/clutterseg bin/clutterseg-segment bin/clutterseg-listen bin/clutterseg-spy \
         include/clutterseg/pipeline/segmenter.h include/clutterseg/objects_t.hpp \
         include/clutterseg/label_image_codec.hpp share/clutterseg/lcmtypes/clutterseg/objects_t.lcm \
         lib/systemd/system/clutterseg.service lib/systemd/system/clutterseg@.service lib/udev/rules.d/50-clutterseg.rules; do
  [ -e "$p/$f" ] || fail "$f not installed"
done
[ -f "$root/etc/clutterseg/clutterseg.yaml" ] || fail "/etc/clutterseg/clutterseg.yaml not installed"
if find "$root" -path '*/internal/*' -name '*.h' | grep -q .; then
  fail "internal headers installed: $(find "$root" -path '*/internal/*' -name '*.h' | head -3)"
fi
"$p/bin/clutterseg" --version | grep -q "clutterseg [0-9]" || fail "clutterseg --version"

# A cluttered tabletop frame (organized 640x480 PCD with colour) from the installed generator.
"$p/bin/clutterseg-synth" --out "$work/frame" --count 1 --seed 7 --objects 4:8 > /dev/null 2>&1 ||
  fail "installed clutterseg-synth --out"
frame=$(ls "$work"/frame/*.pcd 2> /dev/null | head -1)
[ -n "$frame" ] || fail "clutterseg-synth wrote no PCD into $work/frame"

# 1. A consumer project through the CMake package.
cmake -S "$src/tests/install/consumer" -B "$work/consumer" -G Ninja \
  -DCMAKE_PREFIX_PATH="$p" -DCMAKE_BUILD_TYPE=Release > "$work/consumer.log" 2>&1 ||
  { tail -30 "$work/consumer.log"; fail "configure the consumer with find_package(clutterseg)"; }
cmake --build "$work/consumer" > "$work/consumer-build.log" 2>&1 ||
  { tail -30 "$work/consumer-build.log"; fail "build the consumer"; }
out=$("$work/consumer/consumer" "$frame") || fail "consumer run: $out"
echo "$out"
echo "$out" | grep -Eq "consumer .*: [1-9][0-9]* objects, .* labels round trip ok" || fail "consumer output"

# 2. The same source through pkg-config (the .pc file of the staged prefix).
pcdir=$(dirname "$(find "$p" -name clutterseg.pc | head -1)")
flags=$(PKG_CONFIG_PATH="$pcdir" pkg-config --define-variable=prefix="$p" --cflags --libs clutterseg) ||
  fail "pkg-config clutterseg"
g++ -std=c++20 -O1 -o "$work/consumer-pc" "$src/tests/install/consumer/main.cc" $flags -llcm \
  > "$work/pc-build.log" 2>&1 || { tail -20 "$work/pc-build.log"; fail "build with pkg-config flags"; }
"$work/consumer-pc" "$frame" > /dev/null || fail "pkg-config consumer run"

# 3. The installed daemon on a recording, into an LCM log.
"$p/bin/clutterseg-synth" --oni "$work/rec.oni" --sequence --count 1 --frames 4 --seed 5 \
  > /dev/null 2>&1 || fail "installed clutterseg-synth"
log="$work/run.lcmlog"
"$p/bin/clutterseg" --config "$root/etc/clutterseg/clutterseg.yaml" --source "$work/rec.oni" \
  --speed max --lcm-url "file://$log?mode=w" --log-level debug > "$work/daemon.out" 2>&1 ||
  { tail -20 "$work/daemon.out"; fail "installed daemon on a recording"; }
loaded=$(grep -o "OpenNI2 loaded from [^ ]*" "$work/daemon.out" | head -1)
case "$loaded" in
  *"$root"*openni2-recordings*) ;;
  *) fail "the installed daemon loaded OpenNI2 from elsewhere: '$loaded'" ;;
esac
case "$loaded" in *"$build/openni2-recordings"*) fail "the installed daemon reached into the build tree: $loaded" ;; esac

# 4. Python bindings (no lcm module) and Java bindings on that log.
pydir=$(find "$p" -type d -name dist-packages | head -1)
PYTHONPATH="$pydir" python3 "$src/tests/install/decode_log.py" "$log" || fail "python decode"
# 4a. The same recording published in a robot's base frame (camera.extrinsics_file), read by
# the C++ and Python consumers of docs/lcm.md.
printf '{"parent_frame": "base_link", "translation": [0.6, 0.0, 0.9],\n "rotation_xyzw": [-0.9238795, 0.0, 0.0, 0.3826834]}\n' \
  > "$work/hand_eye.json"
base_log="$work/base.lcmlog"
"$p/bin/clutterseg" --config "$root/etc/clutterseg/clutterseg.yaml" --source "$work/rec.oni" \
  --speed max --lcm-url "file://$base_log?mode=w" --set "camera.extrinsics_file=$work/hand_eye.json" \
  > "$work/daemon-base.out" 2>&1 || { tail -20 "$work/daemon-base.out"; fail "daemon with extrinsics"; }
out=$("$work/consumer/base_frame_consumer" "file://$base_log?speed=0") ||
  fail "C++ base-frame consumer: $out"
echo "$out" | grep -q "in base_link: [1-9]" || fail "C++ base-frame consumer output: $out"
echo "$out" | grep -q "upright box" || fail "C++ base-frame consumer: no upright box: $out"
out=$(PYTHONPATH="$pydir" python3 "$src/tests/install/base_frame_consumer.py" "$base_log") ||
  fail "python base-frame consumer: $out"
echo "$out" | grep -q "in base_link: [1-9]" || fail "python base-frame consumer output: $out"
# 4b. The Python module of the staged prefix segments a frame as the installed tool does.
if [ -n "$pymodule" ]; then
  "$p/bin/clutterseg-synth" --out "$work/pysynth" --count 1 --seed 5 > /dev/null 2>&1 ||
    fail "installed clutterseg-synth --out"
  "$p/bin/clutterseg-segment" "$work/pysynth/scene_0000.pcd" "$work/pysynth/seg.pcd" --quiet \
    > /dev/null || fail "installed clutterseg-segment on a synthetic scene"
  PYTHONPATH="$pydir" PYTHONDONTWRITEBYTECODE=1 /usr/bin/python3 "$src/tests/install/segment_frame.py" \
    "$root" "$work/pysynth/scene_0000.pcd" "$work/pysynth/seg.pcd" || fail "python segment"
fi
if command -v javac > /dev/null && [ -f /usr/share/java/lcm.jar ]; then
  jar=$(find "$p" -name clutterseg_lcmtypes.jar | head -1)
  [ -n "$jar" ] || fail "clutterseg_lcmtypes.jar not installed"
  mkdir -p "$work/java"
  javac -nowarn -cp "/usr/share/java/lcm.jar:$jar" -d "$work/java" "$src/tests/install/DecodeLog.java" ||
    fail "javac DecodeLog"
  java -cp "/usr/share/java/lcm.jar:$jar:$work/java" DecodeLog "$log" || fail "java decode"
fi

# 5. The installed units: ExecStart and the other paths must exist; verify copies whose paths
# point into the staging root (the units themselves name the final paths). The template runs
# one camera per instance: instance NAME reads NAME.yaml and publishes camera NAME.
unit="$p/lib/systemd/system/clutterseg.service"
template="$p/lib/systemd/system/clutterseg@.service"
grep -q "^ExecStart=$prefix/bin/clutterseg --config /etc/clutterseg/clutterseg.yaml" "$unit" ||
  fail "ExecStart of the unit: $(grep ExecStart "$unit")"
grep -q "^ExecStart=$prefix/bin/clutterseg --config /etc/clutterseg/%i.yaml --default camera_name=%i " "$template" ||
  fail "ExecStart of the template unit: $(grep ExecStart "$template")"
# The instance's command line, %i expanded, gives the camera its name and the template's
# defaults, and its own file overrides them.
args=$(sed -n "s#^ExecStart=$prefix/bin/clutterseg ##p" "$template" | sed -e "s#%i#cell_left#g" \
  -e "s#/etc/clutterseg/#$work/#g")
printf 'processing:\n  pipeline_depth: 3\n' > "$work/cell_left.yaml"
# shellcheck disable=SC2086  # the unit's arguments are words
"$p/bin/clutterseg" $args --print-config > "$work/cell_left.txt" || fail "template instance --print-config"
grep -q '^camera_name: cell_left$' "$work/cell_left.txt" || fail "template instance camera_name"
grep -q '^  pipeline_depth: 3$' "$work/cell_left.txt" || fail "template instance: NAME.yaml not applied"
grep -q '^  realtime_priority: 10$' "$work/cell_left.txt" || fail "template instance: realtime_priority"
grep -q '^  decimation: 2$' "$work/cell_left.txt" || fail "template instance: camera.decimation"
# A host with a core per camera gives an instance full resolution back in its own file.
printf 'camera:\n  decimation: 1\n' > "$work/cell_right.yaml"
args_right=$(sed -n "s#^ExecStart=$prefix/bin/clutterseg ##p" "$template" | sed -e "s#%i#cell_right#g" \
  -e "s#/etc/clutterseg/#$work/#g")
# shellcheck disable=SC2086  # the unit's arguments are words
"$p/bin/clutterseg" $args_right --print-config > "$work/cell_right.txt" ||
  fail "template instance --print-config (cell_right)"
grep -q '^  decimation: 1$' "$work/cell_right.txt" || fail "template instance: NAME.yaml's camera.decimation"
grep -q '^LimitRTPRIO=11$' "$template" || fail "template unit: LimitRTPRIO"
grep -q '^RestrictRealtime=yes$' "$unit" || fail "unit: RestrictRealtime"
if command -v systemd-analyze > /dev/null; then
  for u in "$unit" "$template"; do
    name=$(basename "$u")
    [ "$name" = "clutterseg@.service" ] && name=clutterseg@left.service
    sed -e "s#$prefix/bin/#$p/bin/#g" "$u" > "$work/$name"
    systemd-analyze verify "$work/$name" > "$work/verify.log" 2>&1 ||
      { cat "$work/verify.log"; fail "systemd-analyze verify $name"; }
  done
fi
echo "check_install $mode: ok"
