#!/bin/sh
# clutterseg-spy: LCM's lcm-spy with the clutterseg message types, so it decodes
# CLUTTERSEG_OBJECTS, _LABELS, _DEPTH and _STATUS. Debian's own /usr/bin/lcm-spy wrapper fails
# on Java 17 (it passes -Xincgc) and knows no clutterseg types.
#
#   clutterseg-spy                       # LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0
#   clutterseg-spy --lcm-url=URL         # any lcm-spy option
#   clutterseg-spy --check               # checks the class path (Java, LCM, jchart2d, types)
#
# Needs liblcm-java, libjchart2d-java (lcm-spy draws its charts with it; without it opening a
# message fails with NoClassDefFoundError) and a Java runtime.
set -eu
here=$(dirname "$(readlink -f "$0")")
types="$here/../share/java/clutterseg_lcmtypes.jar"
[ -f "$types" ] || types="$here/../lcmtypes/clutterseg_lcmtypes.jar"  # a build tree
lcm=/usr/share/java/lcm.jar
chart=/usr/share/java/jchart2d.jar
missing=""
command -v java > /dev/null 2>&1 || missing="$missing default-jre (java)"
[ -f "$lcm" ] || missing="$missing liblcm-java ($lcm)"
[ -f "$chart" ] || missing="$missing libjchart2d-java ($chart)"
[ -f "$types" ] || missing="$missing clutterseg-lcmtypes ($types)"
if [ -n "$missing" ]; then
  echo "clutterseg-spy: missing:$missing" >&2
  echo "clutterseg-spy: sudo apt-get install liblcm-java libjchart2d-java default-jre" >&2
  exit 3
fi
classpath="$lcm:$chart:$types"
if [ "${1:-}" = "--check" ]; then
  # Each class lcm-spy needs to open a clutterseg message must load.
  for jar_class in "$lcm:lcm/spy/Spy.class" "$chart:info/monitorenter/gui/chart/Chart2D.class" \
                   "$types:clutterseg/objects_t.class" "$types:clutterseg/status_t.class"; do
    jar=${jar_class%%:*}
    class=${jar_class#*:}
    if ! unzip -l "$jar" "$class" > /dev/null 2>&1; then
      echo "clutterseg-spy: $class not found in $jar" >&2
      exit 3
    fi
  done
  echo "clutterseg-spy: class path ok: $classpath"
  exit 0
fi
have_url=0
for arg in "$@"; do
  case "$arg" in -l | --lcm-url=* | -l*) have_url=1 ;; esac
done
if [ "$have_url" = 0 ]; then
  set -- "--lcm-url=${LCM_DEFAULT_URL:-udpm://239.255.76.67:7667?ttl=0}" "$@"
fi
exec java -Djava.net.preferIPv4Stack=true -Xmx256m -cp "$classpath" lcm.spy.Spy "$@"
