#!/usr/bin/env bash
# lcm-spy with noisemon's message types, on Debian 12's Java 17. Debian's /usr/bin/lcm-spy passes -Xincgc, an
# option Java 9 removed ("Unrecognized option: -Xincgc"): this calls the same class, lcm.spy.Spy, directly.
#
#   lcm-spy.sh [--jar NOISEMON_MSGS_JAR] [--list-types] [lcm-spy options, e.g. --lcm-url=URL]
#
# The message jar: --jar, else $NOISEMON_MSGS_JAR, else the installed one (share/noisemon/java beside this
# script's bin/), else build/msgs/noisemon_msgs.jar of the source tree. --list-types prints the LCM types found
# on the class path (what lcm-spy can decode) and exits. JAVA_OPTS adds JVM options.
set -euo pipefail
here=$(dirname "$(readlink -f "$0")")
jar=${NOISEMON_MSGS_JAR:-}
list=0
while [ $# -gt 0 ]; do
  case "$1" in
    --jar) jar=$2; shift 2 ;;
    --list-types) list=1; shift ;;
    *) break ;;
  esac
done
if [ -z "$jar" ]; then
  for candidate in "$here/../share/noisemon/java/noisemon_msgs.jar" "$here/../build/msgs/noisemon_msgs.jar"; do
    if [ -f "$candidate" ]; then jar=$candidate; break; fi
  done
fi
if [ -z "$jar" ] || [ ! -f "$jar" ]; then
  echo "lcm-spy.sh: no noisemon_msgs.jar (build it: cmake --build build --target noisemon_msgs_jar; or give --jar FILE)" >&2
  exit 2
fi
lcm_jar=/usr/share/java/lcm.jar        # liblcm-java
jchart_jar=/usr/share/java/jchart2d.jar # libjchart2d-java: lcm-spy's plots
for f in "$lcm_jar" "$jchart_jar"; do
  [ -f "$f" ] || { echo "lcm-spy.sh: $f missing (apt-get install liblcm-java libjchart2d-java)" >&2; exit 2; }
done
classpath="$lcm_jar:$jchart_jar:$jar"
if [ "$list" = 1 ]; then
  exec java -cp "$classpath" lcm.util.ClassDiscoverer
fi
# shellcheck disable=SC2086  # JAVA_OPTS is a list of options
exec java -Djava.net.preferIPv4Stack=true -Xmx256m ${JAVA_OPTS:-} -cp "$classpath" lcm.spy.Spy "$@"
